"""An active-set-predicting Newton direction for frictionless penalty contact (issue 35 §3).

Where a contact zone grows within a load step, each tangent lacks the stiffness of the open nodes just
ahead of its edge: the full step pushes them into the other body, the line search lands where one or two
more facets have closed, and the edge creeps a facet an iteration (docs/performance.md, "Where the
iterations past the predictor go"). :class:`ActiveSetPredictor` looks, after Newton's linear solve,
at the contact gaps at the full step: nodes that it closes (pressure there) but the tangent had open
count as closed, with the closed branch's affine term ``W^T eps gbar`` of those still open in the
right-hand side (the linear model of a primal-dual active-set step), and the direction is solved
again, up to ``NewtonOptions.active_set`` times until the predicted set stops growing. The line
search then runs on the true energy along the last direction, so the answer is the same; each pass
costs a tangent evaluation and a factorization (``NewtonLog.extra["factorizations"]``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contopt.solve.newton import Direction, Iterate, LinearSystem, LoadStep, linear_system, solve_linear
from contopt.vectors import dot


@dataclass(frozen=True, eq=False)
class ActiveSetPredictor:
    """The prediction for one Newton solve of ``system`` at load factor ``t`` with the laws' ``states``
    (every interface a frictionless penalty), at most ``passes`` re-solves an iteration."""

    system: Any
    t: float
    layout: Any
    states: tuple
    passes: int

    def __call__(
        self, step: LoadStep, before: Iterate, x: Iterate, results: tuple, lin: LinearSystem, direction: Direction,
        it: int,
    ) -> tuple[Iterate, LinearSystem, Direction]:  # fmt: skip
        """Iteration ``it``'s direction from ``before`` (its tangent's contact ``results``, the tangent solved
        as ``lin`` into ``x`` and ``direction``), re-solved with the nodes its full step closes counted closed.
        No tangent is held through another's factorization (each is let go of once factored)."""
        contact = self.system.contact
        base = tuple(_closed(res) for res in results)
        forced = tuple(np.zeros_like(b) for b in base)
        for _ in range(self.passes):
            full = contact.evaluate(before.u + direction.du, self.states, tangent=False)
            step.seconds["contact"] += full.seconds
            ahead = tuple((res.lam > 0) & ~_closed(now) for res, now in zip(full.results, results))
            if not any(a.any() for a in ahead):
                break
            forced = tuple(f | a for f, a in zip(forced, ahead))
            closed = tuple(b | f for b, f in zip(base, forced))
            ev = self.system.evaluate(before.u, self.t, self.layout, self.states, True, full=False, closed=closed)
            step.account(ev)
            results = ev.contact
            K, again = linear_system(step, before, ev)
            del ev
            again = replace(again, rhs=again.rhs - self._affine(results, forced)[step.free])
            y, d = solve_linear(step, before, K, again, it)
            del K
            y = replace(y, factorizations=x.factorizations + 1)
            if not dot(again.point.r[step.free], d.du[step.free]) < 0:  # no descent on the energy: keep the last
                return replace(x, factorizations=y.factorizations), lin, direction
            x, lin, direction = y, again, d
        return x, lin, direction

    def _affine(self, results: tuple, forced: tuple) -> np.ndarray:
        """``sum W^T eps gbar`` over the nodes counted closed that are open in the contact ``results`` (n_dofs,)."""
        out = np.zeros(self.system.disc.n_dofs)
        for block, state, res, f in zip(self.system.contact.blocks, self.states, results, forced):
            pick = f & res.has_overlap & (res.lam <= 0)
            if res.W is None or not pick.any():
                continue
            _, eps = block.law.multipliers_and_penalties(state, np.arange(block.n_nodes))
            gbar = np.where(pick, res.g / np.where(pick, res.a, 1.0), 0.0)
            out += res.W.T @ (np.broadcast_to(eps, gbar.shape) * gbar)
        return out


def _closed(res) -> np.ndarray:
    """The nodes closed in an interface result's tangent ((n,) bool)."""
    return np.zeros(len(res.lam), bool) if res.stiff is None else res.stiff > 0
