"""Newton, load stepping, cutback and the errors a user meets."""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.cases.forward import block_compression
from contopt.errors import ConfigError, ConvergenceError
from contopt.material import MooneyRivlin, neo_hookean
from contopt.mesh.generators import box
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static


def test_newton_converges_quadratically():
    # exact solves: with a kept factor (factor_reuse) the steps are accurate to krylov_rtol only,
    # and the orders measured down to 1e-13 would no longer be the tangent's alone
    exact = LinearSolverOptions(factor_reuse=False)
    state = solve_static(
        block_compression(divisions=4, strain=0.4), newton=NewtonOptions(n_steps=2, rtol=1e-12), linear=exact
    )
    assert len(state.logs) == 2 and all(lg.converged for lg in state.logs)
    for lg in state.logs:
        rel = np.array(lg.residuals[1:]) / lg.r_ref
        # orders measured while the residual is well above round-off
        orders = [np.log(b) / np.log(a) for a, b in zip(rel[:-1], rel[1:]) if 1e-13 < b and a < 1e-1]
        assert orders, lg.summary()
        assert min(orders) > 1.7, (orders, lg.summary())
        assert lg.iterations <= 6


def test_cutback_recovers_and_regrows_to_the_same_equilibrium():
    model = block_compression(divisions=3, strain=0.5)
    ref = solve_static(model, newton=NewtonOptions(n_steps=8))
    # three iterations cannot take the whole 50 % compression at once: the step is cut back
    state = solve_static(model, newton=NewtonOptions(n_steps=1, max_iter=3, grow=2.0, easy_iterations=3))
    failed = [lg for lg in state.logs if not lg.converged]
    converged = [lg for lg in state.logs if lg.converged]
    assert failed and failed[0].dt == 1.0
    # after an easy converged step the next attempt is longer (regrowth)
    logs = state.logs
    assert any(a.converged and b.dt > a.dt for a, b in zip(logs[:-1], logs[1:])), [lg.dt for lg in logs]
    assert converged[-1].t == 1.0
    np.testing.assert_allclose(state.u, ref.u, atol=1e-9 * np.abs(ref.u).max())


def test_impossible_load_raises_convergence_error_with_last_state():
    # pushing the top of a unit cube down by 1.2 would turn every cell inside out
    model = block_compression(divisions=2, strain=1.2)
    with pytest.raises(ConvergenceError) as info:
        solve_static(model, newton=NewtonOptions(n_steps=4, min_step=0.02, max_iter=10))
    err = info.value
    assert "minimum load step" in str(err)
    assert err.last_state is not None and 0.3 < err.last_state.t < 1.0
    assert np.all(np.isfinite(err.last_state.u))
    assert any(not lg.converged for lg in err.logs) and any(lg.converged for lg in err.logs)


def test_unsupported_body_is_reported_as_singular():
    mesh = box((1, 1, 1), (2, 2, 2))
    model = Model(
        bodies=(Body("free", mesh, neo_hookean(1.0, 0.3)),), loads=(Traction("free", "zmax", (0.0, 0.0, 1e-3)),)
    )
    with pytest.raises(ConvergenceError, match="singular.*(support|Dirichlet)"):
        solve_static(model)


def test_nearly_incompressible_bending_converges_in_few_iterations():
    # the full Newton step raises |r| here (volumetric second-order terms) but lowers the
    # energy: an energy line search takes it, a residual-norm one would crawl
    mesh = box((4.0, 1.0, 1.0), (8, 2, 2))
    model = Model(
        bodies=(Body("b", mesh, neo_hookean(1.0, 0.499)),),
        dirichlet=(Dirichlet("b", "xmin"),),
        loads=(Traction("b", "xmax", (0.0, 0.0, -1e-4)),),
    )
    state = solve_static(model)
    assert state.logs[-1].converged and state.newton_iterations <= 6


def _tip_deflection(n, fbar, nu=0.499):
    mesh = box((4.0, 1.0, 1.0), (4 * n, n, n))
    model = Model(
        bodies=(Body("b", mesh, neo_hookean(1.0, nu), fbar=fbar),),
        dirichlet=(Dirichlet("b", "xmin"),),
        loads=(Traction("b", "xmax", (0.0, 0.0, -1e-4)),),
    )
    u = solve_static(model).u.reshape(-1, 3)
    return -u[mesh.node_set("xmax"), 2].mean()


