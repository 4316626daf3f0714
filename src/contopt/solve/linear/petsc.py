"""The ``petsc`` backend: Krylov methods (CG; GMRES, BiCGStab) preconditioned with PETSc's smoothed-aggregation AMG.

A direct factorization costs O(n^2) time and O(n^(4/3)) memory on 3D meshes; preconditioned CG
costs about O(n) per solve and the matrix's memory. What the backend does with a (free x free)
stiffness matrix ``K`` and the :class:`~contopt.solve.linear.base.Geometry` of its rows:

* the operator is the full (n_dofs x n_dofs) matrix with the prescribed dofs' rows and columns
  replaced by ``d I`` (``d`` the mean |diagonal| of K), so that every node keeps its three dofs
  (block size 3) and the rigid-body modes of the bodies, computed from the nodes' current
  positions, are a near-null space of every aggregate; it is assembled through PETSc's COO
  interface (``setPreallocationCOO`` once per sparsity pattern, ``setValuesCOO`` per matrix);
* the preconditioner is GAMG with SOR smoothers and an aggregation threshold
  (:attr:`LinearSolverOptions.amg_threshold`); the Krylov method CG on the true residual
  (``||K x - b|| <= rtol ||b||``; with a zero initial guess PETSc's unpreconditioned norm is
  exactly that);
* the matrix, the solver and its preconditioner are kept for the next matrix of the same pattern:
  Newton iterations, multiplier updates and the adjoint then pay only ``setValuesCOO`` and, when
  the iterations have grown :attr:`~LinearSolverOptions.reuse_growth`-fold since the
  preconditioner was built, a new set-up;
* an unsymmetric matrix (``symmetric=False``: frictional contact) is solved with GMRES or
  BiCGStab (:attr:`~LinearSolverOptions.unsymmetric_krylov`) and the same GAMG (which aggregates
  on the symmetrized graph, PETSc's default), and its factorization is MUMPS's LU;
* a solve that does not converge is retried with GMRES when CG met negative curvature (an
  indefinite tangent: the paper-size sabot at its full load), else with a fresh preconditioner
  when it used a kept one; after that (or when GMRES needed more than :data:`GMRES_WORTH`
  iterations) the preconditioner becomes a factorization: MUMPS's LDL^T of the matrix, which
  handles indefinite tangents and works on any number of ranks, kept for the next matrices like
  the AMG (GMRES then needs a few iterations while the tangent is near the factored one, and the
  factorization is redone when they grow). This is also ``preconditioner="mumps"`` from the start.
  Only when MUMPS fails too does a serial run fall back to the caller's ``direct`` factorization;
  each switch is said in the log. With ``backend="auto"`` (which took the AMG for the size alone) a
  serial run whose direct factor fits in memory (:func:`~contopt.solve.linear.base.direct_fits`)
  goes to that factorization instead of MUMPS, and factors the next matrices of the same dofs
  directly too. GMRES stops early when its rate says it will not reach the
  tolerance in its iterations (:func:`contopt.solve.linear.reuse.hopeless`).

Options reach PETSc under the prefix ``contopt_``, so ``PETSC_OPTIONS="-contopt_ksp_monitor"``
(or any ``-contopt_pc_gamg_*``) adds to or overrides them.

The binary wheel this uses (``dolfinx-solver-real``, see :mod:`contopt.solve.linear.petsc_install`)
links its own OpenBLAS and MPICH; :func:`load` puts its MPI library in the process and says what
to run when the wheel has not been prepared to live beside the system's OpenBLAS.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from contopt.errors import LinearSolverError
from contopt.parallel import Comm, MPIComm, node_range, preload_mpi
from contopt.solve.linear.base import Factor, Geometry, Unsuitable, direct_fits, logger
from contopt.solve.linear.choice import Choice
from contopt.solve.linear.options import LinearSolverOptions
from contopt.solve.linear.reuse import hopeless
from contopt.timing import timed

PREFIX = "contopt_"
#: what to run when the wheel is installed but cannot be loaded beside the system's BLAS
PREPARE_HINT = "python -m contopt.solve.linear.petsc_install"
#: PETSc's KSP type of each LinearSolverOptions.unsymmetric_krylov
KSP_TYPES = {"gmres": "gmres", "bicgstab": "bcgs"}
#: PETSc's reasons for a CG that met a non-positive curvature (KSP_DIVERGED_INDEFINITE_PC, _MAT):
#: the tangent is indefinite there, and GMRES may still solve it
INDEFINITE = (-8, -10)
#: GMRES iterations with the AMG beyond which a factorization preconditioner is cheaper: one
#: GAMG iteration costs ~0.4 s at 336k dofs on one process, one factorization of that matrix
#: 39.9 s with Pardiso and ~250 s with MUMPS (docs/scaling.md); the paper-size sabot at its full
#: load needed 289-486
GMRES_WORTH = 100
#: iterations of a factorization-preconditioned solve before the factorization is redone: with
#: the current matrix's factor GMRES needs 1-3, with an older one a few more
FACTOR_MAX_ITER = 30
#: a kept factorization is redone after a solve that needed more iterations than this
FACTOR_REFACTOR_ITER = 10
#: iterations and set-ups of this process's iterative solves (benchmarks and tests read them);
#: "factorizations": set-ups that factored (MUMPS) rather than built the AMG
STATISTICS = {
    "setups": 0,
    "factorizations": 0,
    "solves": 0,
    "iterations": 0,
    "reused": 0,
    "retries": 0,
    "fallbacks": 0,
    "switches": 0,
}


@functools.cache
def load() -> Any:
    """petsc4py's ``PETSc`` module, initialized once (ImportError when PETSc is not usable here)."""
    preload_mpi()
    try:
        import petsc4py

        # no command line for PETSc (it is contopt's); PETSC_OPTIONS still reaches it
        petsc4py.init([sys.argv[0] if sys.argv else "contopt", "-options_left", "no", "-no_signal_handler"])
        from petsc4py import PETSc
    except ImportError as exc:
        if "undefined symbol" in str(exc) or "cannot open shared object" in str(exc):
            raise ImportError(
                f"PETSc is installed but cannot be loaded in this process ({exc}). Its wheel brings its own "
                f"OpenBLAS and MPI; run `{PREPARE_HINT}` once (make setup does) so that they live beside the "
                "system's libraries."
            ) from exc
        raise
    return PETSc


