"""Friction kinematics on tet10 faces (tri6, :func:`contopt.contact.quadratic.quadratic_pair_slip`): the
slip of a rigid sliding, the gap and area rows those of the frictionless kernel, the consistent load
of a uniform traction, and exact derivatives (central differences)."""

import numpy as np
import pytest
from test_mortar_tri6 import CH, _cases, _moved, pairs, quad6, tri6  # tests/contact/test_mortar_tri6.py

from contopt.contact.quadratic import (
    quadratic_slip_hessians,
    quadratic_slips_and_jacobians,
    quadratic_values_and_jacobians,
)


def _z(X, Xp, topo, sub, kinds):
    return quadratic_slips_and_jacobians(X, Xp, topo, sub, kinds, chunk=CH)[0]


def test_rigid_sliding_slips_by_the_displacement_times_the_weights_integral_and_loads_consistently():
    """A flat tri6 slid by d over a larger quad: s_A = d a_A with a_A = ∫ W_A; a rigid motion of both
    is no slip; a uniform traction t puts ∫ N_b t on node b (0 on the corners, area/3 on the midpoints:
    the tet10's consistent load, which the patch test needs)."""
    nm = tri6([(0, 0), (1, 0), (0.2, 0.9)])
    m = quad6((0.4, 0.4), 3.0, 0.0)
    kinds = ("tri6", "quad")
    X, topo, sub = pairs(nm, m, kinds)
    d = np.array([0.03, -0.02, 0.0])
    Xp = X.copy()
    Xp[:, :6] -= d
    z, J, Js = quadratic_slips_and_jacobians(X, Xp, topo, sub, kinds, chunk=CH)
    a = z[:, :, 1]
    np.testing.assert_allclose(z[:, :, 2:5], a[:, :, None] * d, atol=1e-15)
    np.testing.assert_allclose(z[:, :, 5:8], a[:, :, None] * [0, 0, 1], atol=1e-15)
    assert np.abs(_z(X, X - [0.3, 0.1, -0.2], topo, sub, kinds)[:, :, 2:5]).max() < 1e-15
    g, a0, Jn = quadratic_values_and_jacobians(X, topo, sub, kinds, chunk=CH)
    np.testing.assert_allclose(z[:, :, 0], g, atol=1e-15)
    np.testing.assert_allclose(z[:, :, 1], a0, rtol=1e-13)
    np.testing.assert_allclose(J[:, :, 0], Jn[:, :6], atol=1e-13)
    np.testing.assert_allclose(J[:, :, 1], Jn[:, 6:], atol=1e-13)
    t = np.array([0.7, -0.4, 0.0])
    f = np.einsum("c,pkcj->j", t, Js).reshape(12, 3)  # the nonmortar's virtual work of -t
    area = 0.5 * 0.9
    np.testing.assert_allclose(f[:6], np.outer(area * np.r_[0, 0, 0, 1, 1, 1] / 3, t), atol=1e-15)
    np.testing.assert_allclose(f[6:].sum(axis=0), -area * t, rtol=1e-13)


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("case", [0, 1, 3], ids=["tri6-tri6", "tri6-quad", "quad-tri6"])
def test_slip_jacobians_and_force_derivatives_match_central_differences(case):
    nm, m, kinds = _cases()[case]
    X, topo, sub = pairs(nm, m, kinds)
    assert len(X) >= 3 and (topo[:, :, 0] == 2).any()  # clipped polygons, several sub-facets
    rng = np.random.default_rng(5)
    Xp = X - rng.uniform(-0.05, 0.05, (1, 12, 3))  # one previous position for the pair's nodes
    z, J, Js = quadratic_slips_and_jacobians(X, Xp, topo, sub, kinds, chunk=CH)
    live = z[:, :, 1] > 0
    assert np.abs(z[:, :, 2:5]).max() > 1e-4
    # tangential per pair, and the virtual-work rows: a translation of the nonmortar alone slips P0 d a
    assert np.abs(np.einsum("pkc,pkc->pk", z[..., 2:5], z[..., 5:8])).max() < 1e-15
    dvec = np.array([0.3, -0.2, 0.5])
    n0 = z[:, :, 5:8].sum(axis=1) / z[:, :, 1].sum(axis=1)[:, None]
    P0d = dvec - (n0 @ dvec)[:, None] * n0
    nm_only = np.r_[np.tile(dvec, 6), np.zeros(18)]
    if kinds[0] == "quad":  # the two ignored slots carry no weight: moving them does nothing
        nm_only[12:18] = 0.0
    np.testing.assert_allclose(Js @ nm_only, z[..., 1:2] * P0d[:, None, :], atol=1e-14)
    np.testing.assert_allclose(Js @ np.tile(dvec, 12), 0.0, atol=1e-14)
    assert live.sum() >= 3
    h = 1e-6
    for k in range(36):
        fd = (_z(_moved(X, k, h), Xp, topo, sub, kinds) - _z(_moved(X, k, -h), Xp, topo, sub, kinds)) / (2 * h)
        assert np.abs(J[..., k] - fd).max() <= 1e-7 * np.abs(fd).max() + 1e-12, k
    w = rng.normal(size=(len(X), 6, 3))
    H = quadratic_slip_hessians(X, Xp, topo, sub, w, kinds, chunk=CH)
    assert np.abs(H).max() > 1e-3
    for k in range(36):
        grads = []
        for sgn in (1, -1):
            Jsk = quadratic_slips_and_jacobians(_moved(X, k, sgn * h), Xp, topo, sub, kinds, chunk=CH)[2]
            grads.append(np.einsum("pkc,pkcj->pj", w, Jsk))
        fd = (grads[0] - grads[1]) / (2 * h)
        assert np.abs(H[:, :, k] - fd).max() <= 1e-6 * np.abs(fd).max() + 1e-12, k
