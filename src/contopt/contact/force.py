"""The force two bodies exchange through a contact interface: the resultant of its residual forces.

The contact residual ``r_b`` of an interface is the force the contact potential puts on every node
of both bodies. Summed over the mortar body's nodes and negated it is the force the nonmortar body
exerts on the mortar body, ``F = -T^T r_b`` with ``T`` (n_dofs, 3) the rigid translation of the
mortar body. Where the only load path between two supports runs through the interface, ``F``
equals the reaction at either support to Newton's tolerance, whatever the mesh: on a curved or
coarse nonmortar surface the pressure integral ``sum_A lam_A a_A`` (a normal force per node,
summed without its direction) does not.

Derivatives, in the adjoint's model (``contopt.adjoint.sensitivity``: the residual is
``r_b = -sum_A lam_A w_A`` at fixed pressures, ``w_A = dg_A - gbar_A da_A`` the rows ``W``):
``dF/dlam = W T`` and ``dF/du = -K_geo T`` with ``K_geo`` the interface's tangent less its rank-one
pressure terms. For a penalty interface the adjoint adds ``dlam/du = -diag(eps H/a) W`` and the
two make ``-K_b T``, the exact derivative of ``F``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.contact.system import ContactDiscretization, evaluate_interface
from contopt.errors import ConfigError


@dataclass(frozen=True, eq=False)
class ExchangedForce:
    """The force one interface's nonmortar body exerts on its mortar body, with its derivatives.

    force : (3,); d_lam : (n, 3) its derivative by the interface's nodal pressures; d_u : (n_dofs, 3)
    by the displacements at fixed pressures (see the module docstring)
    """

    force: np.ndarray
    d_lam: np.ndarray
    d_u: np.ndarray


def exchanged_force(
    contact: ContactDiscretization, u: np.ndarray, states: tuple, index: int, mortar_dofs: slice
) -> ExchangedForce:
    """:class:`ExchangedForce` of interface ``index`` at displacement u (n_dofs,) with the contact
    laws' ``states`` (the State's ``laws``: the multipliers and penalties of its last solve);
    ``mortar_dofs``: the dofs of the interface's mortar body."""
    block = contact.blocks[index]
    if block.friction is not None:
        raise ConfigError(
            f"contact interface {block.interface.label}: the exchanged force along a direction is for "
            "frictionless interfaces (its gradient would miss the load path); use ContactForce() and FrictionForce"
        )
    x = contact.X + np.asarray(u, dtype=np.float64).reshape(-1, 3)
    result, r_b, K_b, _ = evaluate_interface(block, x, states[index], contact.n_dofs, True)
    T = np.zeros((contact.n_dofs, 3))
    for k in range(3):
        T[mortar_dofs.start + k : mortar_dofs.stop : 3, k] = 1.0
    force = -(T.T @ r_b)
    if K_b is None or result.W is None:  # no pair near the interface: no force
        return ExchangedForce(force=force, d_lam=np.zeros((block.n_nodes, 3)), d_u=np.zeros((contact.n_dofs, 3)))
    _, K_geo = K_b
    return ExchangedForce(force=force, d_lam=np.asarray(result.W @ T), d_u=-np.asarray(K_geo @ T))
