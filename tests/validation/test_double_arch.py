"""Kratos Examples' double arch (contact_structural_mechanics/validation/double_arch): docs/validation.md (c).

The full curve is benchmarks/validation.py's (minutes); here the part of the model that the
difference from the reference turned on: the quarter ring's end stiffness (its bottom clamped, its
end moved down with x held, plane strain) against a curved composite Timoshenko beam. contopt's F-bar
hex8 gives the beam's stiffness to 1.5 % (the composite's shear factor 5/6 is the approximate part:
without shear the beam is 2.3 % stiffer); plain hex8 on Kratos' in-plane mesh (30 cells around the
quarter, 2 across each layer) is 28 % stiffer: it locks in bending, as Kratos' elements do.
"""

from dataclasses import replace

import pytest
from _validation_models import ARCH_DEPTH, arch_ring_beam_stiffness, arch_ring_model

from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

TRAVEL = 1e-5  # small: the linear stiffness


def _end_stiffness(n_theta: int, n_layer: int, fbar: bool = True) -> float:
    """N/m per metre of depth, from the strain energy W = k d^2 / 2 of the end moved by d."""
    model, rho = arch_ring_model(n_theta, n_layer, TRAVEL)
    if not fbar:
        model = replace(model, bodies=tuple(replace(b, fbar=False) for b in model.bodies))
    system = System.of(model)
    state = solve_static(system, rho, newton=NewtonOptions(n_steps=1))
    return 2.0 * float(system.disc.strain_energy(state.u, rho)) / TRAVEL**2 / ARCH_DEPTH


def test_arch_ring_end_stiffness_is_the_curved_beams():
    """48 cells around the quarter ring and 2 across each layer (the benchmark's mesh): within 3 %."""
    assert _end_stiffness(48, 2) == pytest.approx(arch_ring_beam_stiffness(), rel=0.03)


def test_arch_ring_plain_hex8_locks_on_kratos_mesh():
    """Without F-bar, Kratos' in-plane mesh: more than 15 % stiffer than the beam (measured 28 %)."""
    assert _end_stiffness(30, 2, fbar=False) > 1.15 * arch_ring_beam_stiffness()
