"""The load cases analysed in worker processes (contopt.optimize.case_pool, ``[run] case_workers``):
the same objective and gradient as one after the other in this process, a case that fails in a
worker reported as the serial path reports it, the reference analysis of normalize = "full" in the
workers too, the option read and checked, and no process left
behind however the run ends."""

import dataclasses
import signal
import time

import numpy as np
import pytest
from test_load_cases import TWO_CASES, two_cases

from contopt.cases.spec import SpecError, load_spec
from contopt.cli.exits import FAILED, exit_status
from contopt.errors import ConfigError, ConvergenceError, WorkerError
from contopt.optimize.base import EvaluationFailure
from contopt.optimize.case_pool import case_pool
from contopt.optimize.driver import optimize
from contopt.optimize.mma import MMAOptions
from contopt.optimize.multicase import design_nlp
from contopt.optimize.output_options import OutputOptions
from contopt.solve.newton_options import NewtonOptions


@pytest.fixture(scope="module")
def pool():
    """Two workers over the two-case beam (the analyses do not depend on ``combine``)."""
    with case_pool(two_cases("worst", case_workers=2)) as p:
        yield p


def _evaluations(nlp, steps=3):
    x = nlp.start(nlp.space.initial())
    out = []
    for k in range(steps):
        out.append(nlp.evaluate(x))
        x = x.copy()
        x[: nlp.space.n] = np.clip(x[: nlp.space.n] + 0.03 * (k + 1) * (-1) ** k, 0.0, None)
        x = np.clip(x, nlp.lower, nlp.upper)
    return out


@pytest.mark.parametrize("combine", ["sum", "worst"])
def test_the_workers_give_the_objective_and_gradient_of_the_serial_path(pool, combine):
    """Three evaluations, each case warm-started from its own last state: f, g and their gradients
    agree to 1e-12 of their size (a worker's Pardiso analysis is made from its own first matrix, so
    the last bits may differ: docs/optimization.md)."""
    assert pool.size == 2
    serial = _evaluations(design_nlp(two_cases(combine)))
    nlp = design_nlp(two_cases(combine), pool=pool)
    parallel = _evaluations(nlp)
    assert not nlp.last.cold  # warm starts in the workers too
    for a, b in zip(serial, parallel):
        for name in ("f", "g", "df", "dg"):
            u, v = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
            np.testing.assert_allclose(v, u, rtol=0, atol=1e-12 * max(np.abs(u).max(), 1e-300), err_msg=name)


class _Spy:
    """A pool (the NLP calls only ``analyze`` and ``reference``) that keeps what it was asked, in order:
    each call's kind, its outcomes and its wall seconds."""

    def __init__(self, pool):
        self.pool, self.calls = pool, []

    def _call(self, kind, *args):
        start = time.perf_counter()
        outcomes = getattr(self.pool, kind)(*args)
        self.calls.append((kind, outcomes, time.perf_counter() - start))
        return outcomes

    def analyze(self, *args):
        return self._call("analyze", *args)

    def reference(self, *args):
        return self._call("reference", *args)


@pytest.mark.parametrize("combine", ["sum", "worst"])
def test_the_reference_analysis_runs_in_the_workers_and_gives_the_serial_scale(pool, combine):
    """normalize = "full": each case's full design is solved in its worker, once, before the first
    analysis; the scale and each case's first warm start (the full design's displacement) agree
    with the serial path's to 1e-12 of their size (docs/optimization.md: a worker's Pardiso), the
    record's reference seconds hold the reference's wall and its primal and adjoint seconds only the
    analysis's (the cases' own, as the workers timed them)."""
    serial = design_nlp(two_cases(combine))
    scale = serial.objective_scale()
    first = {name: s.u for name, s in serial.starts.items()}
    spy = _Spy(pool)
    nlp = design_nlp(two_cases(combine), pool=spy)
    rec = nlp.record(nlp.space.initial())
    assert [kind for kind, _, _ in spy.calls] == ["reference", "analyze"]
    assert abs(nlp.scale - scale) <= 1e-12 * abs(scale) and scale > 0
    (_, references, wall), (_, analyses, _) = spy.calls
    for case, outcome in zip(nlp.cases, references):
        assert outcome.error is None and outcome.seconds > 0
        value, start = outcome.result
        u = first[case.name]
        np.testing.assert_allclose(start.u, u, rtol=0, atol=1e-12 * np.abs(u).max(), err_msg=case.name)
        assert start.laws == serial.starts[case.name].laws  # the displacement alone, as in serial
    assert wall <= rec.seconds["reference"] < wall + 1.0  # the wall it took here (the full design's chain: ms)
    cases_own = sum(o.seconds for o in analyses)
    assert rec.seconds["primal"] + rec.seconds["adjoint"] == pytest.approx(cases_own, rel=1e-9)
    nlp.record(nlp.space.initial() + 0.01)
    assert [kind for kind, _, _ in spy.calls] == ["reference", "analyze", "analyze"]  # once a run


@pytest.fixture(scope="module")
def failing():
    """Newton limited to one iteration a step: both cases' analyses fail, the full design's too,
    and the pool of two workers that analyses them."""
    problem = two_cases("sum", warm_start=False, newton=NewtonOptions(max_iter=1, min_step=0.5), case_workers=2)
    with case_pool(problem) as p:
        yield problem, p


