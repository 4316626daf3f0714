"""Small nonlinear programs with known solutions, and an NLP wrapper that records calls (tests only)."""

import numpy as np

from contopt.optimize.base import DesignEvaluation, EvaluationFailure


class Problem:
    """An NLP from plain functions, recording evaluate calls and reported iterations.

    ``stop_at``: iteration whose report returns False; ``fail(x)``: evaluate raises
    EvaluationFailure where it is true; ``fail_at``: the evaluation (0-based) that raises.
    """

    def __init__(self, lower, upper, fun, stop_at=None, fail=None, fail_at=None):
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.n = self.lower.size
        self.fun = fun
        self.m = np.atleast_1d(fun(0.5 * (self.lower + self.upper))[1]).size
        self.calls, self.failed, self.infos = [], [], []
        self.stop_at, self.fail, self.fail_at = stop_at, fail, fail_at

    def evaluate(self, x):
        self.calls.append(x.copy())
        if (self.fail is not None and self.fail(x)) or (
            self.fail_at is not None and len(self.calls) - 1 == self.fail_at
        ):
            self.failed.append(x.copy())
            raise EvaluationFailure(f"Newton diverged at x[0] = {x[0]:.3f}")
        f, g, df, dg = self.fun(x)
        return DesignEvaluation(
            float(f),
            np.atleast_1d(np.asarray(g, float)),
            np.asarray(df, float),
            np.asarray(dg, float).reshape(self.m, self.n),
        )

    def iteration(self, info):
        self.infos.append(info)
        return info.iteration != self.stop_at


# --- problems with known solutions ---------------------------------------------------

W = np.array([1.0, 1.0, 2.0, 0.5, 1.0])
T = np.array([0.7, 0.5, 0.35, 1.5, -0.1])
V = 2.05
# KKT by hand: x_j = clip(t_j - lam/(2 w_j), 0, 1) with lam = 0.4 gives sum x = V;
# x_4 sits on its upper bound (df_4 + lam = -0.1 < 0), x_5 on its lower one (0.6 > 0)
X_QUAD = np.array([0.5, 0.3, 0.25, 1.0, 0.0])
LAM_QUAD = 0.4


def quadratic(x):
    """sum w (x - t)^2 subject to sum x <= V, on [0, 1]^5."""
    return np.sum(W * (x - T) ** 2), [np.sum(x) - V], 2 * W * (x - T), np.ones((1, 5))


A_TOY, B_TOY = np.array([5.0, 2.0, 1.0]), np.array([3.0, 4.0, 3.0])
# Svanberg's toy problem (2007 note): both spheres active at the optimum
X_TOY = np.array([2.0175185856761395, 1.7800114373391625, 1.2375071483369766])
LAM_TOY = np.array([0.4262397540503336, 0.7595730873836666])


def toy(x):
    """x.x subject to |x - a|^2 <= 9, |x - b|^2 <= 9, on [0, 5]^3."""
    g = [np.sum((x - A_TOY) ** 2) - 9.0, np.sum((x - B_TOY) ** 2) - 9.0]
    return x @ x, g, 2 * x, np.array([2 * (x - A_TOY), 2 * (x - B_TOY)])
