"""Assembled problems with homogeneous exact solutions: patch test, uniaxial stress, simple shear.

The references are analytic: a linear displacement field must be reproduced
exactly by trilinear elements on any mesh, and its stress is the material's
homogeneous stress, written out here by hand (independently of the AD used
by the code) as

    sigma = 2/J dev(A J^(-2/3) b + B J^(-4/3) (I1 b - b^2)) + kappa ln(J)/J I,

and, for uniaxial stress, from the principal-stretch form with the lateral
stretch found by brentq on the hand formula.
"""

import numpy as np
import pytest
from _analytic import (
    cauchy_hand,
    principal_cauchy,
    rel_err,
    uniaxial_lateral_stretch,
)  # tests/_analytic.py (hand formulas)

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.assembly.system import discretize
from contopt.material.hyperelastic import MooneyRivlin, neo_hookean
from contopt.mesh import Mesh, box
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import State, solve_static

MATERIALS = {
    "neo-hookean": neo_hookean(1.0, 0.3),
    "mooney-rivlin": MooneyRivlin.from_E_nu(1.0, 0.3, b_fraction=0.4),
}
TIGHT = NewtonOptions(rtol=1e-13, atol=1e-15, utol=1e-12, n_steps=3, max_iter=30)


@pytest.fixture(params=sorted(MATERIALS))
def mat(request):
    return MATERIALS[request.param]


@pytest.fixture(params=[False, True], ids=["plain", "fbar"])
def use_fbar(request):
    return request.param


# ---------------------------------------------------------- hand formulas


