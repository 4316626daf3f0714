"""MOOSE's Hertz sphere on sphere (modules/contact/test/tests/hertz_spherical/hertz_contact.i): docs/validation.md (a).

Two equal spheres (R1 = R2 = 2, E1 = E2 = 1.40625e7, nu = 0.25) pressed together touch on their plane
of symmetry, flat and shear-free: one quarter hemisphere (symmetry planes x = 0 and y = 0) pressed on
a rigid frictionless plane by half the spheres' approach d = 0.01, MOOSE's set-up (its block 1000 is
clamped on its contact face). The input's header gives the closed form: with 1/R = 1/R1 + 1/R2 = 1
and 1/E = 2 (1 - nu^2)/E1 (E = 7.5e6), ``a^3 = 3 F R / (4 E)`` and ``d = a^2 / R``: F = 10000 gives
a = 0.1 and d = 0.01.

Measured (cells of h R at the pole; the quadratic path in 4 steps; multipliers to 1e-8), force
against ``4/3 E sqrt(R) d^1.5`` = 10000 and the contact radius (the pressure's second moment)
against the closed form's for the force the contact carries:

* h = 0.025 graded by 1.6 (cells of a/2, 2,360 hexes, 17 s): force -1.7 %, a -2.3 %;
* h = 0.02 graded by 1.4 (cells of a/2.5, 4,589 hexes): force -1.1 %, a -2.2 %;
* h = 0.01 (cells of a/5, 13,920 hexes, 216 s on 2 shared cores): force +1.8 %, a -1.2 %,
  the peak nodal pressure +2.9 % of Hertz's ``3 F / (2 pi a^2)``.

The force compares the equator's approach with Hertz's approach of distant points: the hemisphere's
own compression and the finite-strain material (a/R = 0.05) stay in it, hence a few per cent.
"""

import pytest
from _validation_models import HERTZ_A, HERTZ_D, HERTZ_F, hertz_sphere_model, hertz_sphere_results

from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static
from contopt.solve.system import System


def _solve(h: float, ratio: float = 1.4) -> dict:
    system = System.of(hertz_sphere_model(h, ratio=ratio))
    state = solve_static(
        system,
        newton=NewtonOptions(n_steps=4, rtol=1e-10),
        augmentation=AugmentationOptions(pressure_rtol=1e-8, gap_rtol=1e-8),
    )
    res = hertz_sphere_results(system, state)
    print(" ".join(f"{k}={v:.6g}" for k, v in res.items()))
    return res


def test_the_closed_form_of_the_header():
    """The header's numbers follow from its formulas (what the FE results are compared with)."""
    from _validation_models import hertz_closed_form, hertz_force

    a, d = hertz_closed_form(HERTZ_F)
    assert a == pytest.approx(HERTZ_A, rel=1e-12) and d == pytest.approx(HERTZ_D, rel=1e-12)
    assert hertz_force(HERTZ_D) == pytest.approx(HERTZ_F, rel=1e-12)


def test_moose_hertz_sphere_coarse():
    """Cells of a/2: the force within 4 % of the closed form's 10000 for the approach 0.01, the
    contact radius within 4 % of the closed form's for that force (both measured near 2 %: the
    edge falls inside a cell half as wide as a)."""
    res = _solve(0.025, ratio=1.6)
    assert res["force"] == pytest.approx(res["force_closed"], rel=0.04)
    assert res["a"] == pytest.approx(res["a_closed"], rel=0.04)


@pytest.mark.slow
def test_moose_hertz_sphere_fine():
    """Cells of a/5: the force within 3 %, the contact radius within 2 % and the peak pressure within
    5 % (a nodal value) of the closed form."""
    res = _solve(0.01)
    assert res["force"] == pytest.approx(res["force_closed"], rel=0.03)
    assert res["a"] == pytest.approx(res["a_closed"], rel=0.02)
    assert res["p0"] == pytest.approx(res["p0_closed"], rel=0.05)
