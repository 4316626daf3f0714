"""IPOPT adapter (contopt.optimize.ipopt): known optima, iterate reporting, stopping,
evaluation failures, exceptions in callbacks, silence, determinism and options."""

import math

import numpy as np
import pytest
from _nlp import X_QUAD, X_TOY, Problem, quadratic, toy  # tests/optimize/_nlp.py

from contopt import extras
from contopt.errors import ConfigError
from contopt.optimize import IpoptOptions, run_ipopt
from contopt.optimize.ipopt import Callbacks

pytestmark = pytest.mark.skipif(not extras.installed("ipopt"), reason=extras.missing("ipopt", "IPOPT needs"))

TIGHT = IpoptOptions(tol=1e-9, max_iter=200)


def shifted(x):
    """(x0 - 3)^2 + (x1 + 1)^2 s.t. x0 + x1 <= 1 on [-5, 5]^2: x* = (2.5, -1.5)."""
    t = np.array([3.0, -1.0])
    return np.sum((x - t) ** 2), [x[0] + x[1] - 1.0], 2 * (x - t), [[1.0, 1.0]]


def test_separable_quadratic_with_active_constraint_and_active_bounds():
    p = Problem(np.zeros(5), np.ones(5), quadratic)
    r = run_ipopt(p, np.full(5, 0.4), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_QUAD, atol=1e-6)
    assert r.g[0] <= 1e-7


def test_svanberg_toy_problem():
    p = Problem(np.zeros(3), np.full(3, 5.0), toy)
    r = run_ipopt(p, np.array([4.0, 3.0, 2.0]), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_TOY, atol=1e-6)
    assert np.all(r.g <= 1e-7)


def test_default_tolerance():
    r = run_ipopt(Problem(np.zeros(3), np.full(3, 5.0), toy), np.array([4.0, 3.0, 2.0]))
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_TOY, atol=1e-2)
    assert np.all(r.g <= 1e-4)  # IPOPT's constr_viol_tol


def test_inactive_constraint_interior_minimum():
    t = np.array([0.2, 0.6, 0.45])

    def fun(x):
        return np.sum((x - t) ** 2), [np.sum(x) - 2.5], 2 * (x - t), np.ones((1, 3))

    r = run_ipopt(Problem(np.zeros(3), np.ones(3), fun), np.full(3, 0.9), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, t, atol=1e-6)
    assert r.g[0] < -1.0


def test_bounds_only_problem():
    t = np.array([-1.0, 0.3, 2.0, 0.8])

    def fun(x):
        return np.sum((x - t) ** 2), np.zeros(0), 2 * (x - t), np.zeros((0, 4))

    p = Problem(np.zeros(4), np.ones(4), fun)
    assert p.m == 0
    r = run_ipopt(p, np.full(4, 0.5), TIGHT)
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, np.clip(t, 0, 1), atol=1e-6)
    assert r.g.shape == (0,)


def test_reported_iterates_are_ipopts_iterates():
    """IPOPT's own objective value equals f at each reported x; iteration 0 is x0 (inside the bounds)."""
    p = Problem(np.zeros(3), np.full(3, 5.0), toy)
    x0 = np.array([4.0, 3.0, 2.0])
    r = run_ipopt(p, x0, TIGHT)
    assert [i.iteration for i in p.infos] == list(range(r.iterations + 1))
    assert np.array_equal(p.infos[0].x, x0) and math.isnan(p.infos[0].change)
    for prev, info in zip([None, *p.infos], p.infos):
        assert info.extra["iterate_source"] in ("last_derivative", "get_current_iterate")
        assert info.extra["obj_value"] == pytest.approx(info.f, rel=1e-12)
        f, g, _, _ = toy(info.x)
        assert info.f == f and np.array_equal(info.g, g)
        assert info.optimality >= 0.0
        if prev is not None:
            assert info.change == np.max(np.abs(info.x - prev.x))
    assert np.array_equal(r.x, p.infos[-1].x) and r.f == p.infos[-1].f
    assert r.evaluations == len(p.calls)
    assert len({c.tobytes() for c in p.calls}) == len(p.calls)  # each point evaluated once


def test_restoration_phase_iterations_are_reported_once():
    """start_with_resto forces IPOPT's restoration phase, which reports its last point twice."""

    def fun(x):
        g = [1.0 - x @ x, x[0] + x[1] - 1.5]
        return (x[0] - 2) ** 2 + x[1] ** 2, g, [2 * (x[0] - 2), 2 * x[1]], [-2 * x, [1.0, 1.0]]

    p = Problem(np.full(2, -3.0), np.full(2, 3.0), fun)
    r = run_ipopt(p, np.array([0.1, 0.2]), IpoptOptions(tol=1e-8, options=(("start_with_resto", "yes"),)))
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, [1.75, -0.25], atol=1e-6)
    its = [i.iteration for i in p.infos]
    assert its == list(range(len(its)))
    assert any(i.extra["alg_mod"] == 1 for i in p.infos)
    for info in p.infos:
        assert info.extra["obj_value"] == pytest.approx(info.f, rel=1e-12)


def test_deterministic_iterates():
    runs = []
    for _ in range(2):
        p = Problem(np.zeros(3), np.full(3, 5.0), toy)
        run_ipopt(p, np.array([4.0, 3.0, 2.0]), TIGHT)
        runs.append(p)
    assert len(runs[0].infos) == len(runs[1].infos) > 3
    for a, b in zip(runs[0].infos, runs[1].infos):
        assert a.x.tobytes() == b.x.tobytes() and a.optimality == b.optimality
    assert [c.tobytes() for c in runs[0].calls] == [c.tobytes() for c in runs[1].calls]


