"""The load cases' analyses in worker processes (``[run] case_workers``, ``--case-workers``; issue 40 §2).

A :class:`CasePool` holds ``case_workers`` processes (at most one per case), started with the
``spawn`` method (JAX must not be forked once it is initialized), each with its own copy of the
problem: it builds the cases' systems once and keeps its JAX kernels compiled (the persistent
compilation cache makes the second process's compile a load) and float64 on (:func:`setup_jax`).
Case ``c`` always goes to worker ``c % workers``. Per design evaluation the parent sends each
worker only the design's fields and the warm starts of its cases (:func:`analyze_case` is a pure
function of the case, the design and the case's start, so a case gives the same bits in a worker
as in the parent; the reference analysis of ``normalize = "full"``, :func:`reference_case`, goes
to the workers alike, once, before the first evaluation) and gets back each case's converged state,
adjoint result and seconds, or the error it raised, with the log records the analysis made
(emitted in the parent, in case order).

The parent keeps every warm start (``LoadCasesNLP.starts``, the checkpoint's ``Record.cases``): a
worker keeps nothing between evaluations but its model, so a resumed run, or one with another
number of workers, warm-starts each case as before. The workers ignore Ctrl-C (the parent stops
them), end when the parent's end of their pipe closes (a parent killed outright leaves no orphan
waiting) and are stopped when the run ends (:func:`case_pool`, a context manager).
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import pickle
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from contopt.config import setup_jax
from contopt.errors import ConfigError, WorkerError
from contopt.optimize.problem import DesignProblem
from contopt.parallel import world
from contopt.timing import Stopwatch

log = logging.getLogger(__name__)

#: seconds a worker gets to end after it is told to, before it is terminated
STOP_SECONDS = 10.0


@dataclass(frozen=True)
class CaseOutcome:
    """One case's analysis in a worker: ``result`` (state, cold, adjoint result) or ``error`` (what
    it raised), the ``seconds`` it took and the log ``records`` it made."""

    result: tuple | None
    error: BaseException | None
    seconds: float
    records: tuple


@dataclass(frozen=True, eq=False)
class CasePool:
    """``workers``: the processes (and the parent's ends of their pipes), in the order cases go to them."""

    workers: tuple

    @property
    def size(self) -> int:
        return len(self.workers)

    def analyze(self, fields, mass, starts: list) -> list[CaseOutcome]:
        """Each case's :class:`CaseOutcome` at the design ``fields`` (volume loads scaled by ``mass``),
        case ``c`` warm-started from ``starts[c]`` (None: from zero), the cases of a worker in order;
        its ``result`` is :func:`~contopt.optimize.multicase.analyze_case`'s."""
        return self._run("analysis", fields, mass, starts)

    def reference(self, full, mass, n_cases: int) -> list[CaseOutcome]:
        """Each of the ``n_cases`` cases' :class:`CaseOutcome` of the reference analysis (``normalize =
        "full"``) at the full design ``full``: its ``result`` is
        :func:`~contopt.optimize.multicase.reference_case`'s (the objective and the warm start)."""
        return self._run("reference", full, mass, [None] * n_cases)

    def _run(self, task: str, fields, mass, starts: list) -> list[CaseOutcome]:
        n = self.size
        _ignore_broken_pipes()
        for k, (proc, conn) in enumerate(self.workers):
            if not proc.is_alive():
                raise _ended(k, proc)
            try:
                conn.send((task, fields, mass, [(c, s) for c, s in enumerate(starts) if c % n == k]))
            except OSError:  # a broken pipe: the worker is gone
                raise _ended(k, proc) from None
        out: dict[int, CaseOutcome] = {}
        for k, (proc, conn) in enumerate(self.workers):
            try:
                out.update(conn.recv())
            except (EOFError, OSError):
                raise _ended(k, proc) from None
        return [out[c] for c in range(len(starts))]

    def close(self, wait: bool = True) -> None:
        """Tell the workers to end, and terminate those that do not within :data:`STOP_SECONDS`
        (``wait`` False: at once; a worker writes nothing, so nothing is lost)."""
        for _proc, conn in self.workers:
            try:
                conn.send(None)
            except (OSError, ValueError):  # it is gone already
                pass
        for proc, conn in self.workers:
            proc.join(timeout=STOP_SECONDS if wait else 0.0)
            if proc.is_alive():
                proc.terminate()
                proc.join()
            conn.close()


def _ignore_broken_pipes() -> None:
    """SIGPIPE ignored, as Python starts: a library loaded since (measured in the test suite) may have
    reset it to the default, which kills the process on a write to a worker that died, with no message;
    ignored, the write raises BrokenPipeError, reported in one line. (Only the main thread may set it.)"""
    if hasattr(signal, "SIGPIPE") and threading.current_thread() is threading.main_thread():  # not on Windows
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)


