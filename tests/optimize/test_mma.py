"""MMA (contopt.optimize.mma): known optima, the protocol (one evaluate per iteration,
stopping, failures), determinism, the subproblem solver and option validation."""

import math

import numpy as np
import pytest
from _nlp import LAM_QUAD, LAM_TOY, X_QUAD, X_TOY, Problem, quadratic, toy  # tests/optimize/_nlp.py

from contopt.errors import ConfigError
from contopt.optimize import MMAOptions, run_mma
from contopt.optimize.base import DesignEvaluation
from contopt.optimize.mma import (
    EPSIMIN,
    PrimalDual,
    asymptotes,
    kkt_residual,
    mmasub,
)
from contopt.optimize.mma_subsolv import newton_direction, sub_residual

TIGHT = MMAOptions(max_iter=300, kkt_tol=1e-6, change_tol=0.0)


C_BEAM = np.array([61.0, 37.0, 19.0, 7.0, 1.0])
# Svanberg's 1987 cantilever: min 0.0624 sum x s.t. sum c/x^3 <= 1; Lagrange gives
# x_j = c_j^(1/4) (sum_k c_k^(1/4))^(1/3) = (6.016, 5.309, 4.494, 3.501, 2.153)
X_BEAM = C_BEAM**0.25 * np.sum(C_BEAM**0.25) ** (1.0 / 3.0)


def beam(x):
    return 0.0624 * np.sum(x), [np.sum(C_BEAM / x**3) - 1.0], np.full(5, 0.0624), -3 * C_BEAM / x**4


def test_separable_quadratic_with_active_constraint_and_active_bounds():
    p = Problem(np.zeros(5), np.ones(5), quadratic)
    r = run_mma(p, np.full(5, 0.4), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_QUAD, atol=1e-5)
    assert r.g[0] <= 1e-6
    assert p.infos[-1].extra["lam"][0] == pytest.approx(LAM_QUAD, abs=1e-4)
    assert r.iterations < 60


def test_svanberg_toy_problem():
    p = Problem(np.zeros(3), np.full(3, 5.0), toy)
    r = run_mma(p, np.array([4.0, 3.0, 2.0]), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_TOY, atol=1e-5)
    np.testing.assert_allclose(p.infos[-1].extra["lam"], LAM_TOY, atol=1e-4)
    assert np.all(r.g <= 1e-6)
    assert r.f == pytest.approx(X_TOY @ X_TOY, rel=1e-7)


def test_svanberg_toy_problem_default_tolerance():
    """The defaults stop on change_tol (1e-3 of the range 5): x* to a few 1e-3."""
    r = run_mma(Problem(np.zeros(3), np.full(3, 5.0), toy), np.array([4.0, 3.0, 2.0]))
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_TOY, atol=5e-3)
    assert np.all(r.g <= 1e-4)


def test_svanberg_cantilever_beam():
    p = Problem(np.ones(5), np.full(5, 10.0), beam)
    r = run_mma(p, np.full(5, 5.0), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_BEAM, rtol=1e-5)
    assert r.g[0] <= 1e-6
    assert r.f == pytest.approx(0.0624 * X_BEAM.sum(), rel=1e-6)


def test_inactive_constraint():
    """The bound-constrained minimum satisfies sum x <= 2.5 strictly: lam = 0.

    (The minimizer is on the bounds: at an interior point where every gradient
    vanishes, MMA's approximations are nearly flat and the iterates oscillate
    within about ASYMIN (upper - lower) of it; that is the method, not a bug.)
    """
    t = np.array([-0.5, 1.5, -0.2])

    def fun(x):
        return np.sum((x - t) ** 2), [np.sum(x) - 2.5], 2 * (x - t), np.ones((1, 3))

    p = Problem(np.zeros(3), np.ones(3), fun)
    r = run_mma(p, np.full(3, 0.9), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, [0.0, 1.0, 0.0], atol=1e-5)
    assert r.g[0] == pytest.approx(-1.5, abs=1e-5)
    assert abs(p.infos[-1].extra["lam"][0]) < 1e-5


