"""Friction kinematics and the Coulomb node law: values against closed forms, derivatives against
central finite differences (contopt.contact.friction)."""

import numpy as np
import pytest
from test_mortar import CH, stack, warped_pairs  # tests/contact/test_mortar.py

from contopt.contact import segment_pairs
from contopt.contact.coulomb import Coulomb
from contopt.contact.friction import (
    N_Z,
    cone_magnitude,
    node_tractions,
    pair_slip_hessians,
    pair_slips_and_jacobians,
)
from contopt.errors import ConfigError


@pytest.fixture(scope="module")
def moved():
    """The warped pairs of the mortar tests and a previous position: every node moved by a
    different small displacement (so the slips are nonzero and not uniform)."""
    x_nm, x_m = warped_pairs()
    seg = segment_pairs(x_nm, x_m)
    X = stack(x_nm, x_m)
    rng = np.random.default_rng(3)
    return X, X - rng.uniform(-0.05, 0.05, X.shape), seg


def _z(X, Xp, topo):
    return pair_slips_and_jacobians(X, Xp, topo, chunk=CH)[0]


def test_rigid_sliding_gives_slip_equal_to_displacement_times_area():
    # a nonmortar square on a larger mortar square, slid by d along the plane: s_A = d a_A
    x_nm = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    x_m = np.array([[-1, -1, 0], [-1, 2, 0], [2, 2, 0], [2, -1, 0]], float)
    X = stack(x_nm[None], x_m[None])
    seg = segment_pairs(X[:, :4], X[:, 4:])
    d = np.array([0.03, -0.02, 0.0])
    Xp = X.copy()
    Xp[:, :4] -= d  # the nonmortar moved by d, the mortar stayed
    z = _z(X, Xp, seg.topo)[0]
    a = z[:, 1]
    assert np.allclose(a, 0.25, rtol=1e-13)
    assert np.allclose(z[:, 2:5], a[:, None] * d, atol=1e-14)
    assert np.allclose(z[:, 5:8], a[:, None] * [0, 0, 1], atol=1e-14)
    # moving both bodies alike (a rigid translation of the pair) is no slip
    Xp2 = X - [0.3, 0.1, -0.2]
    assert np.allclose(_z(X, Xp2, seg.topo)[0][:, 2:5], 0.0, atol=1e-14)


def test_slip_is_tangential_and_indifferent_to_rigid_motion(moved, rng):
    X, Xp, seg = moved
    z = _z(X, Xp, seg.topo)
    # s . n0 = 0 per pair (m = a n0)
    assert np.allclose(np.einsum("pkc,pkc->pk", z[..., 2:5], z[..., 5:8]), 0.0, atol=1e-14)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    Q *= np.sign(np.linalg.det(Q))
    shift = np.array([1.0, -2.0, 0.5])
    z2 = _z(X @ Q.T + shift, Xp @ Q.T + shift, seg.topo)
    assert np.allclose(z2[..., :2], z[..., :2], atol=1e-12)
    assert np.allclose(z2[..., 2:5], z[..., 2:5] @ Q.T, atol=1e-12)
    assert np.allclose(z2[..., 5:8], z[..., 5:8] @ Q.T, atol=1e-12)


def test_gap_and_area_rows_agree_with_the_frictionless_kernel(moved):
    from contopt.contact import pair_values_and_jacobians

    X, Xp, seg = moved
    z, J, _ = pair_slips_and_jacobians(X, Xp, seg.topo, chunk=CH)
    g, a, Jn = pair_values_and_jacobians(X, seg.topo, chunk=CH)
    assert np.allclose(z[..., 0], g, rtol=1e-13, atol=1e-16) and np.allclose(z[..., 1], a, rtol=1e-13)
    assert np.allclose(J[:, :, 0], Jn[:, :4], rtol=1e-10, atol=1e-14)
    assert np.allclose(J[:, :, 1], Jn[:, 4:], rtol=1e-10, atol=1e-14)


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_pair_jacobian_matches_central_differences(moved):
    X, Xp, seg = moved
    P = len(X)
    _, J, _ = pair_slips_and_jacobians(X, Xp, seg.topo, chunk=CH)
    h = 1e-6
    for k in range(24):
        plus, minus = X.reshape(P, 24).copy(), X.reshape(P, 24).copy()
        plus[:, k] += h
        minus[:, k] -= h
        fd = (_z(plus.reshape(P, 8, 3), Xp, seg.topo) - _z(minus.reshape(P, 8, 3), Xp, seg.topo)) / (2 * h)
        assert _rel(J[..., k], fd) <= 1e-6, k