@dataclass(eq=False)
class _Solver:
    """The operator of the current matrix, the matrix the preconditioner was built from and the
    Krylov solver, kept for the next matrix on the same dofs.

    A matrix of a new sparsity pattern (contact pairs come and go between Newton iterations)
    gets a new operator ``A``; the preconditioner stays built from the older ``P`` until it is
    judged stale, then is rebuilt from ``A`` (and ``P`` becomes ``A``).
    """

    free: np.ndarray  # (n,) the dofs of the matrix's rows
    comm: Comm
    ksp: Any  # PETSc KSP
    A: Any = None  # PETSc Mat, n_dofs x n_dofs (its rows split over the ranks): the current matrix
    P: Any = None  # the matrix the preconditioner was built from (A itself, or an older one)
    pattern_key: bytes = b""  # the digest of the sparsity pattern of A's free part (_pattern_key)
    n_prescribed: int = 0  # the prescribed dofs' diagonal entries this rank adds (all on rank 0)
    geometry: Geometry | None = None  # of the current matrix: the rigid-body modes at the next set-up
    # iterations per decade of residual reduction (Newton asks for different tolerances): of the
    # first solve with the current preconditioner (-1: none yet), and of the last solve
    setup_rate: float = -1.0
    last_rate: float = 0.0
    last_its: int = 0  # iterations of the last converged solve
    stale: bool = True  # the preconditioner must be (re)built before the next solve
    busy: bool = False  # a live factor uses it
    factored: bool = False  # the preconditioner is a factorization (MUMPS), not the AMG
    prefer_direct: bool = False  # "auto" saw the AMG fail on these dofs: factor their matrices directly
    give_up_within: int = 0  # > 0: stop a solve whose rate would not reach rtol in this many iterations
    r0: float = 0.0  # the residual norm at the start of the solve under way
    deadline: float = 0.0  # > 0: the perf_counter() past which the solve under way stops ("auto"'s trial)
    symmetric: bool = True  # the matrices are symmetric (CG, LDL^T); else GMRES/BiCGStab and LU
    unsymmetric_krylov: str = "gmres"  # PETSc's KSP type for unsymmetric matrices

    def use_factorization(self, PETSc) -> None:
        """From now on the preconditioner is MUMPS's LDL^T (LU if unsymmetric) of the matrix, built
        at the next solve."""
        pc = self.ksp.getPC()
        # on a matrix not marked SPD, "cholesky" is MUMPS's symmetric indefinite LDL^T
        pc.setType("cholesky" if self.symmetric else "lu")
        pc.setFactorSolverType("mumps")
        self.factored, self.stale = True, True

    def same_dofs(self, free: np.ndarray, symmetric: bool) -> bool:
        return (
            not self.busy
            and self.symmetric == symmetric
            and self.free.size == free.size
            and np.array_equal(self.free, free)
        )

    def ksp_type(self, gmres: bool) -> str:
        """CG on symmetric matrices (GMRES when asked: an indefinite one, or with a factorization);
        the unsymmetric method (GMRES or BiCGStab) on the others."""
        if not self.symmetric:
            return KSP_TYPES[self.unsymmetric_krylov]
        return "gmres" if gmres else "cg"

    def method(self) -> str:
        krylov = {"cg": "CG", "gmres": "GMRES", "bcgs": "BiCGStab"}[self.ksp_type(gmres=self.factored)]
        factor = "LDL^T" if self.symmetric else "LU"
        return f"{krylov} + MUMPS {factor} (PETSc)" if self.factored else f"{krylov} + GAMG (PETSc)"

    def same_pattern(self, K: sp.csr_matrix) -> bool:
        return self.pattern_key == _pattern_key(K)

    def new_operator(self, PETSc, K: sp.csr_matrix, rows: np.ndarray, geometry: Geometry) -> None:
        """``A`` with the pattern of ``K`` (the old one is kept only as long as the preconditioner's)."""
        n_dofs = geometry.n_dofs
        r, c, self.n_prescribed = _full_coo(K, rows, geometry.free, n_dofs, geometry.comm, PETSc.IntType)
        own = node_range(geometry.points.shape[0], geometry.comm)  # whole nodes: block size 3
        n_local = 3 * (own.stop - own.start)
        A = PETSc.Mat().create(comm=_petsc_comm(PETSc, geometry.comm))
        A.setSizes(((n_local, n_dofs), (n_local, n_dofs)))
        A.setType("aij")
        A.setBlockSize(3)
        A.setPreallocationCOO(r, c)
        del r, c
        if self.A is not None and self.A is not self.P:
            self.A.destroy()
        self.A = A
        self.pattern_key = _pattern_key(K)

    def rebuild(self, PETSc) -> None:
        """The preconditioner from the current matrix (with the bodies' rigid-body modes)."""
        if self.P is not None and self.P is not self.A:
            self.P.destroy()
        self.P = self.A
        if not self.factored and self.geometry is not None and np.any(self.geometry.points):
            space = _near_null_space(PETSc, self.A, self.geometry)
            self.A.setNearNullSpace(space)
            space.destroy()
        pc = self.ksp.getPC()
        pc.setReusePreconditioner(False)
        self.ksp.setOperators(self.A, self.P)
        self.ksp.setUp()
        pc.setReusePreconditioner(True)
        self.setup_rate = -1.0
        self.stale = False

    def destroy(self) -> None:
        self.ksp.destroy()
        for m in {id(self.A): self.A, id(self.P): self.P}.values():
            if m is not None:
                m.destroy()


