"""The nodal contact potential shared by the penalty and augmented-Lagrangian laws.

Sign convention (docs/formulation.md): weighted gap ``g_A >= 0`` open,
pressure ``p_A >= 0`` compressive, ``p_A g_A = 0``.

The mortar integrals give per node ``g_A = ∫ N_A (x_m - x_nm).n da`` (volume)
and ``a_A = ∫ N_A da`` (area), so ``gbar_A = g_A / a_A`` is a length: the
N_A-weighted mean gap. Enforcing on ``gbar`` makes the penalty ``eps`` a
pressure per unit gap (force/length^3), independent of the mesh size. The
node's potential is

    phi_A(g, a) = a * psi(p_A, g/a),   psi(p, gbar) = [max(0, p - eps gbar)^2 - p^2] / (2 eps)

(paper eqs. 26-28 in this sign convention; the penalty method is ``p = 0``).
Its derivatives, with ``lam = max(0, p - eps gbar)`` and ``H = [p - eps gbar > 0]``:

    dphi/dg = -lam,   dphi/da = psi + lam gbar,
    d2phi/d(g, a)^2 = (eps H / a) v v^T,  v = (1, -gbar)      (rank one)

so the contact tangent is ``sum_A (eps H_A/a_A) w_A w_A^T`` with
``w_A = dg_A - gbar_A da_A``, plus the second derivatives of the mortar
integrals weighted by ``(dphi/dg, dphi/da)``. Uzawa update: ``p <- lam``. The laws that use
this potential and their outer loops are in :mod:`contopt.contact.laws`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class NodeTerms:
    """Node-level values of the contact potential for the nodes with overlap.

    Attributes (all (n,) arrays)
    ----------------------------
    gbar : normalized gap g/a (length)
    lam : contact pressure max(0, p - eps gbar)
    energy : phi_A
    d_g, d_a : dphi/dg, dphi/da
    stiff : eps H / a, the weight of the rank-one tangent term
    """

    gbar: np.ndarray
    lam: np.ndarray
    energy: np.ndarray
    d_g: np.ndarray
    d_a: np.ndarray
    stiff: np.ndarray


def node_terms(g: np.ndarray, a: np.ndarray, p: np.ndarray, eps, touch: float | np.ndarray = 0.0) -> NodeTerms:
    """Potential, first and second derivatives at nodes with ``a > 0`` (g, a, p: (n,); eps: a
    number or (n,), the penalty per node).

    ``touch`` (a length, or one per node): a node whose trial gap ``gbar - p/eps`` is below
    ``touch`` counts as closed in the tangent. At exactly touching surfaces
    (zero gap, zero pressure) the potential has a kink; taking the closed
    branch there (a valid generalized derivative) gives a body that is held
    only by contact the stiffness it needs in the first Newton iteration.
    """
    g, a, p = (np.asarray(v, dtype=np.float64) for v in (g, a, p))
    gbar = g / a
    trial = p - eps * gbar
    active = trial > -eps * touch
    lam = np.maximum(trial, 0.0)
    psi = (lam**2 - p**2) / (2.0 * eps)
    return NodeTerms(
        gbar=gbar, lam=lam, energy=a * psi, d_g=-lam, d_a=psi + lam * gbar, stiff=np.where(active, eps / a, 0.0)
    )
