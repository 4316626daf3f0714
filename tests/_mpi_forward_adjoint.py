"""The two-blocks contact case's state and adjoint gradients at a grey design.

Run under ``mpiexec -n N python tests/_mpi_forward_adjoint.py penalty|alm|friction OUT.npz [gamg|mumps]``
with the iterative solver (and that preconditioner); rank 0 writes the result to OUT.npz.
``solve`` and ``solve_friction`` are also what the tests call in their own process for the serial
answer.
"""

import sys
from dataclasses import replace

import numpy as np

from contopt.adjoint import sensitivities
from contopt.adjoint.check import TIGHT_AUGMENTATION
from contopt.cases.two_blocks import two_blocks
from contopt.config import setup_jax
from contopt.contact.coulomb import Coulomb
from contopt.parallel import abort_on_error, world
from contopt.responses import ContactForce, StrainEnergy
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System


def solve(law: str, backend: str, preconditioner: str = "gamg") -> dict:
    """u (n_dofs,), the total contact force, the responses' values and gradients (2, n_cells)."""
    setup_jax()
    system = System.of(two_blocks(law=law, body_force=(0.0, 0.0, -0.05)))
    rho = _grey(system)
    linear = LinearSolverOptions(backend=backend, preconditioner=preconditioner)
    aug = TIGHT_AUGMENTATION if law == "alm" else None
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


def solve_friction(backend: str) -> dict:
    """The punch pressed and pushed sideways with Coulomb friction (mu 0.3, penalty normal law; some
    nodes stick, some slip), solved along its path; the path adjoint's gradients of the same two
    responses. The unsymmetric solves stop at 1e-12 (GMRES on PETSc), Newton at 1e-11."""
    setup_jax()
    model = two_blocks(law="penalty", body_force=(0.0, 0.0, -0.05), shift=0.01)
    model = replace(model, interfaces=(replace(model.interfaces[0], friction=Coulomb(0.3)),))
    system = System.of(model)
    linear = LinearSolverOptions(backend=backend, krylov_rtol=1e-12)
    state = solve_static(system, _grey(system), NewtonOptions(rtol=1e-11, n_steps=3), linear)
    adj = sensitivities(system, state, [StrainEnergy(bodies="block"), ContactForce()], linear=linear)
    friction = state.contact[0].friction
    return dict(
        u=state.u,
        traction=state.contact[0].traction,
        n_stick=friction.n_stick,
        n_slip=friction.n_slip,
        values=np.array([s.value for s in adj.sensitivities]),
        gradients=np.stack([s.gradient for s in adj.sensitivities]),
        ranks=system.disc.comm.size,
    )


def _grey(system: System) -> np.ndarray:
    """(n_cells,) the block's cells uniform in [0.5, 1], the punch's 1."""
    rho = np.ones(system.disc.n_cells)
    cells = np.arange(system.disc.n_cells)[system.disc.cell_slice("block")]
    rho[cells] = np.random.default_rng(3).uniform(0.5, 1.0, cells.size)
    return rho


if __name__ == "__main__":
    with abort_on_error():
        if sys.argv[1] == "friction":
            result = solve_friction(backend="petsc")
        else:
            result = solve(sys.argv[1], backend="petsc", preconditioner=(sys.argv[3:] or ["gamg"])[0])
        if world().rank == 0:
            np.savez(sys.argv[2], **result)