#: the kept solver (one: the memory of a second matrix and hierarchy is not worth it)
_KEPT: list[_Solver] = []


def kept_solvers() -> int:
    """How many operators, Krylov solvers and preconditioners are kept for the next matrices."""
    return len(_KEPT)


def release_kept() -> None:
    """Destroy the kept matrices, solver and preconditioner (frees their memory)."""
    while _KEPT:
        _KEPT.pop().destroy()


def _pattern_key(K: sp.csr_matrix) -> bytes:
    """A digest of K's sparsity pattern: a kept copy of the pattern would cost 4 bytes a stored
    entry for as long as the operator lives (0.2 GB a rank at a million dofs)."""
    h = hashlib.blake2b(digest_size=32)
    for a in (np.asarray(K.shape), K.indptr, K.indices):
        h.update(str(a.dtype).encode())
        h.update(np.ascontiguousarray(a).data)
    return h.digest()


def _full_coo(K: sp.csr_matrix, rows: np.ndarray, free: np.ndarray, n_dofs: int, comm: Comm, index_type):
    """COO rows/cols (nnz + prescribed,) of ``index_type`` (PETSc's) of K on the full dofs plus the
    prescribed diagonal (added by rank 0 alone: the ranks' entries are summed)."""
    # made in PETSc's int type from the start: at 10^8 entries an int64 detour costs gigabytes
    free = free.astype(index_type)
    prescribed = np.setdiff1d(np.arange(n_dofs, dtype=index_type), free) if comm.rank == 0 else free[:0]
    r, c = np.empty(K.nnz + prescribed.size, index_type), np.empty(K.nnz + prescribed.size, index_type)
    np.take(free, rows, out=r[: K.nnz])
    np.take(free, K.indices, out=c[: K.nnz])
    r[K.nnz :] = c[K.nnz :] = prescribed
    return r, c, prescribed.size