def test_virtual_work_rows_move_the_nonmortar_by_its_area_and_ignore_rigid_motion(moved):
    # ds_A/dx_moved is -(P0 C) ⊗ I: a translation d of the nonmortar nodes alone slips
    # sum_A = P0 d times the overlap area; one of all eight nodes does not slip
    X, Xp, seg = moved
    z, _, Js = pair_slips_and_jacobians(X, Xp, seg.topo, chunk=CH)
    d = np.array([0.3, -0.2, 0.5])
    n0 = z[:, 0, 5:8] / z[:, 0, 1:2]
    P0d = d - (n0 @ d)[:, None] * n0
    nm_only = np.r_[np.tile(d, 4), np.zeros(12)]
    np.testing.assert_allclose(Js @ nm_only, z[..., 1:2] * P0d[:, None, :], atol=1e-14)
    np.testing.assert_allclose(Js @ np.tile(d, 8), 0.0, atol=1e-14)


def test_pair_weighted_hessian_matches_central_differences(moved, rng):
    X, Xp, seg = moved
    P = len(X)
    w = rng.normal(size=(P, 4, 3))
    H = pair_slip_hessians(X, Xp, seg.topo, w, chunk=CH)
    h = 1e-6
    for k in range(24):
        grads = []
        for sgn in (1, -1):
            Y = X.reshape(P, 24).copy()
            Y[:, k] += sgn * h
            _, _, Js = pair_slips_and_jacobians(Y.reshape(P, 8, 3), Xp, seg.topo, chunk=CH)
            grads.append(np.einsum("pkc,pkcj->pj", w, Js))
        assert _rel(H[:, :, k], (grads[0] - grads[1]) / (2 * h)) <= 1e-6, k


# ------------------------------------------------------------------------------ node law
def _node(z, t_prev, p=0.0, eps_n=100.0, eps_t=50.0, mu=0.3, closed=True, history=False, edge=0.0):
    k = len(z)
    out = node_tractions(z, t_prev, np.full(k, p), np.full(k, eps_n), eps_t, mu, np.full(k, closed), edge)
    return out if history else out[:3]


def _z_node(g=-0.01, a=0.5, s=(0.0, 0.0, 0.0), n=(0.0, 0.0, 1.0)):
    return np.r_[g, a, s, a * np.asarray(n)]


def test_node_law_sticks_inside_the_cone_and_slides_on_it():
    lam = 100.0 * 0.01 / 0.5  # eps_n (-g/a) = 2
    small = _z_node(s=(0.5 * 0.3 * lam * 0.5 / 50.0, 0.0, 0.0))  # trial traction half the bound
    large = _z_node(s=(4.0 * 0.3 * lam * 0.5 / 50.0, 0.0, 0.0))
    t, stick, _ = _node(np.array([small, large]), np.zeros((2, 3)))
    assert stick.tolist() == [True, False]
    assert np.allclose(t[0], [0.5 * 0.3 * lam, 0, 0], rtol=1e-14)
    assert np.allclose(t[1], [0.3 * lam, 0, 0], rtol=1e-14)  # on the cone: mu lam along the slip


def test_node_law_projects_the_history_on_the_current_tangent_plane():
    n = np.array([0.0, np.sin(0.2), np.cos(0.2)])
    z = _z_node(n=n)
    t_prev = np.array([[0.1, 0.0, 0.05]])
    t, stick, _ = _node(z[None], t_prev)
    assert stick[0] and abs(np.dot(t[0], n)) < 1e-15
    assert np.allclose(t[0], t_prev[0] - np.dot(t_prev[0], n) * n, rtol=1e-14)


def test_open_nodes_and_mu_zero_carry_no_traction_and_no_stiffness():
    z = np.array([_z_node(s=(0.01, 0, 0)), _z_node(g=0.01, s=(0.01, 0, 0))])
    t, stick, d = _node(z, np.zeros((2, 3)), mu=0.0)
    assert not t.any() and not stick.any() and not d.any()
    t, stick, d = _node(z[1:], np.zeros((1, 3)), closed=False)
    assert not t.any() and not d.any()


