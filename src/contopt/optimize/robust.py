"""The robust formulation of a density design (Wang, Lazarov & Sigmund 2011) as one NLP.

Each design ``x`` is analysed three times, as its eroded, intermediate and dilated projections
(:class:`contopt.design.maps.Robust`), and the optimizer minimizes the worst objective by the
bound formulation (:mod:`contopt.optimize.bound`) over ``(x, z)`` (the optimizer's last variable is
``t = z / s``, s the largest ``|f_k|`` at the start)::

    minimize z  subject to  volume(intermediate) <= nu_max,  constraints of each design <= 0,
                            f_e(x) - z <= 0,  f_i(x) - z <= 0,  f_d(x) - z <= 0

The volume constraint is on the intermediate design, the one that is made: the volume needs no
analysis, so it is exact and free at that design (Wang et al. bound the dilated design's volume
with a limit rescaled every few iterations so that the intermediate meets the target; the bound
on the intermediate states the same target directly). Response constraints hold for all three.

Each realization is a :class:`~contopt.optimize.problem.DesignNLP` of its own, with its own cache
and its own warm start (its last converged state); the objective's scale is shared.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from contopt.design.maps import REALIZATIONS
from contopt.errors import ConfigError
from contopt.optimize.base import EvaluationFailure, same_design
from contopt.optimize.bound import bound_evaluation, bound_limits, bound_scale, bound_start
from contopt.optimize.problem import DesignNLP, DesignProblem, Record

#: the order in which the realizations are analysed: the intermediate first, whose objective
#: fixes the scale of normalize="initial"
ORDER = ("intermediate", "eroded", "dilated")
#: the eroded design's largest volume fraction below which the start counts as void (the optimizers stop at once)
VOID_START = 0.05

log = logging.getLogger(__name__)


class RobustNLP(DesignNLP):
    """A :class:`DesignProblem` whose design has ``robust`` set, as an NLP over ``(x, z)``.

    ``space``, ``fields`` and the volume fractions are the intermediate design's; ``members``
    maps each realization to its own :class:`DesignNLP`. The last variable is the bound ``z``;
    its box is fixed by :meth:`start`.
    """

    def __init__(self, problem: DesignProblem, **kw):
        if problem.design.robust is None:
            raise ConfigError("RobustNLP needs a design with robust = Robust(delta); use DesignNLP otherwise")
        super().__init__(problem, **kw)
        self.members = {
            k: DesignNLP(replace(problem, model=self.system, design=problem.design.realization(k))) for k in ORDER
        }
        self.n_design = self.space.n
        self.n = self.n_design + 1
        self.lower = np.append(self.space.lower, -np.inf)
        self.upper = np.append(self.space.upper, np.inf)
        self.bound_scale = 1.0  # fixed by start(): the largest |objective| there
        self.n_volume = len(self.constraint_names) - len(self._rows)
        names = self.constraint_names
        self.constraint_names = names[: self.n_volume] + [
            f"{name}[{k}]" for k in REALIZATIONS for name in names[self.n_volume :]
        ]
        self.constraint_names += [f"objective[{k}]<=bound" for k in REALIZATIONS]
        self.m = len(self.constraint_names)

    def start(self, x: np.ndarray) -> np.ndarray:
        """``(x, t0)`` (n + 1,) from the start design ``x`` (n,): ``t0`` the worst objective there (the
        three analyses, which the first evaluation then finds in the members' caches) in units of the
        largest ``|f_k|`` there, or, on a resumed run, as the next recorded evaluation has them (a
        continuation's later stage starts at a later one). Fixes
        the bound's unit and box."""
        x = self.space.check_x(x)
        first = self.replay[0] if self.replay else None
        if first is not None and first.index == self.n_evaluations and same_design(first.x[: self.n_design], x):
            # a resumed run: the bound as recorded, not from analyses that now start cold
            f = [first.responses[f"objective[{k}]"] / self.objective_scale() for k in REALIZATIONS]
            t0 = float(first.x[-1])
            self.bound_scale = bound_scale(f)
        else:
            f = [rec.f for rec in self._members_at(x).values()]
            self.bound_scale = bound_scale(f)
            t0 = bound_start(f, self.bound_scale)
            self._warn_if_void(x)
        self.lower[-1], self.upper[-1] = bound_limits(t0)
        return np.append(x, t0)

    def _warn_if_void(self, x: np.ndarray) -> None:
        """One warning when the start's eroded design is void: its sensitivities vanish and MMA and IPOPT
        stop at once (measured from the grey start at eta = 10); a softer Heaviside start helps."""
        largest = float(np.max(self.members["eroded"].space.forward(x).nu, initial=0.0))
        if largest < VOID_START:
            eta = self.problem.design.heaviside.eta
            log.warning(
                "robust: the start's eroded design is void (largest nu %.2g at eta %g), so the optimizer may stop "
                "at once; raise eta within the run from a softer one ([design] eta_continuation = {start = 4}), "
                "or start at --eta 4 and continue from that run at eta %g (--design-from RUN)",
                largest,
                eta,
                eta,
            )

    def fields(self, x):
        return self.space.forward(np.asarray(x)[: self.n_design])

    def realization_fields(self, fields) -> dict:
        """Per designed body, the eroded and dilated volume fractions of ``fields.x``: ``{body: {name: (k,)}}``."""
        out: dict = {p.spec.body: {} for p in self.space.parts}
        for k in ("eroded", "dilated"):
            nu = self.members[k].space.forward(fields.x).nu
            for p in self.space.parts:
                out[p.spec.body][f"nu_{k}"] = nu[p.cells]
        return out

    def _members_at(self, x: np.ndarray) -> dict[str, Record]:
        """Each realization's record at ``x`` (n,), analysed (or cached) with the shared scale."""
        self.objective_scale()  # the full design, once, for all three
        recs = {}
        for k in ORDER:
            member = self.members[k]
            member.scale = self.scale  # None only before the intermediate's first (normalize="initial")
            if member._start is None and member.last is None:
                member._start = self._start  # the first design starts from the full design's displacement
            try:
                recs[k] = member.record(x)
            except EvaluationFailure:
                self.failure = member.failure
                raise
            self.scale = member.scale
        return recs

    def _solve(self, xz: np.ndarray) -> Record:
        index = self.n_evaluations
        recs = self._members_at(xz[: self.n_design])
        order = [recs[k] for k in REALIZATIONS]
        nv, mid = self.n_volume, recs["intermediate"]
        g = np.concatenate([mid.g[:nv], *[r.g[nv:] for r in order]])
        dg = np.concatenate([mid.dg[:nv], *[r.dg[nv:] for r in order]])
        f, df = [r.f for r in order], [r.df for r in order]
        ev = bound_evaluation(f, df, g, dg, float(xz[-1]), self.bound_scale)
        responses = {f"{name}[{k}]": v for k, r in recs.items() for name, v in r.responses.items()}
        responses.update({f"objective[{k}]": r.objective for k, r in recs.items()})
        seconds = {key: sum(r.seconds.get(key, 0.0) for r in order) for key in mid.seconds}
        self.last_state = self.members["intermediate"].last_state
        return replace(
            mid,
            index=index,
            x=xz.copy(),
            f=ev.f,
            g=ev.g,
            df=ev.df,
            dg=ev.dg,
            objective=max(r.objective for r in order),
            responses=responses,
            newton_iterations=sum(r.newton_iterations for r in order),
            alm_updates=sum(r.alm_updates for r in order),
            newton_solves=sum(r.newton_solves for r in order),
            cold=any(r.cold for r in order),
            seconds=seconds,
        )