def test_fbar_removes_volumetric_locking():
    coarse_plain = _tip_deflection(2, fbar=False)
    coarse_fbar = _tip_deflection(2, fbar=True)
    reference = _tip_deflection(4, fbar=True)  # refined mesh (converged to ~1 % here)
    assert coarse_plain < 0.5 * coarse_fbar  # plain hex8 locks: far too stiff
    assert abs(coarse_fbar - reference) < 0.05 * reference
    # and a compressible material barely notices the difference
    assert abs(_tip_deflection(2, False, nu=0.3) - _tip_deflection(2, True, nu=0.3)) < 0.15 * _tip_deflection(
        2, True, nu=0.3
    )


def test_options_are_validated():
    with pytest.raises(ConfigError, match="line_search"):
        NewtonOptions(line_search="wolfe")
    with pytest.raises(ConfigError, match="n_steps"):
        NewtonOptions(n_steps=0)
    with pytest.raises(ConfigError, match="cutback"):
        NewtonOptions(cutback=1.5)
    with pytest.raises(ConfigError, match="nu"):
        MooneyRivlin.from_E_nu(1.0, 0.5)


def _scalar_problem(refuse_above):
    """r(u) = u - 1 (energy (u - 1)^2 / 2) with trial points beyond ``refuse_above`` refused."""
    from types import SimpleNamespace

    import scipy.sparse as sp

    from contopt.assembly.system import Timings

    def evaluate(u, tangent):
        r = u - 1.0
        K = sp.csr_matrix(np.eye(1))
        return SimpleNamespace(
            r=r,
            energy=0.5 * float(r @ r),
            K_dot=lambda v: K @ v,
            K_free=K,
            timings=Timings(),
            modified=None,
            contact=None,
            reduce=lambda v: v,
        )

    def admissible(u):
        return f"u = {u[0]:.3g} is beyond {refuse_above}" if u[0] > refuse_above else ""

    return evaluate, admissible


def test_line_search_shortens_an_inadmissible_step():
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.newton import StepFailure, newton_step

    evaluate, admissible = _scalar_problem(refuse_above=0.3)
    args = (
        np.zeros(1),
        np.arange(1),
        np.zeros(0, np.int64),
        np.zeros(0),
        1.0,
        1.0,
        1.0,
        NewtonOptions(),
        LinearSolverOptions(),
    )
    # the full Newton step (to u = 1) is refused: the first iterate is the longest admissible one, 1/4
    with pytest.raises(StepFailure) as info:
        newton_step(evaluate, *args, admissible=admissible)
    log = info.value.log
    assert log.alphas[0] == 0.25 and "no admissible step" in log.message
    assert "beyond 0.3" in str(info.value)
    # without the refusal the same step converges at once
    u, log, _ = newton_step(evaluate, *args)
    assert log.converged and log.alphas[0] == 1.0 and u[0] == pytest.approx(1.0, abs=1e-15)


def test_a_converged_step_does_not_hold_its_tangent_through_the_next():
    """Only the last step keeps its tangent (the adjoint factors it): before, every step's was alive
    through the next step's solve, 65 MB of the fine die-slab's peak memory."""
    import gc
    import weakref

    import scipy.sparse as sp

    from contopt.assembly.system import Evaluation
    from contopt.solve.newton import NewtonLog, NewtonOptions
    from contopt.solve.stepping import StepResult, solve_load_steps

    refs, alive = [], []

    def step(u, t, dt, state):
        gc.collect()
        alive.append([ref() is not None for ref in refs])
        K = sp.identity(3, format="csr")
        refs.append(weakref.ref(K))
        ev = Evaluation(r=np.zeros(3), K_terms=(K,), K_free=K)
        lg = NewtonLog(t=t, dt=dt, converged=True, iterations=1, residuals=(0.0,), increments=(), alphas=(),
                       r_ref=1.0, seconds={})  # fmt: skip
        return StepResult(t=t, u=u, logs=(lg,), evaluation=ev)

    _, last = solve_load_steps(step, 3, np.zeros(0, np.int64), lambda t: np.zeros(0), NewtonOptions(n_steps=3))
    assert alive == [[], [False], [False, False]]
    assert last.evaluation.K_free is not None and last.evaluation.K is not None
    assert np.array_equal(last.evaluation.K_dot(np.ones(3)), np.ones(3))