def _values(K: sp.csr_matrix, n_prescribed: int) -> np.ndarray:
    scale = float(np.abs(K.diagonal()).mean()) or 1.0
    return np.concatenate([K.data, np.full(n_prescribed, scale)])


def _petsc_comm(PETSc, comm: Comm):
    return PETSc.Comm(comm.mpi) if isinstance(comm, MPIComm) else PETSc.COMM_SELF


def _new_solver(PETSc, geometry: Geometry, opts: LinearSolverOptions) -> _Solver:
    ksp = PETSc.KSP().create(comm=_petsc_comm(PETSc, geometry.comm))
    ksp.setOptionsPrefix(PREFIX)
    ksp.setType("cg" if opts.symmetric else KSP_TYPES[opts.unsymmetric_krylov])
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setInitialGuessNonzero(False)
    ksp.getPC().setType("gamg")
    db = PETSc.Options(PREFIX)
    # Only where the user (PETSC_OPTIONS) said nothing: their word wins.
    for key, value in (
        ("pc_gamg_threshold", opts.amg_threshold),
        ("mg_levels_ksp_type", "richardson"),
        ("mg_levels_pc_type", "sor"),
    ):
        if not db.hasName(key):
            db.setValue(key, value)
    ksp.setFromOptions()
    solver = _Solver(
        free=geometry.free.copy(),
        comm=geometry.comm,
        ksp=ksp,
        symmetric=opts.symmetric,
        unsymmetric_krylov=opts.unsymmetric_krylov,
    )
    ksp.addConvergenceTest(_give_up, args=(solver,))  # after PETSc's own test (converged wins)
    if opts.preconditioner == "mumps":
        solver.use_factorization(PETSc)
    return solver


def _give_up(ksp, its: int, rnorm: float, solver: _Solver) -> int:
    """PETSc's reason to stop: -3 (as at the iteration limit) once the rate so far says that the
    solve would need over 1.5 ``solver.give_up_within`` iterations, or past ``solver.deadline``,
    else 0 (go on)."""
    if its == 0:
        solver.r0 = rnorm
        return 0
    if solver.deadline and time.perf_counter() > solver.deadline:
        return -3
    if solver.give_up_within and its >= 2 and solver.r0 > 0.0:
        if hopeless(rnorm / solver.r0, its, ksp.getTolerances()[0], solver.give_up_within):
            return -3
    return 0


def _near_null_space(PETSc, A, geometry: Geometry):
    lo, hi = A.getOwnershipRange()
    coords = A.createVecLeft()
    coords.setBlockSize(3)
    coords.getArray()[:] = np.asarray(geometry.points, dtype=np.float64).ravel()[lo:hi]
    space = PETSc.NullSpace().createRigidBody(coords)
    coords.destroy()
    return space


