"""``backend="auto"`` on a contact tangent: the direct factor or the AMG, as this model's own
matrices measure them (issue 41 §2).

Neither solver wins on every contact model of one size. On the fine die-slab (43,821 free dofs)
CG + GAMG, its preconditioner kept over Newton iterations, ran the forward 1.3-1.5x faster than
Pardiso; on the fine Hertz line mesh (33,128) the same AMG needed about 250 CG iterations a solve
and failed at 300, several seconds a solve against about one for a factorization. So a contact
tangent from :attr:`LinearSolverOptions.trial_above` rows on, whose direct factor fits in memory
(:func:`contopt.solve.linear.base.direct_fits`), is decided by a trial:

1. the first :data:`DIRECT_MATRICES` matrices on its dofs are factored directly; the faster
   factorization's wall is the yardstick ``direct_seconds`` (the first pays the symbolic analysis
   that later ones on the same pattern reuse);
2. the next :data:`TRIAL_MATRICES` matrices go to the AMG, each solve stopped once it has run
   :data:`TRIAL_SLACK` x ``direct_seconds`` (then that matrix is factored directly);
3. the AMG stays while its mean cost per matrix (matrix copy, set-up, solves) over its last
   :data:`TRIAL_MATRICES` matrices is at most ``direct_seconds``; otherwise every later matrix on
   these dofs is factored. A solve of the kept AMG that runs :data:`AMG_SLACK` x
   ``direct_seconds``, fails, or meets negative curvature (an indefinite tangent: GMRES with
   the AMG may converge, slowly, Newton iteration after Newton iteration) also ends it. A
   factorization made after a failed AMG solve is the new yardstick (contact that closes makes
   the factor larger).

So ``auto`` loses at most about ``TRIAL_SLACK`` factorizations to a hopeless AMG, and gains the
AMG's reuse where it works. The verdict is kept per set of dofs in this process (the design
iterations of an optimization share it): :class:`Choice`, at most :data:`KEPT` of them.
A factorization the user asked to keep (``factor_reuse``) is a direct solver's: no trial then.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from contopt.solve.linear.base import Geometry, direct_fits, logger
from contopt.solve.linear.options import LinearSolverOptions

#: direct factorizations before the trial (the yardstick is the faster)
DIRECT_MATRICES = 2
#: matrices the AMG gets before its verdict
TRIAL_MATRICES = 3
#: a trial solve is stopped after this many times the direct factorization's wall
TRIAL_SLACK = 2.0
#: a solve of the AMG kept after its trial is stopped after this many times that wall
AMG_SLACK = 3.0
#: verdicts kept (the most recent sets of dofs)
KEPT = 4

VERDICTS = ("untried", "trial", "amg", "direct")


@dataclass(eq=False)
class Choice:
    """What ``auto`` measured on the contact tangents of one set of dofs.

    free : (n,) int64, the dofs of the rows; direct_seconds : the yardstick (a direct factorization's
    wall); amg_seconds : the AMG's cost of its last matrices; verdict : one of :data:`VERDICTS`;
    direct_count : the direct factorizations recorded.
    """

    free: np.ndarray
    direct_seconds: float = 0.0
    amg_seconds: list = field(default_factory=list)
    verdict: str = "untried"
    direct_count: int = 0

    @property
    def wants_amg(self) -> bool:
        return self.verdict in ("trial", "amg")

    @property
    def budget(self) -> float:
        """Seconds one AMG solve may run before it is stopped and the matrix factored."""
        return self.direct_seconds * (TRIAL_SLACK if self.verdict == "trial" else AMG_SLACK)

    def record_direct(self, seconds: float) -> None:
        """A direct factorization's wall: the yardstick. Before the trial, the faster of the first
        :data:`DIRECT_MATRICES` (the first also pays the symbolic analysis, which Pardiso keeps
        for the next matrix of the pattern: 73 s against about 20 s on the paper-size sabot)."""
        self.direct_count += 1
        if self.verdict != "untried":
            self.direct_seconds = seconds
            return
        self.direct_seconds = seconds if self.direct_count == 1 else min(self.direct_seconds, seconds)
        if self.direct_count >= DIRECT_MATRICES:
            self.verdict = "trial"

    def record_amg(self, seconds: float, failed: bool) -> None:
        """One matrix's AMG cost; ``failed``: a solve ran out of its budget or did not converge.
        The AMG is judged on its last :data:`TRIAL_MATRICES` matrices, in the trial and after it
        (a load step where contact closes can make its solves slower than a factorization)."""
        if self.verdict not in ("trial", "amg"):
            return
        if failed:
            self._decide("direct", f"an AMG solve failed or ran past {self.budget:.2f} s")
            return
        self.amg_seconds.append(seconds)
        del self.amg_seconds[:-TRIAL_MATRICES]  # only the last few are judged: an optimization's run is long
        if len(self.amg_seconds) < TRIAL_MATRICES:
            return
        mean = float(np.mean(self.amg_seconds))
        won = mean <= self.direct_seconds
        if self.verdict == "trial" or not won:
            self._decide("amg" if won else "direct", f"AMG {mean:.2f} s a matrix over the last {TRIAL_MATRICES}")

    def _decide(self, verdict: str, why: str) -> None:
        self.verdict = verdict
        logger.info(
            "solver auto on this %d-row contact tangent: %s from now on (%s; a direct factorization %.2f s)",
            self.free.size, "the AMG" if verdict == "amg" else "direct factorizations", why, self.direct_seconds,
        )  # fmt: skip


#: the verdicts of this process, the most recent last
_CHOICES: list[Choice] = []


def choice_for(
    opts: LinearSolverOptions, n: int, geometry: Geometry | None, amg_available: Callable[[], bool]
) -> Choice | None:
    """The trial's record for this matrix, or None where ``auto`` does not decide by trial: not
    ``auto``, no contact, distributed, below ``trial_above`` rows, ``factor_reuse`` on, a direct
    factor that would not fit in memory (then the size rule holds), or no AMG installed
    (``amg_available()``, asked last: loading PETSc installs its signal handlers)."""
    if (
        opts.backend != "auto"
        or geometry is None
        or not geometry.contact
        or geometry.comm.distributed
        or n < opts.trial_above
        or opts.factor_reuse
        or not direct_fits(n)
        or not amg_available()
    ):
        return None
    for choice in _CHOICES:
        if choice.free.size == geometry.free.size and np.array_equal(choice.free, geometry.free):
            return choice
    choice = Choice(free=np.array(geometry.free, dtype=np.int64))
    _CHOICES.append(choice)
    del _CHOICES[:-KEPT]
    return choice


def forget() -> None:
    """Drop every verdict (tests; a new model on the same dofs)."""
    _CHOICES.clear()