def test_bounds_only_problem_with_active_bounds():
    """m = 0: the minimizer outside the box is clipped onto it."""
    t = np.array([-1.0, 2.0, 1.5, -0.3])

    def fun(x):
        return np.sum((x - t) ** 2), np.zeros(0), 2 * (x - t), np.zeros((0, 4))

    p = Problem(np.zeros(4), np.ones(4), fun)
    assert p.m == 0
    r = run_mma(p, np.full(4, 0.5), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, np.clip(t, 0, 1), atol=1e-5)
    assert r.g.shape == (0,)


def test_more_constraints_than_variables():
    """m >= n solves the (n+1) Newton system in subsolv instead of the (m+1) one."""

    def fun(x):
        g = [x[0] + x[1] - 2.0, x[0] - x[1] - 1.0, x[1] - x[0] - 1.0]
        dg = [[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0]]
        return np.sum((x - 2.0) ** 2), g, 2 * (x - 2.0), dg

    p = Problem(np.zeros(2), np.full(2, 3.0), fun)
    r = run_mma(p, np.array([0.5, 0.2]), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, [1.0, 1.0], atol=1e-5)
    np.testing.assert_allclose(p.infos[-1].extra["lam"], [2.0, 0.0, 0.0], atol=1e-4)


# --- the protocol -------------------------------------------------------------------


def test_iteration_zero_is_x0_and_one_evaluate_per_iteration():
    p = Problem(np.zeros(3), np.full(3, 5.0), toy)
    x0 = np.array([4.0, 3.0, 2.0])
    r = run_mma(p, x0, MMAOptions(max_iter=6, kkt_tol=0.0, change_tol=0.0))
    assert r.status == "max_iter" and r.iterations == 6
    assert len(p.calls) == r.evaluations == 7
    assert [i.iteration for i in p.infos] == list(range(7))
    first = p.infos[0]
    assert np.array_equal(first.x, x0) and math.isnan(first.optimality) and math.isnan(first.change)
    for call, info in zip(p.calls, p.infos):  # every evaluation is the reported iterate
        assert np.array_equal(call, info.x)
        assert info.f == call @ call
    for prev, info in zip(p.infos, p.infos[1:]):
        assert info.change == np.max(np.abs(info.x - prev.x))
        assert info.extra["change_scaled"] == pytest.approx(info.change / 5.0)
        assert np.all(info.x >= 0.0) and np.all(info.x <= 5.0)
        assert info.change <= 0.2 * 5.0 * (1 + 1e-12)  # move limit
    assert np.array_equal(r.x, p.infos[-1].x) and r.f == p.infos[-1].f


def test_deterministic_iterates():
    runs = []
    for _ in range(2):
        p = Problem(np.zeros(5), np.ones(5), quadratic)
        run_mma(p, np.full(5, 0.4), MMAOptions(max_iter=15, kkt_tol=0.0, change_tol=0.0))
        runs.append(p.infos)
    assert len(runs[0]) == len(runs[1]) == 16
    for a, b in zip(*runs):
        assert a.x.tobytes() == b.x.tobytes()
        assert a.optimality == b.optimality or (math.isnan(a.optimality) and math.isnan(b.optimality))


@pytest.mark.parametrize("stop_at", [0, 3])
def test_iteration_returning_false_stops_after_that_iteration(stop_at):
    p = Problem(np.zeros(3), np.full(3, 5.0), toy, stop_at=stop_at)
    r = run_mma(p, np.array([4.0, 3.0, 2.0]), MMAOptions(kkt_tol=0.0, change_tol=0.0))
    assert r.status == "stopped" and r.iterations == stop_at
    assert p.infos[-1].iteration == stop_at and len(p.calls) == stop_at + 1
    assert np.array_equal(r.x, p.infos[-1].x)


def test_converged_on_change_tol():
    p = Problem(np.ones(5), np.full(5, 10.0), beam)
    r = run_mma(p, np.full(5, 5.0), MMAOptions(kkt_tol=0.0, change_tol=1e-2))
    assert r.status == "converged" and "change" in r.message
    assert p.infos[-1].extra["change_scaled"] < 1e-2
    assert all(i.extra["change_scaled"] >= 1e-2 for i in p.infos[1:-1])


