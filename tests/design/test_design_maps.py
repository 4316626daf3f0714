"""Design maps: known values and vjp against central finite differences."""

import numpy as np
import pytest
import scipy.sparse as sp

from contopt.design import (
    REALIZATIONS,
    BSplineGrid,
    CyclicSymmetry,
    Heaviside,
    Robust,
    Simp,
    cone_filter,
    r_union,
    r_union_partials,
    uniform_basis,
)
from contopt.errors import ConfigError


def _central(f, a, h=1e-6):
    """Entry-by-entry central difference of a pointwise map."""
    return (f(a + h) - f(a - h)) / (2 * h)


# --- pointwise maps ------------------------------------------------------------------------------------------------


def test_heaviside_values_and_inverse():
    H = Heaviside(eta=10.0)
    assert H.forward(np.array([0.0]))[0] == 0.5
    np.testing.assert_allclose(H.forward(np.array([0.3])), 0.5 + 0.5 * np.tanh(3.0), rtol=1e-15)
    for nu in (0.1, 0.4, 0.5, 0.9):
        d = H.inverse(nu)
        np.testing.assert_allclose(H.forward(np.array([d]))[0], nu, rtol=1e-14)
    np.testing.assert_allclose(H.inverse(0.4), np.log(0.4 / 0.6) / 20.0, rtol=1e-15)
    assert np.isfinite(H.vjp(np.array([1e3]), np.ones(1))).all()  # no overflow deep in solid


@pytest.mark.parametrize("eta", [1.0, 10.0, 40.0])
def test_heaviside_vjp_matches_finite_differences(eta, rng):
    H = Heaviside(eta=eta)
    phi, bar = rng.uniform(-0.3, 0.3, 20), rng.normal(size=20)
    np.testing.assert_allclose(H.vjp(phi, bar), bar * _central(H.forward, phi, 1e-7), rtol=1e-6, atol=1e-9)


def test_simp_values_and_vjp(rng):
    s = Simp(p=3.0, nu0=1e-2)
    np.testing.assert_allclose(s.forward(np.array([0.0, 0.5, 1.0])), [1e-2, 0.99 * 0.125 + 1e-2, 1.0], rtol=1e-15)
    nu, bar = rng.uniform(0.05, 1.0, 20), rng.normal(size=20)
    np.testing.assert_allclose(s.vjp(nu, bar), bar * _central(s.forward, nu), rtol=1e-7)


