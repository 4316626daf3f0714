"""The hyperelastic energy kernels: ``W(I1, I2, J, params)`` as pure JAX functions of invariants.

An energy is a pure JAX function ``W(I1, I2, J, params)`` of the invariants
of ``F`` (``I1 = tr C``, ``I2 = (tr(C)^2 - tr(C^2))/2``, ``J = det F``) and a
parameter vector, so that one compiled kernel serves every body of the same
material type. Any isotropic hyperelastic law fits this form. The element
kernels differentiate ``W`` by AD with respect to the three scalars and
chain to ``F`` with closed-form invariant derivatives, which is exact and
an order of magnitude faster under XLA than AD of ``psi(F)`` directly.

The materials that hand these to the analysis (their parameters, their checks) are in
:mod:`contopt.material.hyperelastic`, which loads no JAX.
"""

from __future__ import annotations

import jax.numpy as jnp


def mooney_rivlin_energy(I1, I2, J, params):
    """Strain energy density per unit reference volume from the invariants of F.

    ``W = kappa/2 (ln J)^2 + A (I1bar - 3) + B (I2bar - 3)`` (:mod:`contopt.material.hyperelastic`).

    Parameters
    ----------
    I1, I2, J : scalars ``tr C``, ``(tr(C)^2 - tr(C^2))/2`` and ``det F``
        (J must be positive; J <= 0 gives NaN)
    params : (3,) ``[kappa, A, B]``
    """
    kappa, A, B = params[0], params[1], params[2]
    lnJ = jnp.log(J)
    I1bar = jnp.exp(-2.0 / 3.0 * lnJ) * I1
    I2bar = jnp.exp(-4.0 / 3.0 * lnJ) * I2
    return 0.5 * kappa * lnJ**2 + A * (I1bar - 3.0) + B * (I2bar - 3.0)


def invariants(F):
    """(I1, I2, J) of a (3, 3) deformation gradient: ``tr C``, ``(tr(C)^2 - tr(C^2))/2``, ``det F``."""
    C = F.T @ F
    I1 = jnp.trace(C)
    I2 = 0.5 * (I1**2 - jnp.sum(C * C))
    J = (
        F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
        - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
        + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
    )
    return I1, I2, J


def energy_of_F(energy, F, params):
    """psi(F) = W(I1(F), I2(F), J(F)) for an invariant-based energy ``W``."""
    return energy(*invariants(F), params)