# the trial traction of "edge" is 1.05 mu lam: inside the rounded edge of half-width 0.2
@pytest.mark.parametrize("case", ["stick", "slip", "slip-with-history", "tilted-slip", "edge"])
def test_node_law_derivative_matches_central_differences(case):
    n = (0.0, 0.0, 1.0) if case != "tilted-slip" else (0.1, -0.2, 0.97)
    lam = 0.3 + 100.0 * 0.012 / 0.45
    s_edge = (1.05 * 0.3 * lam * 0.45 / 50.0 * 0.6, 1.05 * 0.3 * lam * 0.45 / 50.0 * 0.8, 0.0)
    s = {"stick": (0.002, 0.001, 0.0), "slip": (0.05, -0.02, 0.0), "edge": s_edge}.get(case, (0.03, 0.04, 0.01))
    edge = 0.2 if case == "edge" else 0.0
    z = _z_node(g=-0.012, a=0.45, s=s, n=n)
    t_prev = np.array([[0.2, -0.1, 0.0]]) if "history" in case else np.zeros((1, 3))
    t, stick, d = _node(z[None], t_prev, p=0.3, edge=edge)
    assert stick[0] == (case == "stick")
    if case == "edge":  # inside the rounded edge: f(1.05) = 1.05 - (1.05 - 0.8)^2 / 0.8
        assert np.linalg.norm(t[0]) == pytest.approx(0.3 * lam * (1.05 - 0.25**2 / 0.8), rel=1e-12)
    h = 1e-7
    fd = np.zeros((3, N_Z))
    for k in range(N_Z):
        zp, zm = z.copy(), z.copy()
        zp[k] += h
        zm[k] -= h
        fd[:, k] = (
            _node(zp[None], t_prev, p=0.3, edge=edge)[0][0] - _node(zm[None], t_prev, p=0.3, edge=edge)[0][0]
        ) / (2 * h)
    assert np.allclose(d[0], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
    # and in the last step's traction (the history a path adjoint runs back through)
    dh = _node(z[None], t_prev, p=0.3, history=True, edge=edge)[3][0]
    fd = np.zeros((3, 3))
    for k in range(3):
        tp, tm = t_prev.copy(), t_prev.copy()
        tp[0, k] += h
        tm[0, k] -= h
        fd[:, k] = (_node(z[None], tp, p=0.3, edge=edge)[0][0] - _node(z[None], tm, p=0.3, edge=edge)[0][0]) / (2 * h)
    assert np.allclose(dh, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_rounded_cone_edge_is_continuously_differentiable_and_exact_outside_the_band():
    x = np.linspace(0.0, 2.0, 2001)
    assert np.array_equal(np.asarray(cone_magnitude(x, 0.0)), np.minimum(x, 1.0))
    d = 0.1
    f = np.asarray(cone_magnitude(x, d))
    out = (x <= 1 - d) | (x >= 1 + d)
    assert np.array_equal(f[out], np.minimum(x, 1.0)[out])
    assert (f <= np.minimum(x, 1.0) + 1e-15).all() and np.min(np.minimum(x, 1.0) - f) >= 0
    assert np.max(np.minimum(x, 1.0) - f) == pytest.approx(d / 4, rel=1e-12)  # at x = 1
    # value and slope continuous at both ends of the band (one-sided differences meet)
    for x0, slope in ((1 - d, 1.0), (1 + d, 0.0)):
        h = 1e-7
        left = (cone_magnitude(x0, d) - cone_magnitude(x0 - h, d)) / h
        right = (cone_magnitude(x0 + h, d) - cone_magnitude(x0, d)) / h
        assert float(left) == pytest.approx(slope, abs=1e-5) and float(right) == pytest.approx(slope, abs=1e-5)


def test_coulomb_options_are_validated():
    assert Coulomb(0.3).resolve_eps(2.0, 0.5) == pytest.approx(400.0)
    assert Coulomb(0.3, eps=7.0).resolve_eps(2.0, 0.5) == 7.0
    for bad in (-0.1, float("nan"), "0.3", True):
        with pytest.raises(ConfigError, match="mu"):
            Coulomb(bad)
    with pytest.raises(ConfigError, match="eps"):
        Coulomb(0.3, eps=0.0)
    for bad in (-0.1, 1.0, float("nan"), True):
        with pytest.raises(ConfigError, match="edge"):
            Coulomb(0.3, edge=bad)