def test_r_union_is_a_smooth_max(rng):
    a, b = rng.uniform(-1, 1, 50), rng.uniform(-1, 1, 50)
    # positive exactly where either argument is; max - sqrt(eps)/2 away from a = b
    u = r_union(a, b, 1e-4)
    assert np.all((u > 0) == ((a > 0) | (b > 0)))
    far = np.abs(a - b) > 0.1
    np.testing.assert_allclose(u[far], np.maximum(a, b)[far] - 0.005, atol=3e-4)
    assert r_union(np.array([0.2]), np.array([0.2]), 1e-4)[0] == pytest.approx(0.2)
    da, db = r_union_partials(a, b, 1e-4)
    np.testing.assert_allclose(da, _central(lambda v: r_union(v, b, 1e-4), a), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(db, _central(lambda v: r_union(a, v, 1e-4), b), rtol=1e-6, atol=1e-9)


def test_pointwise_maps_reject_bad_parameters():
    with pytest.raises(ConfigError, match="heaviside.eta"):
        Heaviside(eta=0.0)
    with pytest.raises(ConfigError, match="simp.nu0"):
        Simp(nu0=1.5)
    with pytest.raises(ConfigError, match="initial design"):
        Heaviside().inverse(1.0)


# --- B-splines -----------------------------------------------------------------------------------------------------


def test_uniform_cubic_basis_is_the_textbook_one(rng):
    t = rng.uniform(0, 1, 30)
    expected = np.stack([(1 - t) ** 3, 3 * t**3 - 6 * t**2 + 4, -3 * t**3 + 3 * t**2 + 3 * t + 1, t**3], 1) / 6
    np.testing.assert_allclose(uniform_basis(t, 3), expected, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(uniform_basis(t, 1), np.stack([1 - t, t], 1), rtol=1e-13)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_bspline_partition_of_unity_and_linear_reproduction(degree, rng):
    grid = BSplineGrid((4, 3, 2), degree=degree, origin=(1.0, -2.0, 0.5), lengths=(9.0, 4.0, 3.0))
    X = np.array([1.0, -2.0, 0.5]) + rng.uniform(0, 1, (200, 3)) * np.array([9.0, 4.0, 3.0])
    X[:3] = [[1.0, -2.0, 0.5], [10.0, 2.0, 3.5], [5.5, 0.0, 2.0]]  # corners and an interior knot
    G = grid.matrix(X)
    assert G.shape == (200, np.prod([n + degree for n in (4, 3, 2)]))
    assert np.all(np.diff(G.indptr) == (degree + 1) ** 3)
    np.testing.assert_allclose(np.asarray(G.sum(axis=1)).ravel(), 1.0, rtol=1e-13)
    assert G.min() >= 0
    c = np.array([0.3, -1.2, 2.5])
    control = grid.greville((np.array(grid.origin), np.array(grid.lengths)))
    np.testing.assert_allclose(G @ (0.7 + control @ c), 0.7 + X @ c, rtol=1e-12, atol=1e-12)


def test_bspline_cubic_matches_tensor_product_of_1d_functions():
    grid = BSplineGrid((2, 1, 1), degree=3, origin=(0, 0, 0), lengths=(2.0, 1.0, 1.0))
    X = np.array([[1.5, 0.25, 0.75]])  # patch (1, 0, 0), local (0.5, 0.25, 0.75)
    G = grid.matrix(X).toarray().reshape(grid.shape)
    bx, by, bz = (uniform_basis(np.array([t]), 3)[0] for t in (0.5, 0.25, 0.75))
    expected = np.zeros(grid.shape)
    expected[1:5, 0:4, 0:4] = bx[:, None, None] * by[None, :, None] * bz[None, None, :]
    np.testing.assert_allclose(G, expected, rtol=1e-14, atol=1e-16)


def test_bspline_with_control_points_and_errors():
    grid = BSplineGrid.with_control_points((13, 8, 7))
    assert grid.patches == (10, 5, 4) and grid.n_control == 728
    with pytest.raises(ConfigError, match="outside the B-spline box"):
        BSplineGrid((2, 2, 2), origin=(0, 0, 0), lengths=(1, 1, 1)).matrix(np.array([[0.5, 0.5, 1.2]]))
    with pytest.raises(ConfigError, match="bspline.patches"):
        BSplineGrid((2, 0, 2))
    with pytest.raises(ConfigError, match="bspline.degree"):
        BSplineGrid((2, 2, 2), degree=7)
    with pytest.raises(ConfigError, match="more than 3 control points"):
        BSplineGrid.with_control_points((3, 8, 7))


# --- cone filter ---------------------------------------------------------------------------------------------------


def _brute_filter(points, sites, vol, r):
    d = np.linalg.norm(points[:, None] - sites[None], axis=2)
    w = np.maximum(r - d, 0) * vol[None]
    return w / w.sum(axis=1, keepdims=True)


def test_cone_filter_weights_match_the_definition_and_sum_to_one(rng):
    pts = rng.uniform(0, 3, (120, 3))
    vol = rng.uniform(0.5, 1.5, 120)
    G = cone_filter(pts, pts, vol, 0.9)
    assert sp.issparse(G) and G.shape == (120, 120)
    np.testing.assert_allclose(G.toarray(), _brute_filter(pts, pts, vol, 0.9), rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(np.asarray(G.sum(axis=1)).ravel(), 1.0, rtol=1e-14)
    assert G.nnz == np.count_nonzero(_brute_filter(pts, pts, vol, 0.9))


def test_cone_filter_radius_below_spacing_is_the_identity_and_errors():
    pts = np.stack(np.meshgrid(*[np.arange(3.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    G = cone_filter(pts, pts, np.ones(27), 0.5)
    np.testing.assert_array_equal(G.toarray(), np.eye(27))
    with pytest.raises(ConfigError, match="reaches no design cell"):
        cone_filter(pts + 10.0, pts, np.ones(27), 0.5)
    with pytest.raises(ConfigError, match="radius must be > 0"):
        cone_filter(pts, pts, np.ones(27), 0.0)


# --- symmetry ------------------------------------------------------------------------------------------------------


def test_cyclic_reflection_symmetry_maps_the_paper_angles_together():
    sym = CyclicSymmetry(n_sectors=5, reflection=True)
    angles = np.radians([-10, 10, 62, 82, 134, 154, 206, 226, 278, 298])  # paper 7.4: all equal
    X = np.stack([2 * np.cos(angles), 2 * np.sin(angles), np.full(10, 0.3)], 1)
    Y = sym.map(X)
    np.testing.assert_allclose(Y, np.broadcast_to(Y[1], Y.shape), atol=1e-12)
    np.testing.assert_allclose(Y[1], X[1], atol=1e-12)  # 10 degrees is in the first half sector
    a = np.arctan2(Y[:, 1], Y[:, 0])
    assert np.all((a >= -1e-12) & (a <= np.pi / 5 + 1e-12))


def test_cyclic_symmetry_without_reflection_and_other_axis(rng):
    sym = CyclicSymmetry(n_sectors=4, reflection=False, axis="x", center=(0, 1, 1))
    X = rng.normal(size=(50, 3))
    Y = sym.map(X)
    rel_x, rel_y = X - [0, 1, 1], Y - [0, 1, 1]
    np.testing.assert_allclose(np.hypot(rel_y[:, 1], rel_y[:, 2]), np.hypot(rel_x[:, 1], rel_x[:, 2]), rtol=1e-12)
    np.testing.assert_allclose(Y[:, 0], X[:, 0])
    # a quarter turn about x maps onto the same image
    rot = X.copy()
    rot[:, 1], rot[:, 2] = 1 - rel_x[:, 2], 1 + rel_x[:, 1]
    np.testing.assert_allclose(sym.map(rot), Y, atol=1e-12)
    with pytest.raises(ConfigError, match="symmetry.axis"):
        CyclicSymmetry(3, axis="w")


# --- the robust formulation's projections ---------------------------------------------------------------------------


def test_heaviside_threshold_shifts_the_projection(rng):
    """nu = 1/2 at the threshold; the vjp and the inverse follow it."""
    H = Heaviside(eta=10.0, threshold=0.3)
    assert H.forward(np.array([0.3]))[0] == 0.5
    np.testing.assert_allclose(H.forward(np.array([0.5])), Heaviside(10.0).forward(np.array([0.2])), rtol=1e-15)
    np.testing.assert_allclose(H.forward(np.array([H.inverse(0.3)])), 0.3, rtol=1e-14)
    phi, bar = rng.uniform(0.0, 0.6, 20), rng.normal(size=20)
    np.testing.assert_allclose(H.vjp(phi, bar), bar * _central(H.forward, phi, 1e-7), rtol=1e-6, atol=1e-9)
    with pytest.raises(ConfigError, match="heaviside.threshold must be a finite number"):
        Heaviside(threshold=float("nan"))


def test_robust_thresholds_and_checks():
    r = Robust(0.15)
    assert [r.threshold(k) for k in REALIZATIONS] == [0.3, 0.0, -0.3]  # filtered density 0.65, 0.5, 0.35
    for bad in (0.0, 0.5, -0.1, "0.1", True):
        with pytest.raises(ConfigError, match=r"robust.delta must be a number in \(0, 0.5\)"):
            Robust(bad)
    with pytest.raises(ConfigError, match="robust realization"):
        r.threshold("middle")
