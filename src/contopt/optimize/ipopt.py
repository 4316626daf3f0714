"""IPOPT (interior point, filter line search) through cyipopt's ``Problem`` class.

The :class:`~contopt.optimize.base.NLP` goes to IPOPT as

    minimize f(x)  s.t.  -2e19 <= g(x) <= 0,  lower <= x <= upper

(IPOPT reads bounds beyond 1e19 as infinite) with a dense Jacobian (m is
small) and a limited-memory (L-BFGS) Hessian approximation, as the NLP has no
Hessian. IPOPT asks for f, g, df and dg in separate callbacks; one
``nlp.evaluate`` serves them all through a small cache of evaluations keyed by
the exact bytes of x, so that every distinct point is evaluated once.

Iterates
--------
IPOPT's per-iteration callback (``intermediate``) receives numbers but not the
iterate. Ipopt >= 3.14 lets cyipopt read it (``Problem.get_current_iterate``);
the first call of ``intermediate`` tries that and, where it does not work (the
system Ipopt 3.11 here: cyipopt raises RuntimeError), the iterate reported is
the last x at which IPOPT asked for a derivative (objective gradient or
constraint Jacobian). That is the current iterate: IPOPT evaluates trial points
of its line search with values only, and each iteration starts with the
convergence check, which needs the gradient of the Lagrangian, hence df and dg,
at the new iterate, before it calls ``intermediate``. The Jacobian counts too
because the restoration phase (``extra["alg_mod"] == 1``) needs dg but not df
at its iterates. In the regular phase the adapter checks that IPOPT's own
objective value matches f at the reported x and logs a warning if not.

IPOPT calls ``intermediate`` twice with the same count where its restoration
phase returns (the same point, once as the last restoration iterate, once as a
regular one); only the first is passed on, so ``nlp.iteration`` sees strictly
increasing iteration numbers.

Evaluation failures
-------------------
An :class:`EvaluationFailure` in the objective or constraint callback returns
nan, which IPOPT treats as an evaluation error at a trial point: it cuts its
line-search step back (and leaves a failing region that way). In the gradient
or Jacobian callback (a point where IPOPT needs derivatives, i.e. an accepted
iterate or the initial point) there is nothing to back off to: the callback
raises cyipopt's ``CyIpoptEvaluationError``, IPOPT stops (status
"Invalid_Number_Detected") and the result is "failed" with the failure's
message. Any other exception raised in a callback (or by ``nlp.iteration``)
stops IPOPT at once and is re-raised by :func:`run_ipopt` after ``solve``
returns, with its traceback.
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from contopt import extras
from contopt.errors import ConfigError
from contopt.optimize.base import (
    NLP,
    DesignEvaluation,
    EvaluationFailure,
    IterationInfo,
    OptimizerResult,
    bounds_and_start,
    checked,
)

log = logging.getLogger(__name__)

NO_LOWER = -2e19  # below IPOPT's nlp_lower_bound_inf (-1e19): no lower bound on g
CACHE_SIZE = 8  # distinct x kept; IPOPT revisits only recent points (trial, current, restoration)
MU_STRATEGIES = ("monotone", "adaptive")
HESSIANS = ("limited-memory",)
_INT_MAX = 2**31 - 1
_OWN_KEYS = {
    "tol": "tol",
    "max_iter": "max_iter",
    "hessian_approximation": "hessian",
    "limited_memory_max_history": "limited_memory_max_history",
    "print_level": "print_level",
    "mu_strategy": "mu_strategy",
}

# Ipopt's ApplicationReturnStatus codes
_CONVERGED = (0, 1)  # Solve_Succeeded, Solved_To_Acceptable_Level
_MAX_ITER = -1  # Maximum_Iterations_Exceeded
_USER_STOP = 5  # User_Requested_Stop


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class IpoptOptions:
    """Options of :func:`run_ipopt`, validated at construction.

    tol : IPOPT's ``tol`` (relative KKT tolerance of the scaled problem), > 0
    max_iter : IPOPT's ``max_iter``, integer in [0, 2**31 - 1] (IPOPT's C int)
    hessian : ``hessian_approximation``; only "limited-memory" (the NLP has no Hessian)
    limited_memory_max_history : L-BFGS pairs kept, integer >= 0
    print_level : IPOPT's console output, 0 (silent) to 12
    mu_strategy : barrier update, "monotone" or "adaptive"
    options : further raw IPOPT options as ``(name, value)`` pairs, value a str,
        int or float, passed as given after the ones above (a name that has
        its own key above is refused)
    """

    tol: float = 1e-3
    max_iter: int = 100
    hessian: str = "limited-memory"
    limited_memory_max_history: int = 6
    print_level: int = 0
    mu_strategy: str = "monotone"
    options: tuple = ()

    def __post_init__(self):
        tol = self.tol
        if not (
            isinstance(tol, (int, float, np.integer, np.floating))
            and not isinstance(tol, (bool, np.bool_))
            and math.isfinite(float(tol))
            and float(tol) > 0.0
        ):
            raise ConfigError(f"ipopt.tol must be a number > 0, got {tol!r}")
        object.__setattr__(self, "tol", float(tol))
        # IPOPT takes its integer options as C ints
        for key, lo, hi in (
            ("max_iter", 0, _INT_MAX),
            ("limited_memory_max_history", 0, _INT_MAX),
            ("print_level", 0, 12),
        ):
            value = getattr(self, key)
            if not _is_int(value) or value < lo or (hi is not None and value > hi):
                allowed = f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
                raise ConfigError(f"ipopt.{key} must be {allowed}, got {value!r}")
            object.__setattr__(self, key, int(value))
        if self.hessian not in HESSIANS:
            raise ConfigError(
                f"ipopt.hessian must be 'limited-memory' (the problem has no exact Hessian), got {self.hessian!r}"
            )
        if self.mu_strategy not in MU_STRATEGIES:
            raise ConfigError(f"ipopt.mu_strategy must be one of 'monotone', 'adaptive', got {self.mu_strategy!r}")
        object.__setattr__(self, "options", _raw_options(self.options))


def _raw_options(options) -> tuple:
    """``options`` as a tuple of (str, str | int | float) pairs; ConfigError naming ipopt.options."""
    if isinstance(options, (str, bytes, dict)) or not isinstance(options, (tuple, list)):
        raise ConfigError(f"ipopt.options must be a sequence of (name, value) pairs, got {options!r}")
    pairs = []
    for item in options:
        if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str) and item[0]):
            raise ConfigError(f"ipopt.options entries must be (name, value) pairs, got {item!r}")
        name, value = item
        if name in _OWN_KEYS:
            raise ConfigError(f"ipopt.options: {name!r} has its own key, ipopt.{_OWN_KEYS[name]}")
        if _is_int(value):
            value = int(value)
            if abs(value) > _INT_MAX:
                raise ConfigError(
                    f"ipopt.options: {name!r} = {value} does not fit IPOPT's integers (at most {_INT_MAX})"
                )
        elif isinstance(value, (float, np.floating)):
            value = float(value)
        elif not isinstance(value, str):
            raise ConfigError(f"ipopt.options: the value of {name!r} must be a str, int or float, got {value!r}")
        pairs.append((name, value))
    return tuple(pairs)


class Callbacks:
    """The problem object handed to ``cyipopt.Problem``: NLP evaluations and iteration reports.

    ``problem(callbacks)`` makes the ``cyipopt.Problem`` that calls them (kept as ``problem``: its
    ``get_current_iterate`` gives the iterate). Attributes after a solve: ``evaluations`` (calls of
    ``nlp.evaluate``), ``last_info`` (the last reported IterationInfo), ``error`` (the first
    exception other than EvaluationFailure), ``failure`` (the last
    EvaluationFailure), ``derivative_failure`` (one where IPOPT needed derivatives).
    """

    def __init__(self, nlp: NLP, n: int, m: int, problem: Callable[[Callbacks], Any]):
        self.nlp, self.n, self.m = nlp, n, m
        self.cache: OrderedDict[bytes, DesignEvaluation | EvaluationFailure] = OrderedDict()
        self.evaluations = 0
        self.last_derivative: tuple[np.ndarray, DesignEvaluation] | None = None
        self.use_current_iterate: bool | None = None  # decided at the first intermediate call
        self.last_info: IterationInfo | None = None
        self.error: BaseException | None = None
        self.failure: EvaluationFailure | None = None
        self.derivative_failure: EvaluationFailure | None = None
        self.objective_mismatch_logged = False
        self.problem = problem(self)  # last: cyipopt looks at the callbacks it is given

    # --- evaluations -------------------------------------------------------

    def _evaluated(self, x: np.ndarray) -> DesignEvaluation:
        """The evaluation at ``x`` (cached by its exact bytes); raises a (cached) EvaluationFailure."""
        key = x.tobytes()
        hit = self.cache.get(key)
        if hit is None:
            self.evaluations += 1
            try:
                hit = self._checked(self.nlp.evaluate(x.copy()))
            except EvaluationFailure as exc:
                hit = exc
            self.cache[key] = hit
            while len(self.cache) > CACHE_SIZE:
                self.cache.popitem(last=False)
        else:
            self.cache.move_to_end(key)
        if isinstance(hit, EvaluationFailure):
            raise hit
        return hit

    def _checked(self, ev: DesignEvaluation) -> DesignEvaluation:
        return checked(ev, self.n, self.m)

    def _record(self, exc: BaseException) -> None:
        if self.error is None:
            self.error = exc

    def _value(self, x: np.ndarray, pick, failed):
        """``pick(evaluation)`` for the objective/constraint callbacks; ``failed`` (nan) on failure."""
        if self.error is not None:
            return failed
        try:
            return pick(self._evaluated(x))
        except EvaluationFailure as exc:
            self.failure = exc
            log.info("IPOPT: evaluation failed at a trial point, backing off: %s", exc)
            return failed
        except BaseException as exc:  # noqa: BLE001 - kept and re-raised after solve
            self._record(exc)
            return failed

    def _derivative(self, x: np.ndarray, pick):
        """``pick(evaluation)`` for the gradient/Jacobian callbacks; remembers x as the current iterate."""
        from cyipopt import CyIpoptEvaluationError

        if self.error is not None:
            raise CyIpoptEvaluationError("stopping after an exception in a callback")
        try:
            ev = self._evaluated(x)
        except EvaluationFailure as exc:
            self.failure = self.derivative_failure = exc
            log.warning("IPOPT: evaluation failed where derivatives are needed: %s", exc)
            raise CyIpoptEvaluationError(str(exc)) from exc
        except BaseException as exc:  # noqa: BLE001 - kept and re-raised after solve
            self._record(exc)
            raise CyIpoptEvaluationError("stopping after an exception in a callback") from exc
        self.last_derivative = (x.copy(), ev)
        return pick(ev)

    # --- cyipopt callbacks -----------------------------------------------------

    def objective(self, x: np.ndarray) -> float:
        return self._value(x, lambda ev: ev.f, float("nan"))

    def constraints(self, x: np.ndarray) -> np.ndarray:
        return self._value(x, lambda ev: ev.g, np.full(self.m, np.nan))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        return self._derivative(x, lambda ev: ev.df)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        return self._derivative(x, lambda ev: ev.dg.ravel())  # row-major, as jacobianstructure

    def jacobianstructure(self) -> tuple[np.ndarray, np.ndarray]:
        rows = np.repeat(np.arange(self.m), self.n)
        cols = np.tile(np.arange(self.n), self.m)
        return rows, cols

    def intermediate(
        self,
        alg_mod,
        iter_count,
        obj_value,
        inf_pr,
        inf_du,
        mu,
        d_norm,
        regularization_size,
        alpha_du,
        alpha_pr,
        ls_trials,
    ) -> bool:
        if self.error is not None:
            return False
        if self.last_info is not None and iter_count == self.last_info.iteration:
            # IPOPT reports the point where its restoration phase ends twice (alg_mod 1,
            # then 0) under one count; the NLP sees each iteration once, numbers increasing
            log.debug("IPOPT iteration %d reported again (alg_mod %d): skipped", iter_count, alg_mod)
            return True
        try:
            x, ev, source = self.current_iterate()
            if (
                alg_mod == 0
                and not self.objective_mismatch_logged
                and not abs(obj_value - ev.f) <= 1e-8 * max(1.0, abs(ev.f))
            ):
                self.objective_mismatch_logged = True
                log.warning(
                    "IPOPT iteration %d: IPOPT's objective %.17g differs from f = %.17g at the reported iterate (%s)",
                    iter_count,
                    obj_value,
                    ev.f,
                    source,
                )
            previous = self.last_info
            change = float("nan") if previous is None else float(np.max(np.abs(x - previous.x), initial=0.0))
            extra = {
                "inf_pr": float(inf_pr),
                "mu": float(mu),
                "alpha_pr": float(alpha_pr),
                "alpha_du": float(alpha_du),
                "ls_trials": int(ls_trials),
                "d_norm": float(d_norm),
                "regularization_size": float(regularization_size),
                "alg_mod": int(alg_mod),
                "obj_value": float(obj_value),
                "iterate_source": source,
            }
            info = IterationInfo(
                iteration=int(iter_count),
                x=x.copy(),
                f=ev.f,
                g=ev.g.copy(),
                optimality=float(inf_du),
                change=change,
                extra=extra,
            )
            self.last_info = info
            log.debug(
                "IPOPT it %d: f = %.6g, inf_pr = %.3g, inf_du = %.3g, mu = %.3g", iter_count, ev.f, inf_pr, inf_du, mu
            )
            return bool(self.nlp.iteration(info))
        except BaseException as exc:  # noqa: BLE001 - kept and re-raised after solve
            self._record(exc)
            return False

    def current_iterate(self) -> tuple[np.ndarray, DesignEvaluation, str]:
        """(x, its evaluation, how x was found) for the iteration IPOPT is reporting."""
        if self.use_current_iterate is None:
            self.use_current_iterate = self._current_iterate_works()
            log.debug(
                "IPOPT: iterates from %s",
                "get_current_iterate" if self.use_current_iterate else "the last derivative request",
            )
        if self.use_current_iterate:
            x = np.array(self.problem.get_current_iterate(scaled=False)["x"], dtype=np.float64)
            return x, self._evaluated(x), "get_current_iterate"
        if self.last_derivative is None:
            raise RuntimeError("IPOPT reported an iteration before asking for any derivative")
        x, ev = self.last_derivative
        return x, ev, "last_derivative"

    def _current_iterate_works(self) -> bool:
        """Whether ``get_current_iterate`` gives x (Ipopt >= 3.14; cyipopt raises RuntimeError before)."""
        getter = getattr(self.problem, "get_current_iterate", None)
        if getter is None:
            return False
        try:
            iterate = getter(scaled=False)
        except Exception:  # noqa: BLE001 - any failure means: not available
            return False
        return isinstance(iterate, dict) and np.shape(iterate.get("x")) == (self.n,)


def _add_options(problem, options: IpoptOptions) -> None:
    """Set IPOPT's options; ConfigError naming the option IPOPT refuses."""
    pairs = [
        ("print_level", options.print_level),
        ("sb", "yes"),
        ("tol", options.tol),
        ("max_iter", options.max_iter),
        ("hessian_approximation", options.hessian),
        ("limited_memory_max_history", options.limited_memory_max_history),
        ("mu_strategy", options.mu_strategy),
        *options.options,
    ]
    for name, value in pairs:
        try:
            problem.add_option(name, value)
        except TypeError:
            raise ConfigError(
                f"ipopt.options: IPOPT refused the option {name!r} = {value!r} "
                "(unknown name, wrong type or value out of range)"
            ) from None


