"""The free flight of a press in one load step (contopt.solve.freeflight).

A punch starts ``GAP`` above a block and moves ``DEPTH`` down in 6 load steps: it touches at t = GAP /
DEPTH = 0.75, so the stepped path's first 4 steps only translate it. The known answer: those states are
the punch translated, stress-free, and the steps from t = 4/6 on are the same steps from the same state,
so the leap ends where the stepped path ends, in 3 fewer Newton iterations (4 steps of one iteration each
become one).
"""

import numpy as np
import pytest

from contopt.assembly.model import Body, BodyForce, Dirichlet, Model, RigidMotion
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.solve import freeflight
from contopt.solve.freeflight import Leap, free_flight
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

GAP, DEPTH = 0.45, 0.6


def _press(gap: float = GAP, law: str = "alm", punch_motion=None, loads=()) -> Model:
    block = box((1.0, 1.0, 0.5), (3, 3, 2))
    punch = box((0.6, 0.6, 0.3), (2, 2, 1), origin=(0.2, 0.2, 0.5 + gap))
    motion = (0.0, 0.0, -DEPTH) if punch_motion is None else punch_motion
    return Model(
        bodies=(Body("block", block, neo_hookean(1.0, 0.3)), Body("punch", punch, neo_hookean(10.0, 0.3))),
        dirichlet=(Dirichlet("block", "zmin", "xyz", 0.0), Dirichlet("punch", "zmax", "xyz", motion)),
        interfaces=(ContactInterface(nonmortar=("punch", "zmin"), mortar=("block", "zmax"), law=law_named(law)),),
        loads=loads,
    )


@pytest.mark.parametrize("law", ["alm", "penalty"])
def test_the_free_flight_in_one_step_ends_where_the_stepped_path_ends(law):
    system = System.of(_press(law=law))
    stepped = solve_static(system, newton=NewtonOptions(n_steps=6, leap=False))
    leapt = solve_static(system, newton=NewtonOptions(n_steps=6))
    assert [round(lg.t, 12) for lg in stepped.logs[:4]] == [round(k / 6, 12) for k in range(1, 5)]
    assert [lg.iterations for lg in stepped.logs[:4]] == [1, 1, 1, 1]
    assert stepped.contact[0].n_active > 0
    # one step to t = 4/6, of one Newton iteration (the consistent predictor of a translation is exact)
    assert leapt.logs[0].t == stepped.logs[3].t and leapt.logs[0].dt == leapt.logs[0].t
    assert leapt.logs[0].iterations == 1
    # then the stepped path's steps in contact, each solve as many iterations as there
    assert [(lg.t, lg.iterations) for lg in leapt.logs[1:]] == [(lg.t, lg.iterations) for lg in stepped.logs[4:]]
    assert leapt.newton_iterations == stepped.newton_iterations - 3
    # the same iterations from the same state (free flight converges to round-off): the states agree far
    # below Newton's rtol (1e-9) and the multipliers' pressure_rtol (1e-6)
    scale = np.abs(stepped.u).max()
    np.testing.assert_allclose(leapt.u, stepped.u, rtol=0, atol=1e-9 * scale)
    lam = stepped.contact[0].lam
    np.testing.assert_allclose(leapt.contact[0].lam, lam, rtol=0, atol=1e-6 * np.abs(lam).max())


def test_the_leap_lands_on_the_last_step_before_the_boxes_can_meet():
    system = System.of(_press())
    leap = free_flight(system, NewtonOptions(n_steps=6))
    assert leap is not None
    assert leap.t == pytest.approx(4 / 6, abs=1e-15) and leap.dt == pytest.approx(1 / 6) and leap.skipped == 4
    disc = system.disc
    punch = disc.body_displacement(leap.expected, "punch")
    np.testing.assert_array_equal(punch, np.tile([0.0, 0.0, -DEPTH * leap.t], (len(punch), 1)))
    assert not disc.body_displacement(leap.expected, "block").any()
    # touch at GAP / DEPTH exactly on a step's end: that step is the first in contact, not leapt over
    at_step = free_flight(System.of(_press(gap=DEPTH * 5 / 6)), NewtonOptions(n_steps=6))
    assert at_step is not None and at_step.t == pytest.approx(4 / 6, abs=1e-15)


