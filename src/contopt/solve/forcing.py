"""How tightly an inexact Newton iteration solves its linear system (Eisenstat & Walker 1996).

An iterative solver stops Newton iteration k's solve ``K du = rhs`` at ``|K du - rhs| <=
eta_k |rhs|``. Loose solves far from the answer save Krylov iterations; tight ones near it keep
Newton's convergence. Two measures of "near":

* choice 2, ``eta_k = gamma (|r_k| / |r_{k-1}|)^alpha``: the residual falls fast;
* the linear model's agreement (choice 1, with the vector difference), ``|r_k - m_k| / |rhs_{k-1}|``
  with ``m_k = (1 - a) r_{k-1} + a (K du - rhs)`` the residual the last iteration's linear model
  predicted for its step ``a du``: where the response is linear the model is exact and only the
  linear solve's error is left, so the next solve should be tight (the first load step of a body
  moved through a gap: 5 Newton iterations with choice 2 alone, 3 with both).

The term is the smaller of the two, at most ``krylov_eta_max``, never tighter than what brings
the residual to half Newton's target, and never tighter than ``krylov_rtol``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from contopt.solve.linear import LinearSolverOptions
from contopt.vectors import norm

#: Eisenstat-Walker: the constants of choice 2
EW_GAMMA, EW_ALPHA = 0.9, 2.0


def forcing_term(
    linear: LinearSolverOptions,
    residuals: Sequence[float],
    eta_prev: float,
    target: float,
    agreement: float | None = None,
) -> float:
    """The relative tolerance of the linear solve of this Newton iteration.

    ``residuals``: ``|r_free|`` so far (the last one is the current); ``eta_prev``: the previous
    iteration's term; ``target``: the residual at which Newton stops; ``agreement``: the last
    step's :func:`model_agreement` (None: not measured). Choice 2, kept from dropping faster than
    ``gamma eta_{k-1}^alpha`` while that is above 0.1; the first iteration takes
    ``krylov_eta_max``. ``forcing="fixed"``: ``krylov_rtol``.
    """
    if linear.forcing == "fixed":
        return linear.krylov_rtol
    eta_max = linear.krylov_eta_max
    r_k = residuals[-1]
    if len(residuals) < 2 or residuals[-2] <= 0:
        eta = eta_max
    else:
        eta = EW_GAMMA * (r_k / residuals[-2]) ** EW_ALPHA
        floor = EW_GAMMA * eta_prev**EW_ALPHA
        if floor > 0.1:
            eta = max(eta, floor)
        if agreement is not None:
            eta = min(eta, agreement)
    eta = min(eta, eta_max)
    if r_k > 0:
        eta = max(eta, min(eta_max, 0.5 * target / r_k))
    return max(eta, linear.krylov_rtol)


def model_agreement(r_new: np.ndarray, r_old: np.ndarray, lin: np.ndarray, rhs_norm: float, alpha: float) -> float:
    """``|r_new - m| / |rhs|`` with ``m = (1 - alpha) r_old + alpha lin``: how far the residual
    after the step ``alpha du`` lies from the linear model's prediction. ``lin = K du - rhs`` is the
    linear solve's residual (with a prescribed jump in ``rhs``, ``m`` is still the model's
    residual: the jump is scaled by ``alpha`` with the rest of the step). Vectors (n_free,)."""
    if not rhs_norm > 0:
        return 1.0
    return norm(r_new - ((1.0 - alpha) * r_old + alpha * lin)) / rhs_norm