def _too_stiff(factor: float):
    """``evaluate(u, tangent)`` of r(u) = u - 1 (one dof) with a tangent ``factor`` times too stiff: each
    full Newton step leaves ``1 - 1/factor`` of the residual."""
    from types import SimpleNamespace

    import scipy.sparse as sp

    from contopt.assembly.system import Timings

    def evaluate(u, tangent):
        K = sp.csr_matrix(factor * np.eye(1))
        r = u - 1.0
        return SimpleNamespace(
            r=r, energy=0.5 * float(r @ r), K_dot=lambda v: K @ v, K_free=K, timings=Timings(),
            modified=None, contact=None, reduce=lambda v: v,
        )  # fmt: skip

    return evaluate


def test_a_stagnating_solve_fails_unless_stall_rtol_accepts_it(caplog):
    """r(u) = u - 1 with a tangent 20 times too stiff: |r| shrinks by 0.95 an iteration, so Newton
    stagnates (less than a halving over six iterations) at |r| = 0.95^10 = 0.60 after 10."""
    from contopt.solve.newton import StepFailure, newton_step

    evaluate = _too_stiff(20.0)

    def run(**options):
        args = (np.arange(1), np.zeros(0, np.int64), np.zeros(0), 1.0, 1.0, 1.0)
        return newton_step(evaluate, np.zeros(1), *args, NewtonOptions(**options), LinearSolverOptions())

    with pytest.raises(StepFailure, match="stagnated"):
        run()
    with pytest.raises(StepFailure, match="stagnated"):
        run(stall_rtol=0.5)  # 0.60 is above it
    u, log, _ = run(stall_rtol=0.7)
    assert log.converged and log.message == "accepted at stagnation" and log.iterations == 10
    assert u[0] == pytest.approx(1.0 - 0.95**10, rel=1e-12)
    assert "accepted" in caplog.text
    for bad in (1e-12, 1.0, True):  # below rtol, not below 1, not a number
        with pytest.raises(ConfigError, match="stall_rtol"):
            NewtonOptions(stall_rtol=bad)


def _piecewise_problem(energy, tangent_at):
    """A scalar problem with energy ``energy(u)``, its exact residual, and the tangent
    ``tangent_at(u)`` (exact or not), as :func:`newton_step` evaluates one."""
    from types import SimpleNamespace

    import scipy.sparse as sp

    from contopt.assembly.system import Timings

    def evaluate(u, tangent):
        h = 1e-6  # the residual: a central difference of the energy is exact for these quadratics
        r = np.array([(energy(u[0] + h) - energy(u[0] - h)) / (2 * h)])
        K = sp.csr_matrix(np.array([[tangent_at(u[0])]]))
        return SimpleNamespace(
            r=r, energy=energy(u[0]), K_dot=lambda v: K @ v, K_free=K, timings=Timings(),
            modified=None, contact=None, reduce=lambda v: v,
        )  # fmt: skip

    return evaluate


def _run_scalar(evaluate, **options):
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.newton import newton_step

    args = (np.arange(1), np.zeros(0, np.int64), np.zeros(0), 1.0, 1.0, 1.0)
    return newton_step(evaluate, np.zeros(1), *args, NewtonOptions(**options), LinearSolverOptions(factor_reuse=False))


def test_a_solve_out_of_iterations_close_to_its_tolerance_says_it_stalled():
    """r(u) = u - 1 with a tangent 4 times too stiff: |r| = 0.75^k after k iterations; five iterations
    end at 0.237, within sqrt(rtol) = 0.32 of the reference 1 for rtol 0.1 (a near-tolerance stall
    that the load stepping does not cut back twice), far from it for the default rtol."""
    from contopt.solve.newton import StepFailure, newton_step

    evaluate = _too_stiff(4.0)

    def failure(**options):
        args = (np.arange(1), np.zeros(0, np.int64), np.zeros(0), 1.0, 1.0, 1.0)
        with pytest.raises(StepFailure, match="no convergence in 5 iterations") as err:
            newton_step(evaluate, np.zeros(1), *args, NewtonOptions(max_iter=5, **options), LinearSolverOptions())
        return err.value

    assert failure(rtol=0.1).stalled == pytest.approx(0.75**5, rel=1e-12)
    assert failure().stalled is None