@contextlib.contextmanager
def _quiet_cyipopt():
    """cyipopt logs every callback (``b'jacobian_cb'``, ...) at INFO: keep that for DEBUG only."""
    logger = logging.getLogger("cyipopt")
    level = logger.level
    if not log.isEnabledFor(logging.DEBUG):
        logger.setLevel(logging.WARNING)
    try:
        yield
    finally:
        logger.setLevel(level)


def _solve(callbacks: Callbacks, x, options, log_file) -> dict:
    """IPOPT's run of the callbacks from x; its info dict (the callbacks' own error re-raised)."""
    problem = callbacks.problem
    try:
        _add_options(problem, options)
        if log_file is not None:
            problem.add_option("output_file", str(log_file))
            problem.add_option("file_print_level", 5)
        try:
            _, info = problem.solve(x)
        except BaseException:
            if callbacks.error is not None:
                raise callbacks.error  # noqa: B904 - the callback's exception is the one that matters
            raise
    finally:
        problem.close()
    return info


def require_ipopt() -> None:
    """Raise :class:`contopt.extras.MissingExtra` (how to install it, or to run MMA) without cyipopt."""
    if not extras.installed("ipopt"):
        raise extras.MissingExtra(
            extras.missing("ipopt", "the IPOPT optimizer needs")
            + '; or optimize with MMA (--optimizer mma, or name = "mma" under [optimizer])'
        )