def _ended(k: int, proc) -> WorkerError:
    """The error for worker ``k``, whose process ended without its result."""
    proc.join(timeout=STOP_SECONDS)
    return WorkerError(
        f"the worker process {k} of the load cases ended without its result (exit code {proc.exitcode}: "
        "killed, or out of memory?); resume the run with case_workers = 1 (--case-workers 1), which "
        "needs the memory of one model instead of one a worker"
    )


@contextmanager
def case_pool(problem: DesignProblem) -> Iterator[CasePool | None]:
    """The pool of ``problem.case_workers`` processes (fewer when there are fewer cases) for the run
    inside the ``with``, stopped at its end however it ends; None when the cases run in this process
    (one worker, or no load cases). Ended by an exception (Ctrl-C among them), it terminates the
    workers at once; else it lets them finish."""
    n = min(problem.case_workers, len(problem.load_cases))
    if n <= 1:
        yield None
        return
    if world().distributed:
        raise ConfigError(
            f"case_workers = {problem.case_workers} under mpiexec: the ranks analyse every case together; "
            "use case_workers = 1"
        )
    try:
        payload = pickle.dumps(problem)
    except (pickle.PicklingError, TypeError, AttributeError) as err:
        raise ConfigError(
            f"case_workers = {problem.case_workers} needs a problem that can be sent to other processes, "
            f"and this one cannot ({err}); use case_workers = 1"
        ) from None
    ctx = mp.get_context("spawn")  # a forked JAX process can deadlock
    workers = []
    try:
        for k in range(n):
            conn, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(child, payload), name=f"contopt-case-worker-{k}", daemon=True)
            proc.start()
            child.close()
            workers.append((proc, conn))
        log.info("load cases: %d worker processes", n)
        yield CasePool(tuple(workers))
    except BaseException:  # Ctrl-C, SIGTERM, an error: a worker's analysis under way is not waited for
        CasePool(tuple(workers)).close(wait=False)
        raise
    CasePool(tuple(workers)).close()


class _Records(logging.Handler):
    """Keeps the log records of one case's analysis, to be emitted by the parent."""

    def __init__(self):
        super().__init__(logging.INFO)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        record.msg, record.args, record.exc_info, record.exc_text = record.getMessage(), None, None, None
        self.records.append(record)


def _worker(conn, payload: bytes) -> None:
    """A worker's life: build the problem's cases once, then analyse what the parent sends until it
    sends None or goes away."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the parent, which stops the workers
    setup_jax()
    from contopt.optimize.multicase import LoadCasesNLP, analyze_case, reference_case  # JAX: after setup_jax

    nlp = LoadCasesNLP(pickle.loads(payload))
    responses = nlp._responses()
    handler = _Records()
    root = logging.getLogger()
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):  # the parent is gone
            return
        if message is None:
            return
        task, fields, mass, jobs = message
        out = {}
        for c, start in jobs:
            clock, error = Stopwatch(), None
            result: tuple | None = None
            handler.records = []
            try:
                if task == "reference":
                    result = reference_case(nlp.cases[c], nlp.problem, fields, mass)
                else:
                    result = analyze_case(nlp.cases[c], nlp.problem, responses, fields, mass, start)
            except Exception as err:  # noqa: BLE001 - the parent raises it as the serial path would
                error = _sendable(err)
            out[c] = CaseOutcome(result, error, clock.seconds, tuple(handler.records))
        conn.send(out)


def _sendable(err: Exception) -> Exception:
    """``err`` if it survives pickling, else a RuntimeError that says what it was."""
    try:
        pickle.loads(pickle.dumps(err))
        return err
    except Exception:  # noqa: BLE001 - any failure to pickle
        return RuntimeError(f"{type(err).__name__}: {err}")
