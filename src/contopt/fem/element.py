"""Hex8 element energy, residual and tangent in JAX (one element; batch with vmap).

Energies are isotropic, ``W(I1, I2, J, params)`` (see
:mod:`contopt.material.energy`). With mean-dilatation F-bar (paper
eq. C.4) the quadrature-point gradient is ``Fbar_q = (Theta/J_q)^(1/3) F_q``
with the element volume ratio ``Theta = sum_q wdet_q J_q / V_e``; its
invariants are ``(I1 s^2, I2 s^4, Theta)`` with ``s = (Theta/J)^(1/3)``, so the
element energy is

    W_e(u) = rho_e sum_q wdet_q psi_q,   psi_q = psi_hat(I1_q, I2_q, J_q, Theta).

Why not ``jax.hessian`` of ``W_e``: it costs ~200 us a cell (and AD of
``psi(F)`` at the quadrature point ~40 us) under XLA on CPU, more than the
sparse factorization it feeds. Here AD is applied where it is cheap, to the
scalar function ``psi_hat`` of four invariants, and chained to the nodal
displacements with the closed-form derivatives of the invariants:

    dI1/dF = 2F,  dI2/dF = 2(I1 F - F C),  dJ/dF = cof F,
    d2I1 = 2 d_ik d_JL,
    d2I2 = 4 F_iJ F_kL + 2 I1 d_ik d_JL - 2 d_ik C_JL - 2 F_iL F_kJ - 2 b_ik d_JL,
    d2J  = eps_ikm eps_JLM F_mM.

These assemble, at each quadrature point, the weighted F-space tangent
``A_q = w_q d2psi/dF dF`` (9 x 9: ``sum_nm psi_nm dI_n (x) dI_m + sum_n psi_n d2I_n``), and the
element tangent is ``sum_q G_q^T A_q G_q`` (``G`` the shape gradients) in two contractions, plus
the rank-2 F-bar couplings through ``dTheta/du`` (see :func:`element_residual_tangent`); exact
and symmetric; the tests check it against ``jax.hessian`` of :func:`element_energy` and central
finite differences. (Until 2026-11 the same sum was formed term by term from the nodal images
``G^T dI_n/dF`` of the invariant gradients: the same values to rounding, twice the time under
XLA on CPU, docs/performance.md, "Element kernels".)

Shapes: ``u`` (8, 3) nodal displacements, ``grad`` (q, 8, 3) shape gradients,
``wdet`` (q,) quadrature weight times reference Jacobian, ``rho`` scalar.
Residual (8, 3), tangent (8, 3, 8, 3) indexed ``[a, i, b, k]``. The kernels take any number
of nodes ``n`` a cell from the shapes of ``grad`` (q, n, 3): tet4 (n = 4, q = 1) and tet10
(n = 10, q = 4) run the same energy, residual and tangent with their own shape gradients
and rule (:mod:`contopt.fem.tet`), without F-bar (tet10 does not lock; F-bar at tet4's one
point would be the identity).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

_EPS = np.zeros((3, 3, 3))
_EPS[0, 1, 2] = _EPS[1, 2, 0] = _EPS[2, 0, 1] = 1.0
_EPS[0, 2, 1] = _EPS[2, 1, 0] = _EPS[1, 0, 2] = -1.0
#: d2 det F / dF_iJ dF_kL = eps_ikm eps_JLM F_mM as a constant (81, 9) map of F (row iJkL, column mM)
_D2J = np.einsum("ikm,JLM->iJkLmM", _EPS, _EPS).reshape(81, 9)


def deformation_gradients(u, grad):
    """F_q = I + sum_a u_a (x) dN_a/dX at each quadrature point: (q, 3, 3)."""
    return jnp.eye(3) + jnp.einsum("ai,qaJ->qiJ", u, grad)


def det3(F):
    """Determinant of (..., 3, 3) by the rule of Sarrus (LU-free: cheap, twice differentiable)."""
    return (
        F[..., 0, 0] * (F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1])
        - F[..., 0, 1] * (F[..., 1, 0] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 0])
        + F[..., 0, 2] * (F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0])
    )


def cofactor(F):
    """cof F = d det F / dF for (..., 3, 3): rows are cross products of the other rows."""
    r0, r1, r2 = F[..., 0, :], F[..., 1, :], F[..., 2, :]
    return jnp.stack([jnp.cross(r1, r2), jnp.cross(r2, r0), jnp.cross(r0, r1)], axis=-2)


def volume_ratio(F, wdet):
    """Theta = deformed / reference cell volume (exact for a trilinear hex at 2x2x2 Gauss)."""
    return jnp.dot(wdet, det3(F)) / jnp.sum(wdet)


def fbar(F, theta):
    """Fbar = (Theta / det F)^(1/3) F: same isochoric part, determinant Theta."""
    return jnp.cbrt(theta / det3(F))[..., None, None] * F


def _invariants(F):
    C = jnp.einsum("...kI,...kJ->...IJ", F, F)
    I1 = jnp.trace(C, axis1=-2, axis2=-1)
    I2 = 0.5 * (I1**2 - jnp.sum(C * C, axis=(-2, -1)))
    return I1, I2, det3(F), C


def element_energy(u, grad, wdet, rho, params, energy, use_fbar: bool = True):
    """W_e = rho * sum_q wdet_q psi(Fbar_q): the reference for the residual/tangent (tests, responses)."""
    F = deformation_gradients(u, grad)
    if use_fbar:
        F = fbar(F, volume_ratio(F, wdet))
    I1, I2, J, _ = _invariants(F)
    return rho * jnp.dot(wdet, jax.vmap(energy, in_axes=(0, 0, 0, None))(I1, I2, J, params))


def _psi_hat(z, params, energy):
    """psi of the F-bar gradient as a function of z = (I1, I2, J, Theta) of the plain F."""
    s2 = jnp.cbrt(z[3] / z[2]) ** 2
    return energy(z[0] * s2, z[1] * s2 * s2, z[3], params)


def _psi_plain(z, params, energy):
    return energy(z[0], z[1], z[2], params)


def _scalar_derivatives(z, params, energy, use_fbar):
    """Value, gradient (n,) and Hessian (n, n) of psi w.r.t. its invariants at one point."""
    f = (lambda z: _psi_hat(z, params, energy)) if use_fbar else (lambda z: _psi_plain(z, params, energy))
    value, grad = jax.value_and_grad(f)(z)
    return value, grad, jax.hessian(f)(z)


def element_residual(u, grad, wdet, rho, params, energy, use_fbar: bool = True):
    """dW_e/du: (8, 3)."""
    return element_residual_tangent(u, grad, wdet, rho, params, energy, use_fbar, tangent=False)[1]


def element_residual_tangent(u, grad, wdet, rho, params, energy, use_fbar: bool = True, tangent: bool = True):
    """Energy W_e (scalar), residual (8, 3) and, if ``tangent``, the tangent (8, 3, 8, 3).

    Returns ``(W, r)`` or ``(W, r, K)``; the energy comes at no extra cost and
    serves the line search.
    """
    n = grad.shape[1]
    F = deformation_gradients(u, grad)  # (q, 3, 3)
    I1, I2, J, C = _invariants(F)
    cof = cofactor(F)
    vol = jnp.sum(wdet)
    if use_fbar:
        theta = jnp.dot(wdet, J) / vol
        z = jnp.stack([I1, I2, J, jnp.broadcast_to(theta, J.shape)], axis=1)
    else:
        z = jnp.stack([I1, I2, J], axis=1)
    psi, g, H = jax.vmap(_scalar_derivatives, in_axes=(0, None, None, None))(z, params, energy, use_fbar)
    W = rho * jnp.dot(wdet, psi)

    # the invariant gradients dI_n/dF at each point (q, 3, 3, 3)
    dI = jnp.stack([2.0 * F, 2.0 * (I1[:, None, None] * F - jnp.einsum("qiL,qLJ->qiJ", F, C)), cof], axis=1)
    # the F-space vectors mapped to the nodes in one contraction, v_a = sum_q G_q^T P_q (n, 3): the
    # weighted first Piola stress, and with F-bar dTheta/dF and the Theta-coupling sum_n psi_nT dI_n
    vecs = [jnp.einsum("qn,qnkJ->qkJ", wdet[:, None] * g[:, :3], dI)]
    if use_fbar:
        vecs.append((wdet / vol)[:, None, None] * cof)
        if tangent:
            vecs.append(jnp.einsum("qn,qnkJ->qkJ", wdet[:, None] * H[:, :3, 3], dI))
    nodal = jnp.einsum("qaJ,qvkJ->vak", grad, jnp.stack(vecs, axis=1))
    r = nodal[0]
    if use_fbar:
        s = nodal[1]  # dTheta/du
        psi_T = jnp.dot(wdet, g[:, 3])
        r = r + psi_T * s
    if not tangent:
        return W, rho * r

    # the weighted material tangent in F-space at each point, A[q, i, J, k, L] = w_q d2psi/dF_iJ dF_kL
    # (Theta held; its couplings are the rank-2 terms below), then K = sum_q G_q^T A_q G_q in two
    # contractions: one small (q x 9 x 9) array a point instead of ~20 contractions of the nodal
    # images of each term, whose batched tiny dots and transposes dominated XLA's time on CPU
    # (docs/performance.md, "Element kernels")
    A = _material_tangent(F, C, I1, g, H, wdet, psi_T * wdet / vol if use_fbar else None, dI)
    gradT = jnp.transpose(grad, (0, 2, 1))  # (q, 3, n)
    T = jnp.einsum("qJikL,qbL->qJikb", jnp.transpose(A, (0, 2, 1, 3, 4)), grad)  # A_q G_q
    K = jnp.einsum("Xa,Xikb->aikb", gradT.reshape(-1, n), T.reshape(-1, 3, 3, n))  # (a, i, k, b)
    if use_fbar:
        t = nodal[2]
        psi_TT = jnp.dot(wdet, H[:, 3, 3])
        K = K + jnp.einsum("ai,bk->aikb", t, s) + jnp.einsum("ai,bk->aikb", s, t + psi_TT * s)
    return W, rho * r, rho * jnp.transpose(K, (0, 1, 3, 2))


def _material_tangent(F, C, I1, g, H, wdet, theta_coupling, dI):
    """``w_q d2psi/dF dF`` at each point (q, 3, 3, 3, 3) ``[q, i, J, k, L]`` from the chain rule through
    the invariants: ``sum_nm psi_nm dI_n (x) dI_m + sum_n psi_n d2I_n`` (the closed forms of the
    module docstring); ``theta_coupling`` (q,) or None: the F-bar term ``psi_T w_q / V`` added to
    the weight of d2J (d2Theta/dF dF at one point)."""
    nq = F.shape[0]
    g1, g2, g3 = g[:, 0], g[:, 1], g[:, 2]
    # sum_nm Psi_nm dI_n (x) dI_m; the 4 psi_2 F (x) F term of d2I2 is psi_2 dI_1 (x) dI_1 (dI_1 = 2F)
    Psi = H[:, :3, :3].at[:, 0, 0].add(g2) * wdet[:, None, None]
    d9 = dI.reshape(nq, 3, 9)
    Pd = [sum(Psi[:, m, l, None] * d9[:, l] for l in range(3)) for m in range(3)]  # (Psi dI)_m (q, 9)
    A = sum(d9[:, m, :, None] * Pd[m][:, None, :] for m in range(3)).reshape(nq, 3, 3, 3, 3)
    # identity-in-components part (2 g1 + 2 I1 g2) d_ik d_JL - 2 g2 d_ik C_JL, and -2 g2 (F_iL F_kJ + b_ik d_JL)
    alpha = (wdet * (2.0 * g1 + 2.0 * I1 * g2))[:, None, None, None, None]
    beta = (wdet * 2.0 * g2)[:, None, None, None, None]
    eye = jnp.asarray(np.eye(3))
    b = jnp.einsum("qiJ,qkJ->qik", F, F)
    A = A + eye[None, :, None, :, None] * (alpha * eye[None, None, :, None, :] - beta * C[:, None, :, None, :])
    Ft = jnp.transpose(F, (0, 2, 1))
    A = A - beta * F[:, :, None, None, :] * Ft[:, None, :, :, None]
    A = A - beta * b[:, :, None, :, None] * eye[None, None, :, None, :]
    # d2J_iJkL = eps_ikm eps_JLM F_mM, a constant (81, 9) map of F, weighted by dpsi/dJ (+ the F-bar coupling)
    gamma = wdet * g3 if theta_coupling is None else wdet * g3 + theta_coupling
    return A + (gamma[:, None] * (F.reshape(nq, 9) @ _D2J.T)).reshape(nq, 3, 3, 3, 3)


def cauchy_stress(u, grad, wdet, params, energy, use_fbar: bool = True):
    """Cauchy stress sigma = P Fbar^T / det Fbar at each quadrature point: (q, 3, 3)."""
    F = deformation_gradients(u, grad)
    if use_fbar:
        F = fbar(F, volume_ratio(F, wdet))

    def psi(F):
        I1, I2, J, _ = _invariants(F)
        return energy(I1, I2, J, params)

    P = jax.vmap(jax.grad(psi))(F)
    return jnp.einsum("qiJ,qkJ->qik", P, F) / det3(F)[:, None, None]
