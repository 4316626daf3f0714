"""Contact patch tests: uniform pressure through non-matching (and rotated) meshes.

A block under a uniform dead load p (per reference area) on a frictionless
support is in a uniform state: the contact pressure (per deformed area) must
be p A0/A at every nonmortar node, A the deformed contact area, and the
displacement the one of a single block on rollers (no contact at all).
"""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.contact.interface import ContactInterface
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static

P = 1e-3  # small strain: pressure / E
TIGHT = NewtonOptions(rtol=1e-12, utol=1e-10)
ALM = AugmentationOptions(pressure_rtol=1e-10, gap_rtol=1e-10)


def _tolerance(state) -> float:
    """How far from the exact state the solver's stopping criteria allow this one to be (relative).

    The augmented Lagrangian stops when its last update changed the pressures by ``dp`` (relative; at
    most its tolerance, or 100 times it where round-off stalls the updates, which is then accepted):
    the remaining error is ``dp rho / (1 - rho)`` for a contraction rate rho, at most 9 dp while
    rho <= 0.9. Newton's residual tolerance adds ~1e3 rtol (the pressures and displacements of a
    patch of ~100 nodes from a force residual of rtol times the load).
    """
    dp = state.logs[-1].extra["pressure_change"]
    return 10.0 * max(dp, ALM.pressure_rtol) + 1e3 * TIGHT.rtol


def _rollers(body):
    return (Dirichlet(body, "xmin", "x"), Dirichlet(body, "ymin", "y"))


def _single_block(mesh, material):
    model = Model(
        bodies=(Body("top", mesh, material),),
        dirichlet=(*_rollers("top"), Dirichlet("top", "zmin", "z")),
        loads=(Traction("top", "zmax", (0.0, 0.0, -P)),),
    )
    return solve_static(model, newton=TIGHT).u


@pytest.mark.parametrize("nonmortar", ["top", "bottom"])
def test_two_deformable_blocks_non_matching(nonmortar):
    upper = box((1.0, 1.0, 0.5), (3, 3, 2), origin=(0.0, 0.0, 1.0))
    lower = box((1.0, 1.0, 1.0), (5, 5, 2))
    # one material: both blocks expand alike laterally, so their footprints stay equal
    # (with different ones the wider block overhangs and the exact state is not uniform)
    mat_up = mat_lo = neo_hookean(1.0, 0.3)
    sides = {"top": ("top", "zmin"), "bottom": ("bottom", "zmax")}
    other = "bottom" if nonmortar == "top" else "top"
    model = Model(
        bodies=(Body("top", upper, mat_up), Body("bottom", lower, mat_lo)),
        dirichlet=(*_rollers("top"), *_rollers("bottom"), Dirichlet("bottom", "zmin", "z")),
        loads=(Traction("top", "zmax", (0.0, 0.0, -P)),),
        interfaces=(ContactInterface(nonmortar=sides[nonmortar], mortar=sides[other]),),
    )
    state = solve_static(model, newton=TIGHT, augmentation=ALM)
    res = state.contact[0]
    tol = _tolerance(state)
    assert tol < 1e-6  # the check below is not vacuous
    np.testing.assert_allclose(res.lam, P * 1.0 / res.a.sum(), rtol=tol)
    # the upper block moves as a single block on rollers, shifted by the lower block's shortening
    n_up = upper.n_nodes
    u_up = state.u[: 3 * n_up].reshape(-1, 3)
    ref = _single_block(upper, mat_up).reshape(-1, 3)
    shift = u_up[upper.node_set("zmin"), 2].mean() - ref[upper.node_set("zmin"), 2].mean()
    np.testing.assert_allclose(u_up - ref - [0.0, 0.0, shift], 0.0, atol=tol * np.abs(ref).max())


def test_block_on_rotated_rigid_support():
    # the support is fixed (rigid, exactly flat), larger than the block and meshed 7x7 rotated 5 degrees
    upper = box((1.0, 1.0, 0.5), (4, 4, 2), origin=(0.0, 0.0, 1.0))
    c, s = np.cos(np.deg2rad(5.0)), np.sin(np.deg2rad(5.0))
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    lower = box((2.0, 2.0, 1.0), (7, 7, 1), origin=(-0.5, -0.5, 0.0))
    lower = lower.transformed(R, np.array([0.5, 0.5, 0.0]) - R @ [0.5, 0.5, 0.0])
    mat = neo_hookean(1.0, 0.3)
    model = Model(
        bodies=(Body("top", upper, mat), Body("support", lower, neo_hookean(10.0, 0.3))),
        dirichlet=(*_rollers("top"), Dirichlet("support", "all")),
        loads=(Traction("top", "zmax", (0.0, 0.0, -P)),),
        interfaces=(ContactInterface(nonmortar=("top", "zmin"), mortar=("support", "zmax")),),
    )
    state = solve_static(model, newton=TIGHT, augmentation=ALM)
    res = state.contact[0]
    tol = _tolerance(state)
    assert tol < 1e-6
    np.testing.assert_allclose(res.lam, P * 1.0 / res.a.sum(), rtol=tol)
    ref = _single_block(upper, mat)
    np.testing.assert_allclose(state.u[: 3 * upper.n_nodes], ref, atol=tol * np.abs(ref).max())