def test_evaluation_failure_returns_the_last_accepted_iterate():
    p = Problem(np.zeros(3), np.full(3, 5.0), toy, fail_at=4)
    r = run_mma(p, np.array([4.0, 3.0, 2.0]), MMAOptions(kkt_tol=0.0, change_tol=0.0, backtracks=0))
    assert r.status == "failed" and r.iterations == 3
    assert "Newton diverged" in r.message and "iteration 4" in r.message
    assert np.array_equal(r.x, p.infos[-1].x) and p.infos[-1].iteration == 3
    assert r.f == p.infos[-1].f and r.evaluations == 5


def test_evaluation_failure_at_the_initial_design():
    p = Problem(np.zeros(3), np.full(3, 5.0), toy, fail_at=0)
    r = run_mma(p, np.array([4.0, 3.0, 2.0]))
    assert r.status == "failed" and r.iterations == 0 and p.infos == []
    assert np.array_equal(r.x, [4.0, 3.0, 2.0]) and math.isnan(r.f)


def test_non_finite_values_count_as_a_failed_evaluation():
    def fun(x):
        return (np.nan if x[0] < 3.5 else x @ x), [x[0] - 5.0], 2 * x, np.array([[1.0, 0.0]])

    r = run_mma(Problem(np.zeros(2), np.full(2, 5.0), fun), np.array([4.0, 4.0]), MMAOptions(backtracks=0))
    assert r.status == "failed" and "non-finite" in r.message
    assert np.array_equal(r.x, [4.0, 4.0])


def test_other_exceptions_propagate():
    def fun(x):
        if len(p.calls) > 2:
            raise KeyError("a bug, not a failed analysis")
        return toy(x)

    p = Problem(np.zeros(3), np.full(3, 5.0), toy)
    p.fun = fun
    with pytest.raises(KeyError, match="a bug"):
        run_mma(p, np.array([4.0, 3.0, 2.0]))
    assert len(p.calls) == 3


def test_x0_outside_the_bounds_is_a_config_error():
    with pytest.raises(ConfigError, match=r"x0\[1\]"):
        run_mma(Problem(np.zeros(3), np.ones(3), lambda x: (0, [0], x, x)), np.array([0.5, 1.5, 0.5]))


# --- the pieces ---------------------------------------------------------------------


def test_asymptote_rules():
    lower, upper, opts = np.zeros(3), np.full(3, 2.0), MMAOptions(asyinit=0.4, asyincr=1.5, asydecr=0.6)
    x = np.array([1.0, 1.0, 1.0])
    low, upp = asymptotes(2, x, x, x, None, None, lower, upper, opts)
    np.testing.assert_allclose(low, x - 0.8)
    np.testing.assert_allclose(upp, x + 0.8)
    # x_{k-2} -> x_{k-1} -> x: variable 0 moves on (widen), 1 turns back (narrow), 2 stalls
    xold2, xold1 = np.array([0.8, 0.8, 1.0]), np.array([0.9, 1.2, 1.0])
    low_old, upp_old = np.array([0.5, 0.5, 0.5]), np.array([1.5, 1.5, 1.5])
    low, upp = asymptotes(3, x, xold1, xold2, low_old, upp_old, lower, upper, opts)
    np.testing.assert_allclose(low, [1.0 - 1.5 * 0.4, 1.0 - 0.6 * 0.7, 1.0 - 0.5])
    np.testing.assert_allclose(upp, [1.0 + 1.5 * 0.6, 1.0 + 0.6 * 0.3, 1.0 + 0.5])
    # clamped to [0.01, 10] (upper - lower) from x
    low, upp = asymptotes(3, x, x, x, np.full(3, 0.999), np.full(3, 100.0), lower, upper, opts)
    np.testing.assert_allclose(low, x - 0.02)
    np.testing.assert_allclose(upp, x + 20.0)


