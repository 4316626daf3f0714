"""Contact through triangle facets: patch tests across a tet and a hex body, the penetration check on
triangles.

As in ``test_contact_patch.py``: a block under a uniform dead load p on a frictionless support is
in a uniform state, the contact pressure p A0/A at every nonmortar node and the displacement that
of a single block on rollers.
"""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.contact.facets import contact_facets
from contopt.contact.interface import ContactInterface
from contopt.contact.verify import depths, surface
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tets import tetrahedralize
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static

P = 1e-3  # small strain: pressure / E
TIGHT = NewtonOptions(rtol=1e-12, utol=1e-10)
ALM = AugmentationOptions(pressure_rtol=1e-10, gap_rtol=1e-10)


def _tolerance(state) -> float:
    """The solver's stopping criteria as a relative error bound (``test_contact_patch._tolerance``)."""
    dp = state.logs[-1].extra["pressure_change"]
    return 10.0 * max(dp, ALM.pressure_rtol) + 1e3 * TIGHT.rtol


def _rollers(body):
    return (Dirichlet(body, "xmin", "x"), Dirichlet(body, "ymin", "y"))


def _blocks(order, nonmortar, lower_element="hex8"):
    """A tet block (tet4: order 1, tet10: 2) of 3 x 3 x 2 cells on a 5 x 5 x 2 block (hex8 or tet4)."""
    upper = tetrahedralize(box((1.0, 1.0, 0.5), (3, 3, 2), origin=(0.0, 0.0, 1.0)), order)
    lower = box((1.0, 1.0, 1.0), (5, 5, 2))
    lower = lower if lower_element == "hex8" else tetrahedralize(lower, 1 if lower_element == "tet4" else 2)
    mat = neo_hookean(1.0, 0.3)
    sides = {"top": ("top", "zmin"), "bottom": ("bottom", "zmax")}
    other = "bottom" if nonmortar == "top" else "top"
    model = Model(
        bodies=(Body("top", upper, mat), Body("bottom", lower, mat)),
        dirichlet=(*_rollers("top"), *_rollers("bottom"), Dirichlet("bottom", "zmin", "z")),
        loads=(Traction("top", "zmax", (0.0, 0.0, -P)),),
        interfaces=(ContactInterface(nonmortar=sides[nonmortar], mortar=sides[other]),),
    )
    return model, upper, mat


def _single_block(mesh, material):
    model = Model(
        bodies=(Body("top", mesh, material),),
        dirichlet=(*_rollers("top"), Dirichlet("top", "zmin", "z")),
        loads=(Traction("top", "zmax", (0.0, 0.0, -P)),),
    )
    return solve_static(model, newton=TIGHT).u


def _patch_test(order, nonmortar, lower):
    model, upper, mat = _blocks(order, nonmortar, lower)
    state = solve_static(model, newton=TIGHT, augmentation=ALM)
    res = state.contact[0]
    tol = _tolerance(state)
    assert tol < 1e-6  # the check below is not vacuous
    np.testing.assert_allclose(res.lam, P * 1.0 / res.a.sum(), rtol=tol)
    u_up = state.u[: 3 * upper.n_nodes].reshape(-1, 3)
    ref = _single_block(upper, mat).reshape(-1, 3)
    shift = u_up[upper.node_set("zmin"), 2].mean() - ref[upper.node_set("zmin"), 2].mean()
    np.testing.assert_allclose(u_up - ref - [0.0, 0.0, shift], 0.0, atol=tol * np.abs(ref).max())
    assert all(c.ok and c.flagged == 0 for c in state.checks)  # the independent check on triangles


@pytest.mark.parametrize("nonmortar, lower", [("top", "hex8"), ("bottom", "hex8"), ("top", "tet4")])
def test_tet4_block_passes_the_patch_test(nonmortar, lower):
    """tri3 facets nonmortar against quads, quads against tri3, tri3 against tri3 (non-matching)."""
    _patch_test(1, nonmortar, lower)


@pytest.mark.parametrize(
    "nonmortar, lower",
    [
        ("top", "hex8"),
        pytest.param("bottom", "hex8", marks=pytest.mark.slow),
        pytest.param("top", "tet10", marks=pytest.mark.slow),
    ],
)
def test_tet10_block_passes_the_patch_test(nonmortar, lower):
    """tri6 faces (the parent's geometry, the transformed quadratic weights) nonmortar against
    quads, quads against tri6, tri6 against tri6 (non-matching): the uniform pressure and the
    displacement of a single block, to the solver's tolerance (27-49 s each with the kernels
    compiled, the tri6/tri6 one the longest: the last two slow)."""
    _patch_test(2, nonmortar, lower)


@pytest.mark.parametrize("order", [1, 2])
def test_penetration_check_measures_depths_on_triangle_facets(order):
    """A hex block sunk by d into a tet block's top: every node of either surface inside the other's
    footprint is d deep, the others not at all (closest points on a free edge)."""
    d = 0.01
    lower = tetrahedralize(box((1.0, 1.0, 0.5), (3, 3, 1)), order)
    upper = box((0.6, 0.6, 0.5), (2, 2, 1), origin=(0.2, 0.2, 0.5 - d))
    x = np.concatenate([lower.points, upper.points])
    nm = contact_facets(lower, "zmax")
    m = contact_facets(upper, "zmin") + lower.n_nodes
    assert len(surface(x, nm).tri) == 3 * len(nm)  # a triangle gives three, its repeated slot none
    nm_nodes = np.unique(nm)
    got = depths(x, nm, m, nm_nodes)
    inside = lambda p: np.all((p[:, :2] > 0.2 + 1e-9) & (p[:, :2] < 0.8 - 1e-9), axis=1)  # noqa: E731
    np.testing.assert_allclose(got.nonmortar, np.where(inside(x[nm_nodes]), d, 0.0), atol=1e-14)
    np.testing.assert_allclose(got.mortar, d, atol=1e-14)  # the hex face lies inside the tet face


def test_tet10_faces_integrate_on_their_parents_with_and_without_friction():
    from dataclasses import replace

    from contopt.assembly.system import discretize
    from contopt.contact import Coulomb
    from contopt.contact.system import discretize_contact

    for order, mu in ((1, None), (2, None), (1, 0.3), (2, 0.3)):
        model, _, _ = _blocks(order, "top")
        if mu is not None:
            model = replace(model, interfaces=(replace(model.interfaces[0], friction=Coulomb(mu)),))
        contact = discretize_contact(model, discretize(model))
        # the parent faces where the quadratic kernels integrate the gaps and the slips: tet10 only
        assert (contact.blocks[0].parents is not None) == (order == 2), (order, mu)
