"""The two-blocks contact case's state and adjoint gradients at a grey design.

Run under ``mpiexec -n N python tests/_mpi_forward_adjoint.py penalty|alm OUT.npz [gamg|mumps]``
with the iterative solver (and that preconditioner); rank 0 writes the result to OUT.npz.
``solve`` is also what the tests call in their own process for the serial answer.
"""

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


def solve(enforcement: str, backend: str, preconditioner: str = "gamg") -> dict:
    """u (n_dofs,), the total contact force, the responses' values and gradients (2, n_cells)."""
    setup_jax()
    system = System.of(two_blocks(enforcement=enforcement, body_force=(0.0, 0.0, -0.05)))
    rho = np.ones(system.disc.n_cells)
    cells = np.arange(system.disc.n_cells)[system.disc.cell_slice("block")]
    rho[cells] = np.random.default_rng(3).uniform(0.5, 1.0, cells.size)
    linear = LinearSolverOptions(backend=backend, preconditioner=preconditioner)
    aug = TIGHT_AUGMENTATION if enforcement == "alm" else None
    state = solve_static(system, rho, newton=NewtonOptions(rtol=1e-11, n_steps=3), linear=linear, augmentation=aug)
    adj = sensitivities(system, state, [StrainEnergy(bodies="block"), ContactForce()], linear=linear)
    lam = tuple(r.lam for r in state.contact)
    from contopt.solve.linear import petsc

    return dict(
        petsc_factorizations=petsc.STATISTICS["factorizations"],
        petsc_setups=petsc.STATISTICS["setups"],
        petsc_fallbacks=petsc.STATISTICS["fallbacks"],
        u=state.u,
        force=np.asarray(system.contact.total_force(state.u, lam)),
        values=np.array([s.value for s in adj.sensitivities]),
        gradients=np.stack([s.gradient for s in adj.sensitivities]),
        ranks=system.disc.comm.size,
    )


if __name__ == "__main__":
    with abort_on_error():
        result = solve(sys.argv[1], backend="petsc", preconditioner=(sys.argv[3:] or ["gamg"])[0])
        if world().rank == 0:
            np.savez(sys.argv[2], **result)
