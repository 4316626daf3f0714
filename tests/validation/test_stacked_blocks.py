"""Zimmerman & Ateshian (2018) §3.5, FEBio's stacked blocks: docs/validation.md (d).

Four 2 mm cubes, stiff (E = 10 MPa, nu = 0.1) and soft (E = 0.3 MPa, nu = 0.4) in turn, on
dissimilar meshes; Coulomb friction mu = 0.05 between blocks 1-2 and 2-3 and mu = 1 between 3-4;
the top pressed down. The paper's answer (its §3.5 text, as LLNL Smith's example of it restates
it): the soft block 2 spreads and slides on its low-friction neighbours, block 4 sticks to block 3.
Here: on the mu = 0.05 interfaces the nodes slip with the traction on the Coulomb cone, |t| = mu p
(to the cone's rounding: Coulomb's ``edge`` 0.05 lets a node between (1 -+ 0.05) mu p fall short of
it by at most 0.05/4), the friction force at most mu N; on the mu = 1 interface every node in
contact sticks; the vertical force the same through every interface and the top.
"""

import numpy as np
import pytest
from _validation_models import STACK_MU, stacked_blocks_model

from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

EDGE = 0.05  # Coulomb's default rounding of the cone


def _check(press: float, cells, steps: int):
    model = stacked_blocks_model(press=press, cells=cells)
    system = System.of(model)
    state = solve_static(system, newton=NewtonOptions(n_steps=steps))
    top = system.disc.blocks[0].node_offset + model.body("block1").mesh.node_set("zmax")
    force = float(-state.reactions.reshape(-1, 3)[top, 2].sum())
    for k, res in enumerate(state.contact):
        lam, a, t = np.asarray(res.lam), np.asarray(res.a), np.asarray(res.traction)
        act = lam > 0
        stick = np.asarray(res.friction.stick) & act
        ratio = np.linalg.norm(t, axis=1)[act] / (STACK_MU[k] * lam[act])
        print(
            f"interface {k + 1}: active {act.sum()} stick {stick.sum()} |t|/(mu p) {ratio.min():.4f}-{ratio.max():.4f}"
        )
        assert float(lam @ a) == pytest.approx(force, rel=0.01)  # the stack carries one force
        assert np.linalg.norm(t, axis=1) @ a <= STACK_MU[k] * float(lam @ a) * (1 + 1e-9)
        if STACK_MU[k] < 1:
            assert not stick.any()  # block 2 slides on both its neighbours
            assert ratio.min() > 1 - EDGE / 4 - 1e-6 and ratio.max() < 1 + 1e-6
        else:
            assert stick.sum() == act.sum() and ratio.max() < 1 - EDGE  # block 4 sticks to block 3
    return state


def test_stacked_blocks_slide_on_low_friction_and_stick_on_high():
    """Pressed by 0.25 mm (3 % of the stack) on coarse dissimilar meshes (3, 5, 3, 5 cells a side)."""
    _check(0.25, (3, 5, 3, 5), 2)


@pytest.mark.slow
def test_stacked_blocks_pressed_by_a_quarter():
    """The top down by 1 mm (half the paper's 2 mm: the full load needs cut steps beyond 1.02 mm),
    4, 7, 4, 7 cells a side, 5 steps (133 s)."""
    _check(1.0, None, 5)
