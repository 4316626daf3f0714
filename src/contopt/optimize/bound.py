"""The bound formulation of a worst case: ``min_x max_k f_k(x)`` as a smooth nonlinear program.

One extra variable, the bound ``z``, appended to the design variables::

    minimize z  over (x, z)  subject to  g_j(x) <= 0 (j = 1..m),  f_k(x) - z <= 0 (k = 1..K)

with the bound's variable in units of ``scale`` (the size of the objectives at the start): the
optimizer's variable is ``t = z / scale``, so that it moves on the scale of the design variables
(IPOPT took steps of about 1 in an unscaled bound of size 100, one per iteration, on the robust
cantilever), while the objective ``z = scale t`` and the rows ``f_k - scale t`` keep the
objectives' own values and gradients (the history's objective is the worst one).

(Bendsøe & Sigmund 2003, 4.3; Svanberg's MMA note, section 5). Pure functions of arrays: any
worst case (the robust formulation's three designs, several load cases) hands its values here,
and MMA and IPOPT see an ordinary :class:`~contopt.optimize.base.DesignEvaluation`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from contopt.optimize.base import DesignEvaluation

#: the bound's box: its start plus or minus this many times max(1, |start|) (MMA's move limit is a
#: share of the box, so it must not be tight; the bound is linear in every function, so wide is harmless)
BOUND_RANGE = 10.0


def bound_scale(f: ArrayLike) -> float:
    """The bound's unit: the largest ``|f_k|`` at the start, at least 1e-12."""
    return max(float(np.max(np.abs(np.asarray(f, dtype=np.float64)))), 1e-12)


def bound_start(f: ArrayLike, scale: float) -> float:
    """The bound variable ``t`` at the start: the largest of the K values ``f`` over ``scale`` (every
    bound row then holds, one at 0)."""
    return float(np.max(np.asarray(f, dtype=np.float64))) / scale


def bound_limits(t0: float) -> tuple[float, float]:
    """``(lower, upper)`` of the bound variable around its start ``t0``."""
    half = BOUND_RANGE * max(1.0, abs(float(t0)))
    return float(t0) - half, float(t0) + half


def bound_evaluation(
    f: ArrayLike, df: ArrayLike, g: ArrayLike, dg: ArrayLike, t: float, scale: float = 1.0
) -> DesignEvaluation:
    """The bound formulation at ``(x, t)`` from the K objectives and the m constraints at ``x``.

    f : (K,) objective values; df : (K, n) their gradients
    g : (m,) constraints (<= 0 feasible); dg : (m, n) their gradients
    t : the bound in units of ``scale`` (z = scale t)
    Returns the evaluation over the n + 1 variables ``(x, t)``: objective ``scale t``, constraints
    ``(m + K,)``, the m given ones first, then ``f_k - scale t``.
    """
    fv, dfv = np.asarray(f, dtype=np.float64), np.atleast_2d(np.asarray(df, dtype=np.float64))
    gv = np.asarray(g, dtype=np.float64)
    m, n = len(gv), dfv.shape[1]
    grad = np.zeros(n + 1)
    grad[n] = scale
    rows = np.zeros((m + len(fv), n + 1))
    rows[:m, :n] = np.asarray(dg, dtype=np.float64).reshape(m, n)
    rows[m:, :n] = dfv
    rows[m:, n] = -scale
    return DesignEvaluation(f=scale * float(t), g=np.concatenate([gv, fv - scale * float(t)]), df=grad, dg=rows)
