"""Run under ``mpiexec -n N``: the two-blocks contact case's state and adjoint gradient with the
iterative solver; rank 0 writes them to ``sys.argv[2]`` (.npz). ``sys.argv[1]``: penalty | alm."""

import sys

import numpy as np

from contopt.adjoint import sensitivities
from contopt.adjoint.check import TIGHT_AUGMENTATION
from contopt.cases.two_blocks import two_blocks
from contopt.config import setup_jax
from contopt.parallel import abort_on_error, world
from contopt.responses import ContactForce, StrainEnergy
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System


def main(enforcement: str, out: str) -> None:
    setup_jax()
    system = System.of(two_blocks(enforcement=enforcement, body_force=(0.0, 0.0, -0.05)))
    rho = np.ones(system.disc.n_cells)
    cells = np.arange(system.disc.n_cells)[system.disc.cell_slice("block")]
    rho[cells] = np.random.default_rng(3).uniform(0.5, 1.0, cells.size)
    linear = LinearSolverOptions(backend="petsc")
    aug = TIGHT_AUGMENTATION if enforcement == "alm" else None
    state = solve_static(system, rho, newton=NewtonOptions(rtol=1e-11, n_steps=3), linear=linear, augmentation=aug)
    adj = sensitivities(system, state, [StrainEnergy(bodies="block"), ContactForce()], linear=linear)
    lam = tuple(r.lam for r in state.contact)
    if world().rank == 0:
        np.savez(
            out,
            u=state.u,
            force=np.asarray(system.contact.total_force(state.u, lam)),
            values=np.array([s.value for s in adj.sensitivities]),
            gradients=np.stack([s.gradient for s in adj.sensitivities]),
            ranks=world().size,
            newton=state.newton_iterations,
        )


if __name__ == "__main__":
    with abort_on_error():
        main(sys.argv[1], sys.argv[2])