def test_subsolv_solves_the_subproblem():
    """The subproblem's KKT residual at its solution is at the level of the last barrier parameter."""
    x = np.array([4.0, 3.0, 2.0])
    lower, upper = np.zeros(3), np.full(3, 5.0)
    f, g, df, dg = toy(x)
    ev = DesignEvaluation(f, np.asarray(g), df, dg)
    w, sub, steps = mmasub(1, x, x, x, None, None, lower, upper, ev, MMAOptions(move=1.0))
    assert steps > 0
    assert np.max(np.abs(sub_residual(w, sub, EPSIMIN))) < 1e-6
    assert np.all(w.x > sub.alfa) and np.all(w.x < sub.beta)
    # the approximation matches the NLP at x: its gradient equals df
    ux, xl = sub.upp - x, x - sub.low
    np.testing.assert_allclose(sub.p0 / ux**2 - sub.q0 / xl**2, df, rtol=1e-12)
    np.testing.assert_allclose(sub.P @ (1 / ux) + sub.Q @ (1 / xl) - sub.b, g, rtol=1e-12)


def _flat(w):
    return np.concatenate([np.atleast_1d(getattr(w, f)) for f in PrimalDual.__dataclass_fields__])


def _unflat(v, n, m):
    sizes = {"x": n, "y": m, "z": 1, "lam": m, "xsi": n, "eta": n, "mu": m, "zet": 1, "s": m}
    parts, i = {}, 0
    for name, size in sizes.items():
        parts[name] = float(v[i]) if name in ("z", "zet") else v[i : i + size]
        i += size
    return PrimalDual(**parts)


@pytest.mark.parametrize(
    "fun, lower, upper, x",
    [
        (toy, np.zeros(3), np.full(3, 5.0), np.array([4.0, 3.0, 2.0])),  # m < n: (m+1) system
        (
            lambda x: (
                x @ x,
                [x[0] + x[1] - 2.0, x[0] - x[1] - 1.0, x[1] ** 2 - x[0] - 1.0],
                2 * x,
                [[1.0, 1.0], [1.0, -1.0], [-1.0, 2 * x[1]]],
            ),
            np.zeros(2),
            np.full(2, 3.0),
            np.array([0.5, 1.2]),
        ),  # m >= n: (n+1) system
    ],
)
def test_newton_direction_solves_the_linearized_kkt_system(fun, lower, upper, x, rng):
    """Against Newton with a finite-difference Jacobian of the full (3n + 4m + 2) residual."""
    f, g, df, dg = fun(x)
    ev = DesignEvaluation(float(f), np.asarray(g, float), np.asarray(df, float), np.asarray(dg, float))
    _, sub, _ = mmasub(1, x, x, x, None, None, lower, upper, ev, MMAOptions())
    m, n = sub.P.shape
    mid = 0.5 * (sub.alfa + sub.beta)
    w = PrimalDual(
        x=mid + 0.2 * (sub.beta - sub.alfa) * rng.uniform(-1, 1, n),
        y=rng.uniform(0.1, 1, m),
        z=0.3,
        lam=rng.uniform(0.1, 2, m),
        xsi=rng.uniform(0.1, 2, n),
        eta=rng.uniform(0.1, 2, n),
        mu=rng.uniform(1, 10, m),
        zet=0.6,
        s=rng.uniform(0.1, 2, m),
    )
    epsi = 1e-2
    v = _flat(w)
    jac = np.empty((v.size, v.size))
    for k in range(v.size):
        h = 1e-6 * max(1.0, abs(v[k]))
        e = np.zeros(v.size)
        e[k] = h
        plus, minus = sub_residual(_unflat(v + e, n, m), sub, epsi), sub_residual(_unflat(v - e, n, m), sub, epsi)
        jac[:, k] = (plus - minus) / (2 * h)
    expected = np.linalg.solve(jac, -sub_residual(w, sub, epsi))
    np.testing.assert_allclose(
        _flat(newton_direction(w, sub, epsi)), expected, rtol=1e-5, atol=1e-7 * np.max(np.abs(expected))
    )