def test_steps_that_stall_close_to_the_tolerance_whatever_their_size_stop_with_stall_rtol_advice():
    """A step function that stalls at |r| = 4e-7 r_ref (rtol 1e-9, so within sqrt(rtol)) on every
    step of more than 0.3: one such stall is cut back (the smaller step converges), two in a row stop
    at once with the acceptance that would take them (1e-6), not after halving down to min_step; a
    stall far from the tolerance (0.6 r_ref) keeps cutting back to min_step."""
    from contopt.solve.newton import NewtonLog, StepFailure
    from contopt.solve.stepping import StepResult, solve_load_steps

    tried = []

    def stepping(ratio, converge_below):
        def step(u, t, dt, state):
            tried.append(dt)
            lg = NewtonLog(t=t, dt=dt, converged=dt < converge_below, iterations=10, residuals=(1.0, ratio),
                           increments=(), alphas=(), r_ref=1.0, seconds={})  # fmt: skip
            if dt >= converge_below:
                near = ratio if ratio <= np.sqrt(1e-9) else None
                raise StepFailure("Newton stagnated", lg, stalled=near)
            return StepResult(t=t, u=u, logs=(lg,), evaluation=None)

        return step

    def run(ratio, converge_below):
        tried.clear()
        options = NewtonOptions(n_steps=2, min_step=1e-3, grow=1.0)
        return solve_load_steps(stepping(ratio, converge_below), 1, np.zeros(0, np.int64), lambda t: np.zeros(0),
                                options)  # fmt: skip

    logs, last = run(4e-7, 0.3)  # 0.5 stalls, 0.25 converges, every time
    assert last.t == 1.0 and tried == [0.5, 0.25, 0.25, 0.25, 0.25]
    with pytest.raises(ConvergenceError) as err:
        run(4e-7, 0.2)  # 0.5 and 0.25 stall in a row
    assert tried == [0.5, 0.25] and err.value.last_state.t == 0.0
    message = str(err.value)
    assert "stall_rtol = 1e-06" in message and "smaller load step does not help" in message
    assert "\n" not in message
    with pytest.raises(ConvergenceError, match="minimum load step"):
        run(0.6, 1e-9)  # far from the tolerance: the cutbacks go on
    assert min(tried) < 2e-3


def test_a_stall_again_at_the_step_size_that_got_past_an_earlier_one_stops_the_solve():
    """Steps stall close to the tolerance (4e-7 r_ref) beyond t = 0.3 whatever their size: 0.5 stalls, 0.25
    converges to 0.25, and the next 0.25 (the cutback that got past the first stall) stalls too: the solve
    stops there, not after another cutback (before: 0.125 tried). Where only the step's size stalls (0.5,
    regrown after each easy step), the stalls are cut back every time and the solve converges."""
    from contopt.solve.newton import NewtonLog, StepFailure
    from contopt.solve.stepping import StepResult, solve_load_steps

    tried = []

    def stepping(stalls):
        def step(u, t, dt, state):
            tried.append(dt)
            lg = NewtonLog(t=t, dt=dt, converged=not stalls(t, dt), iterations=3, residuals=(1.0, 4e-7),
                           increments=(), alphas=(), r_ref=1.0, seconds={})  # fmt: skip
            if stalls(t, dt):
                raise StepFailure("Newton stagnated", lg, stalled=4e-7)
            return StepResult(t=t, u=u, logs=(lg,), evaluation=None)

        return step

    def run(stalls, **options):
        tried.clear()
        options = NewtonOptions(n_steps=2, min_step=1e-3, **options)
        return solve_load_steps(stepping(stalls), 1, np.zeros(0, np.int64), lambda t: np.zeros(0), options)

    with pytest.raises(ConvergenceError, match="smaller load step does not help") as err:
        run(lambda t, dt: t > 0.3 + 1e-12, grow=1.0)
    assert tried == [0.5, 0.25, 0.25] and err.value.last_state.t == 0.25
    assert "in load steps of 0.5 and 0.25 from t=0 and t=0.25 alike" in str(err.value)
    logs, last = run(lambda t, dt: dt > 0.3, grow=2.0, easy_iterations=3)
    assert last.t == 1.0 and tried == [0.5, 0.25, 0.5, 0.25, 0.5, 0.25, 0.25]