class PetscSolve(Factor):
    """CG (GMRES, BiCGStab) + GAMG on one matrix (see the module docstring); ``info['iterations']``
    lists every solve's."""

    backend = "petsc"
    iterative = True

    def __init__(
        self, PETSc, solver: _Solver, K, opts: LinearSolverOptions, direct: Callable[[], Factor],
        trial: Choice | None = None, spent: float = 0.0,
    ):  # fmt: skip
        super().__init__(K.shape[0], solver.method())
        self._PETSc, self._solver, self._K, self._opts, self._direct = PETSc, solver, K, opts, direct
        self._fallback: Factor | None = None
        # "auto"'s trial (contopt.solve.linear.choice): its record, and this matrix's seconds so far
        self._trial, self._spent = trial, spent
        self.info["iterations"] = []
        self.info["preconditioner_reused"] = not solver.stale
        solver.busy = True

    def _solve(self, b: np.ndarray) -> np.ndarray:
        if b.ndim == 2:
            return np.column_stack([self._solve_one(b[:, j]) for j in range(b.shape[1])])
        return self._solve_one(b)

    def _solve_one(self, b: np.ndarray) -> np.ndarray:
        rtol = self._opts.krylov_rtol if self.rtol is None else float(self.rtol)
        if self._fallback is not None:
            return self._fallback.solve(b)
        if not np.any(b):
            return np.zeros_like(b)
        start = time.perf_counter()
        self._solver.deadline = start + self._trial.budget if self._trial is not None else 0.0
        try:
            return self._attempts(b, rtol)
        except self._PETSc.Error as exc:
            if not self._solver.factored:
                raise
            # MUMPS could not factor (memory, a zero pivot): at the switch or on a later refactorization
            why = str(exc).strip().splitlines()[-1]
            logger.warning("MUMPS could not factor the matrix: %s", why)
            return self._fall_back(b, 0, 0, mumps_failed=why)
        finally:
            self._solver.deadline = 0.0
            self._spent += time.perf_counter() - start

    def _attempts(self, b: np.ndarray, rtol: float) -> np.ndarray:
        """The solve, retries and the switch to a factorization; a failed MUMPS factorization raises."""
        s = self._solver
        # each failed attempt costs up to krylov_max_iter iterations: retry only where it can help
        reused = not s.stale
        x, reason, its = self._krylov(b, rtol, gmres=s.factored)
        if reason > 0:
            return x
        if s.deadline and time.perf_counter() > s.deadline:  # "auto"'s trial lost: no retries
            return self._fall_back(b, reason, its, expected=True)
        if reason in INDEFINITE and not s.factored and self._trial is not None:
            # "auto"'s trial: an indefinite contact tangent stays with the factor (GMRES with the AMG
            # may converge, slowly, a Newton iteration after another: the paper-size sabot's full load)
            return self._fall_back(b, reason, its, expected=True)
        if reason in INDEFINITE and not s.factored:
            # negative curvature is the matrix's (an indefinite tangent), not the preconditioner's fault
            x, reason, its = self._retry(b, rtol, "GMRES", reason, its, gmres=True, max_it=GMRES_WORTH)
        elif reused:  # a kept preconditioner: one of the same kind built from this matrix may do
            x, reason, its = self._retry(b, rtol, "new preconditioner", reason, its, gmres=s.factored)
        if reason > 0:
            return x
        if not s.factored and self._direct_first():
            # "auto" chose the AMG by size only: a direct factor that fits beats MUMPS inside PETSc
            s.prefer_direct = True
            return self._fall_back(b, reason, its)
        if not s.factored and self._mumps():
            logger.warning(
                "%s did not converge on this %dx%d matrix (reason %d, %d iterations); preconditioning with a "
                "MUMPS factorization from now on (kept, and redone when the iterations grow)",
                self.info["method"], *self.shape, reason, its,
            )  # fmt: skip
            STATISTICS["switches"] += 1
            s.use_factorization(self._PETSc)
            self.info["method"] = s.method()
            x, reason, its = self._krylov(b, rtol, gmres=True)
            if reason > 0:
                return x
        return self._fall_back(b, reason, its)

    def _retry(self, b, rtol, attempt: str, reason: int, its: int, gmres: bool, max_it: int | None = None):
        STATISTICS["retries"] += 1
        logger.info("PETSc %s did not converge (reason %d, %d iterations); retrying: %s", self.info["method"],
                    reason, its, attempt)  # fmt: skip
        self._solver.stale = self._solver.stale or attempt == "new preconditioner"
        return self._krylov(b, rtol, gmres=gmres, max_it=max_it)

    def _direct_first(self) -> bool:
        """Whether a failed AMG solve goes to the caller's direct factorization before MUMPS: with
        ``backend="auto"`` in a serial run, when the factor fits in memory."""
        return self._opts.backend == "auto" and not self._solver.comm.distributed and direct_fits(self.shape[0])

    def _mumps(self) -> bool:
        return bool(self._PETSc.Sys.hasExternalPackage("mumps"))

    def _fall_back(
        self, b: np.ndarray, reason: int, its: int, mumps_failed: str = "", expected: bool = False
    ) -> np.ndarray:
        """A direct factorization of this matrix (serial); ``mumps_failed``: why MUMPS could not factor it;
        ``expected``: ``"auto"``'s trial of the AMG ended (out of time, or an indefinite tangent: said at
        the info level)."""
        self._solver.stale = True
        STATISTICS["fallbacks"] += 1
        if self._solver.comm.distributed:
            n = self.shape[0]
            if mumps_failed:
                raise LinearSolverError(
                    f"MUMPS could not factor this {n}x{n} matrix ({mumps_failed}), and a distributed run has no "
                    "other solver to fall back on: run on one process (Pardiso), on more processes (less memory "
                    'each), or give MUMPS more workspace (PETSC_OPTIONS="-contopt_mat_mumps_icntl_14 50")'
                )
            raise LinearSolverError(
                f"{self.info['method']} did not converge on this {n}x{n} matrix (PETSc "
                f"reason {reason} after {its} iterations), and a distributed run has no other solver to fall back "
                "on: raise LinearSolverOptions.krylov_max_iter, or run on one process"
            )
        if not mumps_failed:
            logger.log(
                logging.INFO if expected else logging.WARNING,
                "%s did not converge on this %dx%d matrix (reason %d, %d iterations%s); solving it with a direct "
                "factorization",
                self.info["method"], *self.shape, reason, its, "; auto's trial ends" if expected else "",
            )  # fmt: skip
        clock = time.perf_counter()
        self._fallback = self._direct()
        if self._trial is not None:
            self._trial.record_direct(time.perf_counter() - clock)
        self.info["fallback_from"] = "petsc"
        return self._fallback.solve(b)

    def _krylov(
        self, b: np.ndarray, rtol: float, gmres: bool, max_it: int | None = None
    ) -> tuple[np.ndarray, int, int]:
        s = self._solver
        ksp = s.ksp
        if s.stale:
            with timed(self.info, "setup_seconds"):
                s.rebuild(self._PETSc)
                STATISTICS["setups"] += 1
                STATISTICS["factorizations"] += int(s.factored)
        if max_it is None:
            max_it = min(self._opts.krylov_max_iter, FACTOR_MAX_ITER) if s.factored else self._opts.krylov_max_iter
        kind = s.ksp_type(gmres)
        ksp.setType(kind)
        ksp.setTolerances(rtol=rtol, atol=0.0, max_it=max_it)
        # GMRES (the retry on an indefinite tangent, with a factorization, or on an unsymmetric
        # matrix) is cut short when its rate says it will fail: what follows a failure (a switch,
        # a new factor) is then cheaper. BiCGStab's residual is not monotone: it runs to max_it.
        s.give_up_within = max_it if kind == "gmres" else 0
        bv, xv = s.A.createVecs()
        lo, hi = s.A.getOwnershipRange()
        full = np.zeros(s.A.getSize()[0])
        full[s.free] = b  # replicated on every rank; each sets the rows it owns
        bv.getArray()[:] = full[lo:hi]
        if self.x0 is None:
            xv.set(0.0)
        else:  # the relative tolerance stays ||b||'s (PETSc's default test)
            full[:] = 0.0
            full[s.free] = self.x0
            xv.getArray()[:] = full[lo:hi]
        ksp.setInitialGuessNonzero(self.x0 is not None)
        ksp.solve(bv, xv)
        its, reason = int(ksp.getIterationNumber()), int(ksp.getConvergedReason())
        local = xv.getArray(readonly=True)
        if isinstance(s.comm, MPIComm):  # the rows are split in rank order
            full = np.concatenate(s.comm.mpi.allgather(np.array(local)))
        else:
            full = local
        x = full[s.free].copy()
        bv.destroy()
        xv.destroy()
        STATISTICS["solves"] += 1
        STATISTICS["iterations"] += its
        self.info["iterations"].append(its)
        if reason > 0 and self.x0 is None:  # from a guess, the iterations say little of the preconditioner
            rate = its / max(1.0, -np.log10(rtol))
            if s.setup_rate < 0:
                s.setup_rate = rate
            s.last_rate, s.last_its = rate, its
        return x, reason, its

    def _release(self) -> None:
        if self._trial is not None:
            self._trial.record_amg(self._spent, failed=self._fallback is not None)
        if self._fallback is not None:
            self._fallback.free()
        s = self._solver
        s.busy = False
        if self._opts.preconditioner_reuse and s.setup_rate >= 0:
            grown = s.last_rate > self._opts.reuse_growth * max(s.setup_rate, 0.1)
            if s.factored:  # an iteration is two triangular solves, a new factor costs many: keep it longer
                grown = s.last_its > FACTOR_REFACTOR_ITER
            s.stale = s.stale or grown
        else:
            s.stale = True
        self._K = None
        if self._trial is not None and not self._trial.wants_amg and s in _KEPT:
            # "auto" left these dofs to the factor: the operator and the AMG hierarchy would only
            # hold memory (1.2 GB on the paper-size sabot)
            _KEPT.remove(s)
            s.destroy()