def test_kkt_residual_vanishes_at_the_known_optimum():
    f, g, df, dg = toy(X_TOY)
    ev = DesignEvaluation(f, np.asarray(g), df, dg)
    c = np.full(2, 1000.0)
    w = PrimalDual(
        x=X_TOY, y=np.zeros(2), z=0.0, lam=LAM_TOY, xsi=np.zeros(3), eta=np.zeros(3), mu=c - LAM_TOY, zet=1.0, s=-ev.g
    )
    r = kkt_residual(w, np.zeros(3), np.full(3, 5.0), ev, c=c)
    assert r.shape == (3 * 3 + 4 * 2 + 2,)
    assert np.max(np.abs(r)) < 1e-8
    w_off = PrimalDual(**{**w.__dict__, "lam": LAM_TOY * 1.1})
    assert np.max(np.abs(kkt_residual(w_off, np.zeros(3), np.full(3, 5.0), ev, c=c))) > 1e-2


# --- options ------------------------------------------------------------------------


def test_option_message_names_key_and_range():
    with pytest.raises(ConfigError, match=r"^mma\.move must lie in \(0, 1\], got 1\.5$"):
        MMAOptions(move=1.5)


@pytest.mark.parametrize(
    "key, value",
    [
        ("max_iter", -1),
        ("max_iter", 2.5),
        ("max_iter", True),
        ("move", 0.0),
        ("kkt_tol", -1e-3),
        ("change_tol", "0.1"),
        ("asyinit", 0.0),
        ("asyinit", 1.5),
        ("asyincr", 0.9),
        ("asydecr", 1.2),
        ("asydecr", 0.0),
        ("c", 0.0),
        ("c", float("nan")),
        ("c", float("inf")),
    ],
)
def test_invalid_options_name_the_key(key, value):
    with pytest.raises(ConfigError, match=rf"^mma\.{key} "):
        MMAOptions(**{key: value})


def test_options_are_normalized_floats():
    o = MMAOptions(max_iter=np.int64(5), move=1, c=np.float32(100))
    assert o.max_iter == 5 and type(o.max_iter) is int
    assert type(o.move) is float and type(o.c) is float


def test_a_failed_analysis_is_retried_with_shorter_steps():
    """The analysis fails beyond 30 % of MMA's first step in x[0] (think: Newton cannot follow that
    design): the retries at 1/2 and 1/4 of the step, and the second one is accepted."""
    x0 = np.array([4.0, 3.0, 2.0])
    free = Problem(np.zeros(3), np.full(3, 5.0), toy)
    run_mma(free, x0, MMAOptions(max_iter=1, kkt_tol=0.0, change_tol=0.0))
    step = free.calls[1] - x0
    assert abs(step[0]) > 0.1
    fail = lambda x: (x[0] - x0[0]) / step[0] > 0.3  # noqa: E731
    p = Problem(np.zeros(3), np.full(3, 5.0), toy, fail=fail)
    r = run_mma(p, x0, MMAOptions(max_iter=1, kkt_tol=0.0, change_tol=0.0, backtracks=3))
    assert r.status == "max_iter" and r.iterations == 1 and not fail(r.x)
    assert len(p.failed) == 2 and len(p.calls) == 4
    np.testing.assert_allclose(p.failed[1], x0 + 0.5 * step, rtol=1e-14)
    np.testing.assert_allclose(r.x, x0 + 0.25 * step, rtol=1e-14)
    np.testing.assert_allclose(p.calls[-1], r.x, rtol=0)
    assert r.evaluations == len(p.calls)
    # every try fails: the last accepted iterate, status failed, all tries counted
    q = Problem(np.zeros(3), np.full(3, 5.0), toy, fail=lambda x: not np.array_equal(x, x0))
    r = run_mma(q, x0, MMAOptions(max_iter=1, kkt_tol=0.0, change_tol=0.0, backtracks=2))
    assert r.status == "failed" and np.array_equal(r.x, x0) and len(q.failed) == 3 and r.evaluations == 4


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_backtracks_is_validated(bad):
    with pytest.raises(ConfigError, match="mma.backtracks must be an integer >= 0"):
        MMAOptions(backtracks=bad)