@pytest.mark.parametrize("stop_at", [0, 2])
def test_iteration_returning_false_stops(stop_at):
    p = Problem(np.zeros(3), np.full(3, 5.0), toy, stop_at=stop_at)
    r = run_ipopt(p, np.array([4.0, 3.0, 2.0]), TIGHT)
    assert r.status == "stopped" and r.iterations == stop_at
    assert p.infos[-1].iteration == stop_at and len(p.infos) == stop_at + 1
    assert np.array_equal(r.x, p.infos[-1].x)


def test_max_iter():
    r = run_ipopt(
        Problem(np.zeros(3), np.full(3, 5.0), toy), np.array([4.0, 3.0, 2.0]), IpoptOptions(tol=1e-12, max_iter=3)
    )
    assert r.status == "max_iter" and r.iterations == 3


def test_backs_off_from_a_failing_region_and_converges():
    """The first full step overshoots to x0 > 2.7, where the analysis fails: IPOPT cuts the step back."""
    p = Problem([-5.0, -5.0], [5.0, 5.0], shifted, fail=lambda x: x[0] > 2.7)
    r = run_ipopt(p, np.zeros(2), IpoptOptions(tol=1e-8))
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, [2.5, -1.5], atol=1e-6)
    assert p.failed, "the test needs a step into the failing region"
    assert all(i.x[0] <= 2.7 for i in p.infos)
    assert any(i.extra["ls_trials"] > 1 for i in p.infos)


def test_failure_where_derivatives_are_needed_fails():
    p = Problem([-5.0, -5.0], [5.0, 5.0], shifted, fail=lambda x: True)
    r = run_ipopt(p, np.zeros(2))
    assert r.status == "failed" and r.iterations == 0 and p.infos == []
    assert "Newton diverged at x[0] = 0.000" in r.message
    assert np.array_equal(r.x, [0.0, 0.0]) and math.isnan(r.f)


@pytest.mark.parametrize("where", ["evaluate", "iteration"])
def test_other_exceptions_are_reraised(where):
    p = Problem([-5.0, -5.0], [5.0, 5.0], shifted)

    def boom(*args):
        raise KeyError(f"bug in {where}")

    if where == "evaluate":
        fun = p.fun
        p.fun = lambda x: boom() if len(p.calls) > 3 else fun(x)
    else:
        p.iteration = lambda info: boom() if info.iteration == 2 else True
    with pytest.raises(KeyError, match=f"bug in {where}"):
        run_ipopt(p, np.zeros(2))
    assert len(p.calls) <= 6  # stopped at once, no evaluations after the exception


def test_silent_by_default(capfd):
    run_ipopt(Problem([-5.0, -5.0], [5.0, 5.0], shifted), np.zeros(2))
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_x0_outside_the_bounds_is_a_config_error():
    with pytest.raises(ConfigError, match=r"x0\[0\]"):
        run_ipopt(Problem([-5.0, -5.0], [5.0, 5.0], shifted), np.array([6.0, 0.0]))


def test_iterate_detection_prefers_a_working_get_current_iterate():
    p = Problem([-5.0, -5.0], [5.0, 5.0], shifted)

    class Working:
        def get_current_iterate(self, scaled=False):
            return {"x": np.array([1.0, 2.0])}

    class Old:
        def get_current_iterate(self, scaled=False):
            raise RuntimeError("get_current_iterate only supports Ipopt version >=3.14.0")

    cb = Callbacks(p, 2, 1, lambda callbacks: Working())
    x, ev, source = cb.current_iterate()
    assert source == "get_current_iterate" and np.array_equal(x, [1.0, 2.0]) and ev.f == shifted(x)[0]
    cb = Callbacks(p, 2, 1, lambda callbacks: Old())
    cb.gradient(np.array([0.5, 0.5]))
    x, ev, source = cb.current_iterate()
    assert source == "last_derivative" and np.array_equal(x, [0.5, 0.5])


# --- options ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "key, value",
    [
        ("tol", 0.0),
        ("tol", -1.0),
        ("tol", "1e-3"),
        ("max_iter", -1),
        ("max_iter", 1.5),
        ("max_iter", True),
        ("hessian", "exact"),
        ("limited_memory_max_history", -2),
        ("print_level", 13),
        ("mu_strategy", "probing"),
        ("options", "tol 1e-3"),
        ("options", (("tol", 1e-6),)),
        ("options", (("acceptable_tol",),)),
        ("options", (("acceptable_tol", None),)),
        ("max_iter", 10**12),
        ("options", (("acceptable_iter", 2**31),)),
    ],
)
def test_invalid_options_name_the_key(key, value):
    with pytest.raises(ConfigError, match=rf"ipopt\.{key}"):
        IpoptOptions(**{key: value})


def test_raw_options_are_passed_and_unknown_ones_refused():
    o = IpoptOptions(options=[("acceptable_tol", np.float64(1e-2)), ("acceptable_iter", np.int64(5))])
    assert o.options == (("acceptable_tol", 1e-2), ("acceptable_iter", 5))
    r = run_ipopt(Problem([-5.0, -5.0], [5.0, 5.0], shifted), np.zeros(2), o)
    assert r.status == "converged"
    with pytest.raises(ConfigError, match="no_such_option"):
        run_ipopt(
            Problem([-5.0, -5.0], [5.0, 5.0], shifted), np.zeros(2), IpoptOptions(options=(("no_such_option", 1),))
        )


def test_adaptive_mu_strategy_converges():
    p = Problem(np.zeros(5), np.ones(5), quadratic)
    r = run_ipopt(p, np.full(5, 0.4), IpoptOptions(tol=1e-9, mu_strategy="adaptive", max_iter=200))
    assert r.status == "converged"
    np.testing.assert_allclose(r.x, X_QUAD, atol=1e-6)