def test_a_contact_check_that_fails_as_deep_after_a_cutback_stops_with_the_sides_advice():
    """A node left unheld 0.08 h deep whatever the step: a smaller step does not help, the error
    says so and names the sides, not more load steps; a penetration that halves with the step (a step
    too large) keeps cutting back."""
    from contopt.contact.verify import LOST
    from contopt.solve.newton import NewtonLog, StepFailure
    from contopt.solve.stepping import solve_load_steps

    tried = []

    def step(depth_per_dt):
        def failing(u, t, dt, state):
            tried.append(dt)
            lg = NewtonLog(t=t, dt=dt, converged=True, iterations=3, residuals=(1.0,), increments=(), alphas=(),
                           r_ref=1.0, seconds={})  # fmt: skip
            depth = depth_per_dt(dt)
            message = f"contact interface a -> b: node 1 lies {depth:.2g} h inside body 'b' (1 node(s) fail): {LOST}"
            raise StepFailure(message, lg, cause="check", depth=depth, advice="use more or smaller load steps")

        return failing

    def run(depth_per_dt):
        tried.clear()
        options = NewtonOptions(n_steps=2, min_step=1e-3)
        return solve_load_steps(step(depth_per_dt), 1, np.zeros(0, np.int64), lambda t: np.zeros(0), options)

    with pytest.raises(ConvergenceError) as err:
        run(lambda dt: 0.08)
    message = str(err.value)
    assert tried == [0.5, 0.25] and "smaller load step does not help" in message
    assert "nonmortar" in message and LOST not in message and "minimum load step" not in message
    with pytest.raises(ConvergenceError, match="minimum load step"):
        run(lambda dt: 0.4 * dt)  # halves with the step: a step too large
    assert min(tried) < 2e-3


def test_a_contact_check_that_rejects_a_load_factor_again_from_closer_stops_at_once():
    """The seam with the blocks' tops nonmortar (issue 35): a block corner sinks 0.08 h into the roller
    once the roller passes t = 0.62, whatever the step. The step to t = 0.667 fails the check, its
    cutback to 0.583 converges, and the step to 0.667 from there fails alike: the check rejects the state
    at that load factor, not the step, so the solve ends there (it went on creeping towards 0.62 by
    halvings until two steps in a row failed). A penetration that halves with the step (a step too large)
    keeps cutting back."""
    from contopt.contact.verify import LOST
    from contopt.solve.newton import NewtonLog, StepFailure
    from contopt.solve.stepping import StepResult, solve_load_steps

    tried = []

    def step(depth_per_dt):
        def solve(u, t, dt, state):
            tried.append(round(t, 6))
            lg = NewtonLog(t=t, dt=dt, converged=True, iterations=3, residuals=(1.0,), increments=(), alphas=(),
                           r_ref=1.0, seconds={})  # fmt: skip
            if t <= 0.62:
                return StepResult(t=t, u=u, logs=(lg,), evaluation=None)
            depth = depth_per_dt(dt)
            message = f"contact interface a -> b: node 1 lies {depth:.2g} h inside body 'b' (1 node(s) fail): {LOST}"
            raise StepFailure(message, lg, cause="check", depth=depth, advice="use more or smaller load steps")

        return solve

    def run(depth_per_dt, grow=1.0):
        tried.clear()
        options = NewtonOptions(n_steps=6, min_step=1e-3, grow=grow)
        return solve_load_steps(step(depth_per_dt), 1, np.zeros(0, np.int64), lambda t: np.zeros(0), options)

    with pytest.raises(ConvergenceError) as err:
        run(lambda dt: 0.08)
    message = str(err.value)
    assert tried == [0.166667, 0.333333, 0.5, 0.666667, 0.583333, 0.666667]
    assert err.value.last_state.t == pytest.approx(7 / 12)
    assert "in load steps of 0.167 and 0.0833 from t=0.5 and t=0.5833 alike" in message
    assert "smaller load step does not help" in message and "nonmortar" in message and LOST not in message
    # the steps grow after easy ones: the second failure ends past the first's t, from closer, as deep
    with pytest.raises(ConvergenceError, match="smaller load step does not help"):
        run(lambda dt: 0.08, grow=1.5)
    assert tried == [0.166667, 0.333333, 0.5, 0.666667, 0.583333, 0.708333]
    with pytest.raises(ConvergenceError, match="minimum load step"):
        run(lambda dt: 0.4 * dt)  # halves with the step: a step too large
    assert len(tried) > 8