def run_ipopt(
    nlp: NLP, x0: np.ndarray, options: IpoptOptions | None = None, log_file: str | None = None
) -> OptimizerResult:
    """Minimize ``nlp`` from ``x0`` with IPOPT.

    ``nlp.iteration`` is called once per IPOPT iteration (0 = the starting point,
    which IPOPT may first push inside the bounds by its ``bound_push``) with the
    iterate, ``optimality`` = IPOPT's scaled dual infeasibility ``inf_du`` and
    IPOPT's other numbers in ``extra``; returning False stops with status
    "stopped". The result holds the last reported iterate (x0 with nan values if
    IPOPT stopped before its first iteration). x0 outside the bounds raises
    :class:`ConfigError`. ``log_file``: IPOPT's own iteration table and summary go there
    (IPOPT's ``output_file``, ``file_print_level`` 5), whatever ``print_level`` says for the console.
    """
    require_ipopt()
    import cyipopt

    options = IpoptOptions() if options is None else options
    n, m = int(nlp.n), int(nlp.m)
    lower, upper, x = bounds_and_start(nlp, x0, "ipopt", finite=False)

    def problem(callbacks):
        return cyipopt.Problem(
            n=n, m=m, problem_obj=callbacks, lb=lower, ub=upper, cl=np.full(m, NO_LOWER), cu=np.zeros(m)
        )

    with _quiet_cyipopt():
        callbacks = Callbacks(nlp, n, m, problem)
        info = _solve(callbacks, x, options, log_file)
    if callbacks.error is not None:
        raise callbacks.error

    code = int(info["status"])
    message = info["status_msg"]
    message = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
    if code in _CONVERGED:
        status = "converged"
    elif code == _MAX_ITER:
        status = "max_iter"
    elif code == _USER_STOP:
        status = "stopped"
    else:
        status = "failed"
        failure = callbacks.derivative_failure or callbacks.failure
        if failure is not None:
            message += f" (last evaluation failure: {failure})"
    last = callbacks.last_info
    log.info(
        "IPOPT %s (status %d) after %s iterations: %s", status, code, "no" if last is None else last.iteration, message
    )
    if last is None:
        return OptimizerResult(
            x=x,
            f=float("nan"),
            g=np.full(m, np.nan),
            iterations=0,
            status=status,
            message=message,
            evaluations=callbacks.evaluations,
        )
    return OptimizerResult(
        x=last.x.copy(),
        f=last.f,
        g=last.g.copy(),
        iterations=last.iteration,
        status=status,
        message=message,
        evaluations=callbacks.evaluations,
    )
