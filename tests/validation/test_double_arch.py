"""Kratos Examples' double arch (contact_structural_mechanics/validation/double_arch): docs/validation.md (c).

The full curve is benchmarks/validation.py's (minutes); here the part of the model that the
difference from the reference turned on: the quarter ring's end stiffness (its bottom clamped, its
end moved down with x held, plane strain) against a curved composite Timoshenko beam. contopt's F-bar
hex8 gives the beam's stiffness to 1.5 % (the composite's shear factor 5/6 is the approximate part:
without shear the beam is 2.3 % stiffer); plain hex8 on Kratos' in-plane mesh (30 cells around the
quarter, 2 across each layer) is 28 % stiffer: it locks in bending, as Kratos' elements do.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from _validation_models import (
    ARCH_DEPTH,
    arch_centre_node,
    arch_ring_beam_stiffness,
    arch_ring_model,
    double_arch_model,
)

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


def _centre_minus_reference(e_base: float):
    """The centre's displacement minus the reference at its points to 20 mm (coarse mesh, 1 mm steps)."""
    model, rho = double_arch_model(n_theta=24, n_layer=1, h_base=0.005, travel=0.02, e_base=e_base)
    node = arch_centre_node(model)
    curve = [(0.0, 0.0)]

    def record(state):
        curve.append((0.02 * float(state.t), float(state.u.reshape(-1, 3)[node, 1])))

    solve_static(System.of(model), rho, newton=NewtonOptions(n_steps=20), on_step=record)
    ref = np.loadtxt(Path(__file__).parent / "data" / "double_arch_reference.csv", delimiter=",", skiprows=4)
    ref = ref[ref[:, 0] <= 0.02]
    c = np.asarray(curve)
    d = np.interp(ref[:, 0], c[:, 0], c[:, 1]) - ref[:, 1]
    print(f"base {e_base:.0e}: centre minus reference (mm) at {np.round(1e3 * ref[:, 0], 1)}: {np.round(1e3 * d, 2)}")
    return d


def test_arch_follows_the_reference_with_the_base_at_1e8():
    """docs/validation.md (c): with the base three times softer than Kratos' file (1e8 Pa), the
    centre follows the reference's first 20 mm (its points to 18.5 mm) within 0.5 mm on the coarse
    mesh (24 cells around, 1 across each layer, base 5 mm; measured at most 0.38 mm, at 7.1 mm where
    the reference kinks)."""
    assert np.abs(_centre_minus_reference(1e8)).max() < 5e-4


def test_arch_falls_short_of_the_reference_with_kratos_base():
    """With Kratos' file's base (3e8 Pa) the centre is more than 2 mm short of the reference at 9.4 mm
    (docs/validation.md (c): not passed)."""
    assert _centre_minus_reference(3e8)[2] > 2e-3