def test_the_watchdog_takes_the_full_step_into_a_closing_contact():
    """A spring (k = 1, force f = 2) pushed onto a stiff wall (eps = 1e4) at u = g = 0.5: the tangent
    at u < g misses the wall, so the full step (to u = 2) overshoots deep into it and backtracking keeps
    only 1/8 of it again and again. Taken anyway, it lands where the tangent has the wall, and the next
    step reaches the exact equilibrium u* = (f + eps g) / (k + eps) of this piecewise quadratic energy."""
    k, f, eps, g = 1.0, 2.0, 1e4, 0.5

    def energy(u):
        return 0.5 * k * u**2 - f * u + 0.5 * eps * max(0.0, u - g) ** 2

    evaluate = _piecewise_problem(energy, lambda u: k + (eps if u > g else 0.0))
    exact = (f + eps * g) / (k + eps)
    u, log, _ = _run_scalar(evaluate)
    assert log.converged and u[0] == pytest.approx(exact, rel=1e-12)
    assert log.alphas[:2] == (1.0, 1.0) and log.iterations <= 3
    # the overshot point's residual is no scale of the step: the tolerance stays the load's
    assert log.r_ref == pytest.approx(f, rel=1e-6)
    u, plain, _ = _run_scalar(evaluate, watchdog=0)
    assert plain.converged and u[0] == pytest.approx(exact, rel=1e-9)
    assert plain.alphas[0] < 1.0


def test_the_line_search_lands_at_the_energy_minimum_where_a_contact_closes():
    """The spring of the watchdog's test without the watchdog: the full step (to u = 2) and half of it
    raise the energy, a quarter (to the wall, u = g) lowers it and the slope there still falls. The
    halving alone would stop at u = g, and the next tangent, still without the wall, would send
    Newton through it again; the secant on the slope lands at the minimum along the step, which for
    this piecewise quadratic energy is the equilibrium itself."""
    k, f, eps, g = 1.0, 2.0, 1e4, 0.5

    def energy(u):
        return 0.5 * k * u**2 - f * u + 0.5 * eps * max(0.0, u - g) ** 2

    evaluate = _piecewise_problem(energy, lambda u: k + (eps if u > g else 0.0))
    exact = (f + eps * g) / (k + eps)
    u, log, _ = _run_scalar(evaluate, watchdog=0)
    assert log.converged and u[0] == pytest.approx(exact, rel=1e-9)
    assert log.alphas[0] == pytest.approx(exact / 2, rel=1e-6) and log.iterations == 1


def test_the_watchdog_goes_back_when_the_full_step_does_not_pay():
    """Energy (u - 1)^2 / 2; the tangent is 10 times too soft at u = 0 (the full step goes to u = 10,
    energy 40.5 against 0.5) and 1000 times too stiff beyond u = 3, where the steps after it crawl:
    the two iterations the watchdog gives do not get below 0.5, so Newton goes back to u = 0 and
    backtracks along the first step, as without the watchdog (to u = 1.25, then to 1)."""

    def energy(u):
        return 0.5 * (u - 1.0) ** 2

    evaluate = _piecewise_problem(energy, lambda u: 0.1 if u == 0.0 else (1000.0 if u > 3.0 else 1.0))
    u, log, _ = _run_scalar(evaluate)
    assert log.converged and u[0] == pytest.approx(1.0, abs=1e-9)
    # iteration 1 the full step, 2 a crawl from u = 10, 3 back to u = 0 and 1/8 of the first step
    assert log.alphas[0] == 1.0 and log.alphas[2] == pytest.approx(0.125)
    assert log.residuals[3] == pytest.approx(0.25, rel=1e-6)
    _, plain, _ = _run_scalar(evaluate, watchdog=0)
    assert plain.alphas[0] == pytest.approx(0.125) and plain.residuals[1] == pytest.approx(0.25, rel=1e-6)


