"""Newton's and the load stepping's options (:class:`NewtonOptions`), apart from the solver that
imports JAX: reading a problem file about them (``contopt schema``, ``contopt explain``) loads none."""

from __future__ import annotations

from dataclasses import dataclass

from contopt.errors import ConfigError

#: the line searches of a Newton step
LINE_SEARCHES = ("backtracking", "none")


@dataclass(frozen=True)
class NewtonOptions:
    """Newton and load-stepping settings (validated at construction).

    rtol : converged when ``|r_free| <= rtol * r_ref`` (``r_ref``: the largest of
        the external load, the reactions and the step's first residual)
    atol : absolute residual floor (for problems with no load at all); also converged when
        ``|r_free|`` is at the round-off of the internal forces, ``ROUNDOFF * |diag(K) x|`` with x
        the free dofs' positions (a step that loads nothing: a body moving freely before it touches
        another; a nearly incompressible body), or when two full Newton steps in a row are below
        ``SQRT_EPS * |u|`` without lowering ``|r_free|`` below ``sqrt(rtol) r_ref`` by half (the
        round-off floor of an ill-conditioned tangent, measured by the solve itself)
    utol : and ``|du| <= utol * |u|`` for the last increment; a solve that stagnates with ``|r_free|``
        below ``sqrt(rtol) r_ref`` (or creeps there to ``max_iter``) is converged when its last two full
        Newton steps (exact tangent) are below ``utol * |u|``: the state is known to that, whatever noise
        the residual carries
    max_iter : Newton iterations per step before the step counts as failed
    line_search : ``"backtracking"`` or ``"none"``
    max_line_search : halvings of a step the backtracking line search tries
    n_steps : initial number of equal load steps
    min_step : smallest load-factor increment before giving up
    max_step : largest increment after regrowth (default: the initial one)
    grow, cutback : step growth factor after an easy step / reduction after a failure
    easy_iterations : a step converged within this many iterations lets the step grow
    divergence_factor : a solve whose residual grows this many times over its first one has diverged
    watchdog : iterations a full Newton step that raised the energy gets to bring it below the
        point it left (a nonmonotone "watchdog" line search); 0 takes no such step. Where a contact
        zone closes, the tangent of an iterate with the nodes still open misses their stiffness, so
        the full step overshoots into the other body and the backtracking line search keeps only
        1/8..1/32 of it, iteration after iteration; from the overshot point the tangent has the
        right contact nodes and the next step lands near equilibrium. When the iterations allowed
        do not get below, Newton goes back to that point and backtracks along its step after all,
        and the rest of the load step backtracks as with 0.
        Taken only far from convergence and with an energy (not with friction); the contact solver
        turns it off in the solves after a multiplier update, which start at an equilibrium, and in a
        load step that starts in contact with penalty laws, whose contact-aware predictor leaves the
        edge nodes about their touch (there a full step only flips them).
    active_set : with every contact interface a frictionless penalty, how many times an iteration's
        direction is solved again with the contact nodes its full step closes (but its tangent had open)
        counted closed, with the closed branch's force term, until that set stops growing (a predicted
        active set: :mod:`contopt.solve.activeset`; default 3); 0 never. Each pass costs a tangent
        evaluation and a factorization; the line search stays on the true energy, so the answer is
        the same. The penalty Hertz line at Kratos' size: docs/performance.md.
    stall_rtol : None (default): a solve that stagnates (less than a halving of ``|r|`` over six
        iterations) or reaches ``max_iter`` fails and the load step is cut back. A number (>=
        rtol, < 1): such a solve is accepted, with a warning and "accepted at stagnation" in its
        log, when ``|r_free| <= stall_rtol * r_ref``. For frictional contact, whose nonsmooth
        stick/slip law can leave Newton creeping at residuals near its tolerance (docs/friction.md);
        the state then balances to ``stall_rtol`` instead of ``rtol``, and gradients are as
        accurate as that.
    leap : in a solve from zero with contact, no friction and no load, where every body's prescribed
        dofs move as one rigid translation (a press), the load steps before the contact surfaces can
        first touch are taken as one step to the last of them (default true): the steps in contact
        are the same, so is the answer (:mod:`contopt.solve.freeflight`). False takes every step.
    """

    rtol: float = 1e-9
    atol: float = 1e-14
    utol: float = 1e-6
    max_iter: int = 25
    line_search: str = "backtracking"
    max_line_search: int = 8
    n_steps: int = 1
    min_step: float = 1e-4
    max_step: float | None = None
    grow: float = 1.5
    cutback: float = 0.5
    easy_iterations: int = 6
    divergence_factor: float = 1e8
    watchdog: int = 2
    stall_rtol: float | None = None
    active_set: int = 3
    leap: bool = True

    def __post_init__(self):
        if self.line_search not in LINE_SEARCHES:
            raise ConfigError(f"newton.line_search must be one of {LINE_SEARCHES}, got {self.line_search!r}")
        for key in ("rtol", "utol", "min_step", "grow", "divergence_factor"):
            if not (getattr(self, key) > 0):
                raise ConfigError(f"newton.{key} must be > 0, got {getattr(self, key)!r}")
        if not (self.atol >= 0):
            raise ConfigError(f"newton.atol must be >= 0, got {self.atol!r}")
        if not (0 < self.cutback < 1):
            raise ConfigError(f"newton.cutback must lie in (0, 1), got {self.cutback!r}")
        for key in ("max_iter", "n_steps", "easy_iterations", "max_line_search", "watchdog", "active_set"):
            v, lowest = getattr(self, key), 0 if key in ("max_line_search", "watchdog", "active_set") else 1
            if isinstance(v, bool) or not isinstance(v, int) or v < lowest:
                what = "a non-negative" if lowest == 0 else "a positive"
                raise ConfigError(f"newton.{key} must be {what} integer, got {v!r}")
        if not isinstance(self.leap, bool):
            raise ConfigError(f"newton.leap must be true or false, got {self.leap!r}")
        if self.stall_rtol is not None and (
            isinstance(self.stall_rtol, bool)
            or not isinstance(self.stall_rtol, (int, float))
            or not (self.rtol <= self.stall_rtol < 1)
        ):
            raise ConfigError(
                f"newton.stall_rtol must be None or a number in [rtol, 1) = [{self.rtol:g}, 1), got {self.stall_rtol!r}"
            )
        if self.max_step is not None and not (0 < self.max_step <= 1):
            raise ConfigError(f"newton.max_step must lie in (0, 1], got {self.max_step!r}")