def boundary_nodes(mesh):
    return np.unique(np.concatenate([mesh.node_set(s) for s in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")]))


def perturbed_box(rng, n=3, amount=0.15):
    """box() of n^3 unit-size cells with the interior nodes moved randomly by up to ``amount`` x cell size."""
    base = box((1.0, 1.0, 1.0), (n, n, n))
    h = 1.0 / n
    pts = base.points.copy()
    bnd = boundary_nodes(base)
    interior = np.setdiff1d(np.arange(base.n_nodes), bnd)
    pts[interior] += rng.uniform(-amount * h, amount * h, (len(interior), 3))
    node_sets = dict(base.node_sets)
    node_sets["boundary"] = bnd
    node_sets["interior"] = interior
    return Mesh(pts, base.cells, node_sets, dict(base.facet_sets))


def solve(mesh, mat, use_fbar, dirichlet, newton=TIGHT, u0=None):
    model = Model(bodies=[Body("b", mesh, mat, fbar=use_fbar)], dirichlet=dirichlet)
    disc = discretize(model)
    state = solve_static(disc, newton=newton, start=None if u0 is None else State(u=np.ravel(u0)))
    u = disc.body_displacement(state.u, "b")
    return disc, state, u


# ------------------------------------------------------------- patch test
def test_patch_test_large_strain_linear_field(rng, mat, use_fbar):
    mesh = perturbed_box(rng)
    interior = mesh.node_set("interior")
    assert len(interior) == 8
    moved = np.abs(mesh.points[interior] - box((1.0, 1.0, 1.0), (3, 3, 3)).points[interior]).max()
    assert moved > 0.02  # the interior really is distorted
    a = np.array([0.1, -0.2, 0.05])
    H = np.array([[0.22, -0.15, 0.1], [0.18, -0.2, 0.12], [-0.1, 0.25, 0.15]])
    F = np.eye(3) + H
    assert np.linalg.det(F) > 0.5

    def linear(X, t):
        return t * (a + X @ H.T)

    # start Newton away from the answer (interior nodes off the linear field): with a consistent
    # predictor a homogeneous state would otherwise be reached in a single linear solve
    u0 = np.zeros((mesh.n_nodes, 3))
    u0[interior] = rng.uniform(-0.03, 0.03, (len(interior), 3))
    disc, state, u = solve(mesh, mat, use_fbar, [Dirichlet("b", "boundary", "xyz", linear)], u0=u0)
    exact = linear(mesh.points, 1.0)
    assert state.newton_iterations > 3
    err = np.abs(u[interior] - exact[interior]).max()
    assert err <= 1e-10 * np.abs(exact).max()
    sig = disc.cauchy_stress(state.u, "b")  # (27, 3, 3) cell averages
    ref = cauchy_hand(mat, F)
    assert np.abs(ref).max() > 0.1 * mat.mu
    for e in range(mesh.n_cells):
        assert rel_err(sig[e], ref) <= 1e-9, e
    # equilibrium: the free residual vanishes, the reactions balance
    r = state.reactions.reshape(-1, 3)
    assert np.abs(r[interior]).max() <= 1e-10 * np.abs(r).max()
    np.testing.assert_allclose(r.sum(axis=0), 0.0, atol=1e-10 * np.abs(r).max())


# ------------------------------------------------------ FE uniaxial stress
def uniaxial_bcs(l1, L):
    return [
        Dirichlet("b", "xmin", "x", 0.0),
        Dirichlet("b", "ymin", "y", 0.0),
        Dirichlet("b", "zmin", "z", 0.0),
        Dirichlet("b", "xmax", "x", (l1 - 1.0) * L[0]),
    ]


@pytest.mark.parametrize("l1", [1.5, 0.6])
def test_fe_uniaxial_stress_matches_analytic_curve(mat, use_fbar, l1):
    L = (2.0, 1.0, 1.5)
    mesh = box(L, (2, 2, 2))
    disc, state, u = solve(mesh, mat, use_fbar, uniaxial_bcs(l1, L))
    l2 = uniaxial_lateral_stretch(mat, l1)
    # lateral stretch from the FE solution: u_y = (l2 - 1) Y and u_z = (l2 - 1) Z at every node
    X = mesh.points
    ymax, zmax = mesh.node_set("ymax"), mesh.node_set("zmax")
    assert np.abs(1.0 + u[ymax, 1] / L[1] - l2).max() <= 1e-8
    assert np.abs(1.0 + u[zmax, 2] / L[2] - l2).max() <= 1e-8
    np.testing.assert_allclose(u, X * (np.array([l1, l2, l2]) - 1.0), rtol=0, atol=1e-8 * L[0])
    sig = disc.cauchy_stress(state.u, "b")
    s11 = principal_cauchy(mat, [l1, l2, l2])[0]
    assert np.sign(s11) == np.sign(l1 - 1.0)
    np.testing.assert_allclose(sig[:, 0, 0], s11, rtol=1e-8)
    off = sig.copy()
    off[:, 0, 0] = 0.0
    assert np.abs(off).max() <= 1e-8 * abs(s11)
    # the reaction on xmax is the Cauchy stress times the deformed area: s11 * l2^2 * Ly * Lz
    fx = state.reactions.reshape(-1, 3)[mesh.node_set("xmax"), 0].sum()
    assert fx == pytest.approx(s11 * l2**2 * L[1] * L[2], rel=1e-8)


# --------------------------------------------------------- FE simple shear
def test_fe_simple_shear_matches_hand_formula(mat, use_fbar):
    g = 0.8
    mesh = box((1.0, 1.0, 1.0), (2, 2, 2))
    bnd = boundary_nodes(mesh)
    mesh = mesh.with_sets(node_sets={"boundary": bnd})

    def shear(X, t):
        return np.stack([t * g * X[:, 1], np.zeros(len(X)), np.zeros(len(X))], axis=1)

    disc, state, u = solve(mesh, mat, use_fbar, [Dirichlet("b", "boundary", "xyz", shear)])
    interior = np.setdiff1d(np.arange(mesh.n_nodes), bnd)
    assert len(interior) == 1
    np.testing.assert_allclose(u[interior], shear(mesh.points[interior], 1.0), rtol=0, atol=1e-10)
    F = np.eye(3)
    F[0, 1] = g
    b = F @ F.T
    I1 = np.trace(b)
    s = 2.0 * (mat.A * b + mat.B * (I1 * b - b @ b))  # J = 1
    ref = s - np.trace(s) / 3.0 * np.eye(3)
    assert ref[0, 1] == pytest.approx(2.0 * (mat.A + mat.B) * g, rel=1e-14)
    sig = disc.cauchy_stress(state.u, "b")
    for e in range(mesh.n_cells):
        assert rel_err(sig[e], ref) <= 1e-8, e