def test_after_going_back_the_load_step_is_monotone(caplog):
    """The tangent is 10 times too soft everywhere below u = 3 (1000 times too stiff above): every
    full step overshoots, as a warm start's can from a state far from the new design's. The watchdog
    takes the first one and goes back; the rest of the load step backtracks, or it would go out and
    back again until Newton stagnated."""

    def energy(u):
        return 0.5 * (u - 1.0) ** 2

    evaluate = _piecewise_problem(energy, lambda u: 1000.0 if u > 3.0 else 0.1)
    with caplog.at_level("DEBUG", logger="contopt.solve.linesearch"):
        u, log, _ = _run_scalar(evaluate, max_iter=40)
    assert log.converged and u[0] == pytest.approx(1.0, abs=1e-9)
    messages = [r.getMessage() for r in caplog.records]
    assert sum("although the energy rose" in m for m in messages) == 1
    assert sum("back to where" in m for m in messages) == 1
    _, plain, _ = _run_scalar(evaluate, watchdog=0, max_iter=40)
    assert plain.converged and log.iterations <= plain.iterations + 2  # the excursion's cost


def test_watchdog_option_is_validated():
    for bad in (-1, 1.5, True):
        with pytest.raises(ConfigError, match="newton.watchdog must be a non-negative integer"):
            NewtonOptions(watchdog=bad)
    assert NewtonOptions(watchdog=0).watchdog == 0


def _noisy_problem(k, noise):
    """r(u) = k u - 1 + noise sin(1e12 u): a spring of stiffness k under a unit load whose residual
    carries round-off of size ``noise`` (as a penalty grown 1e3 times adds it to a stiff punch's
    contact forces); the full Newton step at the floor is noise / k, noise times u* = 1/k."""
    from types import SimpleNamespace

    import scipy.sparse as sp

    from contopt.assembly.system import Timings

    def evaluate(u, tangent):
        r = k * u - 1.0 + noise * np.sin(1e12 * u)
        K = sp.csr_matrix(np.array([[k]]))
        return SimpleNamespace(
            r=r, energy=0.5 * k * float(u[0] ** 2) - float(u[0]), K_dot=lambda v: K @ v, K_free=K, timings=Timings(),
            modified=None, contact=None, reduce=lambda v: v,
        )  # fmt: skip

    return evaluate


def test_a_residual_at_the_round_off_floor_of_its_tangent_is_converged():
    """The target (rtol 1e-14 of the unit load) lies far below the residual's noise (1e-9): Newton's full
    steps shrink to 1e-9 of u (below SQRT_EPS = 1.5e-8) without lowering |r|. That is the floor, measured
    by the solve itself; before, less than a halving over six iterations cut the load step back."""
    u, log, _ = _run_scalar(_noisy_problem(1e3, 1e-9), rtol=1e-14)
    assert log.converged and log.message == "round-off floor"
    assert u[0] == pytest.approx(1e-3, rel=1e-8) and log.iterations <= 6
    assert log.residuals[-1] > 1e-14  # above the target: accepted as round-off, not as met


def test_a_stall_above_the_round_off_floor_still_fails():
    from contopt.solve.newton import StepFailure

    # a tangent 1e9 times too stiff: full steps of 1e-9 of u that do not lower |r| = the whole load
    # are a wrong model, not round-off (the residual is above sqrt(rtol) of the load)
    with pytest.raises(StepFailure, match="stagnated"):
        _run_scalar(_piecewise_problem(lambda u: 0.5 * 1e3 * u**2 - u, lambda u: 1e12), rtol=1e-14)


def _noisy_pair(noise, max_iter=25):
    """Two unit springs under unit loads whose residual carries noise of size ``noise`` in both
    components, r(u) = u - 1 + noise (sin(1e12 (u0 + 1.3 u1)), cos(1e12 (0.7 u0 - 1.1 u1))): along a Newton
    step |r| has no root (a scalar noisy residual crosses zero, and the line search finds such a point
    by chance); the full Newton step at the floor is the noise, ``noise`` of |u|."""
    from types import SimpleNamespace

    import scipy.sparse as sp

    from contopt.assembly.system import Timings

    K = sp.identity(2, format="csr")

    def evaluate(u, tangent):
        a, b = 1e12 * (u[0] + 1.3 * u[1]), 1e12 * (0.7 * u[0] - 1.1 * u[1])
        r = u - 1.0 + noise * np.array([np.sin(a), np.cos(b)])
        return SimpleNamespace(
            r=r, energy=0.5 * float(u @ u) - float(u.sum()), K_dot=lambda v: K @ v, K_free=K, timings=Timings(),
            modified=None, contact=None, reduce=lambda v: v,
        )  # fmt: skip

    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.newton import newton_step

    args = (np.arange(2), np.zeros(0, np.int64), np.zeros(0), 1.0, 1.0, 1.0)
    options = NewtonOptions(max_iter=max_iter)
    return newton_step(evaluate, np.zeros(2), *args, options, LinearSolverOptions(factor_reuse=False))