def test_a_case_whose_reference_fails_in_a_worker_is_reported_as_in_serial(failing):
    problem, p = failing
    serial = design_nlp(problem)
    x = serial.space.initial()
    with pytest.raises(ConvergenceError) as expected:
        serial.evaluate(x)
    nlp = design_nlp(problem, pool=p)
    with pytest.raises(ConvergenceError) as got:
        nlp.evaluate(x)
    assert str(got.value) == str(expected.value) and "\n" not in str(got.value)
    assert nlp.failure.design == serial.failure.design == "the full design in load case 'down' (the reference)"
    assert nlp.failure.last_state is not None and nlp.scale is None
    np.testing.assert_array_equal(nlp.failure.fields.rho, serial.failure.fields.rho)


def test_a_case_that_fails_in_a_worker_is_reported_as_in_serial(failing):
    problem, p = failing
    problem = dataclasses.replace(problem, normalize="none")
    serial = design_nlp(problem)
    x = serial.space.initial()
    with pytest.raises(EvaluationFailure) as expected:
        serial.evaluate(x)
    nlp = design_nlp(problem, pool=p)
    with pytest.raises(EvaluationFailure) as got:
        nlp.evaluate(x)
    assert str(got.value) == str(expected.value)
    assert "design evaluation 0 in load case 'down'" in str(got.value) and "\n" not in str(got.value)
    assert nlp.failure.design == serial.failure.design
    assert isinstance(nlp.failure.error, ConvergenceError) and isinstance(serial.failure.error, ConvergenceError)
    assert nlp.failure.last_state is not None  # what the failed solve reached came back too


def test_the_workers_end_with_the_run_however_it_ends():
    with case_pool(two_cases("sum", case_workers=2)) as p:
        procs = [proc for proc, _ in p.workers]
        assert all(proc.is_alive() for proc in procs)
    assert not any(proc.is_alive() for proc in procs)
    with pytest.raises(KeyboardInterrupt), case_pool(two_cases("sum", case_workers=3)) as p:
        assert p.size == 2  # one worker a case at most
        procs = [proc for proc, _ in p.workers]
        raise KeyboardInterrupt
    assert not any(proc.is_alive() for proc in procs)


def test_a_worker_that_dies_ends_the_evaluation_in_one_line():
    """A worker killed (as the kernel's out-of-memory killer would) ends the evaluation with a
    WorkerError that says what to run instead, not a traceback; also where a library has reset
    SIGPIPE to its default (one did in the whole suite: the write to the dead worker then killed
    pytest without a word)."""
    problem = two_cases("sum", case_workers=2)
    with case_pool(problem) as p:
        nlp = design_nlp(problem, pool=p)
        proc, _ = p.workers[1]
        proc.kill()
        proc.join()
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
        try:
            with pytest.raises(WorkerError, match="case_workers = 1") as err:
                nlp.evaluate(nlp.start(nlp.space.initial()))
            # ignored again before any write: a worker that dies between the liveness check and the
            # write then raises BrokenPipeError, reported as above, instead of killing the process
            assert signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN
        finally:
            signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    assert "\n" not in str(err.value) and "worker process 1" in str(err.value)
    assert exit_status(err.value) == FAILED


def test_one_worker_or_one_case_runs_here():
    with case_pool(two_cases("sum")) as p:
        assert p is None
    plain = load_spec(TWO_CASES.split("[[load_cases]]")[0].replace('combine = "worst"\n', ""), check=False).problem
    with case_pool(dataclasses.replace(plain, case_workers=4)) as p:
        assert p is None


def test_case_workers_is_read_and_checked_in_one_line():
    assert load_spec(TWO_CASES + "\n[run]\ncase_workers = 2\n", check=False).problem.case_workers == 2
    assert load_spec(TWO_CASES, check=False).problem.case_workers == 1
    with pytest.raises(SpecError, match="case_workers"):
        load_spec(TWO_CASES + "\n[run]\ncase_workers = 0\n", check=False)
    for bad in (0, 1.5, True):
        with pytest.raises(ConfigError, match="case_workers must be an integer >= 1"):
            two_cases("sum", case_workers=bad)


@pytest.mark.slow
def test_a_run_with_workers_makes_the_serial_runs_iterates_and_resumes_each_case(tmp_path):
    """optimize() with two workers: the serial run's history to round-off; a serial run cut after
    2 iterations and resumed with two workers warm-starts each case from the state its checkpoint
    kept (no cold solve) and ends where the uninterrupted run does."""
    quiet = OutputOptions(vtu="none", plot=False)
    serial = optimize(two_cases("worst"), options=MMAOptions(max_iter=3), out=tmp_path / "serial", outputs=quiet)
    parallel = optimize(two_cases("worst", case_workers=2), options=MMAOptions(max_iter=3))
    np.testing.assert_allclose(
        [r["objective"] for r in parallel.history], [r["objective"] for r in serial.history], rtol=1e-10
    )
    np.testing.assert_allclose(parallel.x, serial.x, atol=1e-10)
    optimize(two_cases("worst"), options=MMAOptions(max_iter=2), out=tmp_path / "cut", outputs=quiet)
    resumed = optimize(
        two_cases("worst", case_workers=2),
        options=MMAOptions(max_iter=3),
        out=tmp_path / "cut",
        outputs=quiet,
        resume=True,
    )
    assert resumed.replayed >= 3 and [r["cold_solves"] for r in resumed.history] == [0] * 4
    np.testing.assert_allclose(resumed.x, serial.x, rtol=1e-8, atol=1e-10)