def test_the_leap_keeps_the_grown_steps_of_the_stepped_path():
    # steps that grow x1.5 after easy ones: the leap lands on one of the stepped path's load factors and
    # the next step has the stepped path's length
    newton = NewtonOptions(n_steps=10, max_step=0.5)
    system = System.of(_press())
    stepped = solve_static(system, newton=NewtonOptions(n_steps=10, max_step=0.5, leap=False))
    leap = free_flight(system, newton)
    assert leap is not None and leap.skipped >= 3
    ends = [lg.t for lg in stepped.logs]
    k = ends.index(leap.t)
    assert k == leap.skipped - 1 and stepped.logs[k + 1].dt == pytest.approx(leap.dt, rel=1e-14)
    leapt = solve_static(system, newton=newton)
    assert [lg.t for lg in leapt.logs[1:]] == ends[k + 1 :]
    np.testing.assert_allclose(leapt.u, stepped.u, rtol=0, atol=1e-9 * np.abs(stepped.u).max())


def _tilting(X, t):
    """(k, 3) a motion that tilts the punch as it goes down: no translation"""
    return t * np.c_[0 * X[:, :2], -DEPTH * (1.0 + 0.1 * X[:, 0])]


def _accelerating(X, t):
    """(k, 3) a translation quadratic in t"""
    return np.c_[0 * X[:, :2], -DEPTH * t**2 + 0 * X[:, 0]]


@pytest.mark.parametrize(
    "model",
    [
        pytest.param(lambda: _press(gap=0.0), id="in-touch"),
        pytest.param(lambda: _press(loads=(BodyForce("block", (0.0, 0.0, -0.1)),)), id="loaded"),
        pytest.param(lambda: _press(punch_motion=_tilting), id="not-a-translation"),
        pytest.param(lambda: _press(punch_motion=_accelerating), id="t^2"),
    ],
)
def test_no_leap_where_the_free_flight_is_not_known(model):
    assert free_flight(System.of(model()), NewtonOptions(n_steps=6)) is None


def test_no_leap_for_a_rotating_tool_or_one_step_or_when_off():
    from contopt.mesh.generators import box as mesh_box

    system = System.of(_press())
    assert free_flight(system, NewtonOptions(n_steps=1)) is None
    assert free_flight(system, NewtonOptions(n_steps=6, leap=False)) is None
    block = mesh_box((1.0, 1.0, 0.5), (3, 3, 2))
    tool = mesh_box((0.6, 0.6, 0.3), (2, 2, 1), origin=(0.2, 0.2, 0.5 + GAP))
    turning = Model(
        bodies=(
            Body("block", block, neo_hookean(1.0, 0.3)),
            Body("tool", tool, rigid=RigidMotion(translation=(0.0, 0.0, -DEPTH), angle=0.1)),
        ),
        dirichlet=(Dirichlet("block", "zmin", "xyz", 0.0),),
        interfaces=(ContactInterface(nonmortar=("block", "zmax"), mortar=("tool", "zmin"), law=law_named("alm")),),
    )
    assert free_flight(System.of(turning), NewtonOptions(n_steps=6)) is None


def test_a_leap_that_does_not_land_is_dropped_for_the_load_steps(monkeypatch):
    # a leap that expects another state (as where something the leap does not know loads the bodies):
    # its solve is kept as a failed attempt and the load steps start from zero, to the stepped path's end
    system = System.of(_press())
    stepped = solve_static(system, newton=NewtonOptions(n_steps=6, leap=False))
    real = freeflight.free_flight

    def wrong(*args):
        leap = real(*args)
        return Leap(t=leap.t, dt=leap.dt, skipped=leap.skipped, expected=2.0 * leap.expected)

    monkeypatch.setattr("contopt.solve.static.free_flight", wrong)
    state = solve_static(system, newton=NewtonOptions(n_steps=6))
    assert not state.logs[0].converged and state.logs[0].t == pytest.approx(4 / 6)
    assert [(lg.t, lg.iterations) for lg in state.logs[1:]] == [(lg.t, lg.iterations) for lg in stepped.logs]
    assert state.newton_iterations == stepped.newton_iterations
    np.testing.assert_allclose(state.u, stepped.u, rtol=0, atol=1e-9 * np.abs(stepped.u).max())