def test_a_stall_whose_full_newton_step_is_below_utol_is_converged():
    """The residual's noise (1e-7) lies far above the target (rtol 1e-9 of the load) and the round-off
    estimate (3e-14), and inside sqrt(rtol) of the load. Newton's full steps are the noise over the
    stiffness, 1e-7 of |u|: the state is known to utol (1e-6), and the stagnation is accepted on that;
    the solution is within it of u* = (1, 1). Before, the stagnation cut the load step back (issue 35:
    the stiff punch's and the cylinder's slivers' noise)."""
    u, log, _ = _noisy_pair(1e-7)
    assert log.converged and log.message == "displacement converged"
    assert log.residuals[-1] > 1e-9  # above the target: accepted on the step, not the residual
    assert np.abs(u - 1.0).max() <= 1e-6


def test_a_stall_whose_full_newton_step_is_above_utol_still_fails():
    from contopt.solve.newton import StepFailure

    # noise 1e-5: still inside sqrt(rtol) of the load, but the full steps are 1e-5 of |u|, above utol
    with pytest.raises(StepFailure, match="stagnated") as err:
        _noisy_pair(1e-5)
    assert err.value.stalled is not None


def test_a_creep_to_max_iter_whose_full_newton_step_is_below_utol_is_converged():
    """The same noisy springs cut short by ``max_iter`` = 4 before the stagnation test (ten iterations)
    can see them: the residual sits at the noise (1e-7) without a digit gained, inside sqrt(rtol) of the
    load, full steps 1e-7 |u|: converged on the step, as at a stagnation (the seam under a stiff roller
    crept by halvings to max_iter, issue 35)."""
    u, log, _ = _noisy_pair(1e-7, max_iter=4)
    assert log.converged and log.message == "displacement converged"
    assert log.iterations == 4 and log.residuals[-1] > 1e-9
    assert np.abs(u - 1.0).max() <= 1e-6


def test_a_creep_to_max_iter_with_full_steps_above_utol_still_fails():
    from contopt.solve.newton import StepFailure

    with pytest.raises(StepFailure, match="no convergence in 4 iterations") as err:
        _noisy_pair(1e-5, max_iter=4)
    assert err.value.stalled is not None


def test_load_steps_end_on_the_stops_and_grow_from_the_increment_they_had():
    """Three equal steps (1/3) with a stop at 0.5: the second step is cut to end there (1/6), the
    next is the full 1/3 again (the stop does not shrink the increment), and the last ends at 1."""
    from contopt.solve.newton import NewtonLog
    from contopt.solve.stepping import StepResult, solve_load_steps

    ends = []

    def step(u, t, dt, state):
        ends.append((t, dt))
        lg = NewtonLog(t=t, dt=dt, converged=True, iterations=10, residuals=(0.0,), increments=(), alphas=(),
                       r_ref=1.0, seconds={})  # fmt: skip
        return StepResult(t=t, u=u, logs=(lg,), evaluation=None)

    options = NewtonOptions(n_steps=3)
    solve_load_steps(step, 1, np.zeros(0, np.int64), lambda t: np.zeros(0), options, stops=(0.5,))
    assert [t for t, _ in ends] == pytest.approx([1 / 3, 0.5, 5 / 6, 1.0])
    assert [dt for _, dt in ends] == pytest.approx([1 / 3, 1 / 6, 1 / 3, 1 / 6])


def test_solve_static_refuses_stops_outside_the_load():
    from contopt.cases.two_blocks import two_blocks
    from contopt.solve.static import solve_static

    for stops in ((0.0,), (1.5,), ("half",)):
        with pytest.raises(ConfigError, match=r"stops must be .*load factors in \(0, 1\]"):
            solve_static(two_blocks(divisions=2), stops=stops)