def factor(
    K: sp.csr_matrix,
    rows: np.ndarray,
    opts: LinearSolverOptions,
    geometry: Geometry | None,
    direct: Callable[[], Factor],
    trial: Choice | None = None,
) -> Factor:
    """A :class:`PetscSolve` of ``K`` (free x free) whose rows are the dofs ``geometry.free``;
    ``trial``: ``"auto"``'s record of the AMG on these dofs (:mod:`contopt.solve.linear.choice`).

    ``geometry`` None: every row a dof of its own and no near-null space (AMG then knows nothing
    of rigid-body modes and needs many more iterations on elasticity). ``direct()`` factors ``K``
    when the Krylov solver cannot solve with it.
    """
    start = time.perf_counter()
    PETSc = load()
    if geometry is None:
        n = K.shape[0]
        geometry = Geometry(points=np.zeros((-(-n // 3), 3)), free=np.arange(n, dtype=np.int64))
    if geometry.free.size != K.shape[0] or geometry.n_dofs < K.shape[0]:
        raise Unsuitable(f"the geometry describes {geometry.free.size} rows, the matrix has {K.shape[0]}")
    comm = geometry.comm
    # creating a matrix is collective: every rank must take the same branch
    solver = next((s for s in _KEPT if s.same_dofs(geometry.free, opts.symmetric)), None)
    if not comm.all(solver is not None):
        solver = None
    if solver is None:
        for idle in [s for s in _KEPT if not s.busy]:
            _KEPT.remove(idle)
            idle.destroy()
        solver = _new_solver(PETSc, geometry, opts)
        _KEPT.append(solver)
    if solver.prefer_direct and opts.backend == "auto" and not comm.distributed:
        STATISTICS["fallbacks"] += 1
        logger.info("the AMG failed on these dofs before: factoring this %dx%d matrix directly", *K.shape)
        return direct()
    if not comm.all(solver.A is not None and solver.same_pattern(K)):
        solver.new_operator(PETSc, K, rows, geometry)
        solver.ksp.setOperators(solver.A, solver.P if solver.P is not None else solver.A)
    else:
        STATISTICS["reused"] += 1
    solver.unsymmetric_krylov = opts.unsymmetric_krylov  # this call's choice, also for a kept solver
    if opts.preconditioner == "mumps" and not solver.factored:
        solver.use_factorization(PETSc)
    if not opts.preconditioner_reuse or solver.P is None:
        solver.stale = True
    solver.A.setValuesCOO(_values(K, solver.n_prescribed), addv=PETSc.InsertMode.INSERT_VALUES)
    solver.A.assemble()
    solver.geometry = geometry
    return PetscSolve(PETSc, solver, K, opts, direct, trial, time.perf_counter() - start)


def describe() -> str:
    """One line: the PETSc version and what it was built with (for ``contopt info``)."""
    PETSc = load()
    major, minor, patch = PETSc.Sys.getVersion()
    have = [name for name in ("mumps", "hypre", "superlu_dist") if PETSc.Sys.hasExternalPackage(name)]
    return f"PETSc {major}.{minor}.{patch} (GAMG; with {', '.join(have) or 'no external packages'})"
