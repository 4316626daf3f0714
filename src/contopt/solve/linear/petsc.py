"""The ``petsc`` backend: conjugate gradients preconditioned with PETSc's smoothed-aggregation AMG.

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
* a solve that does not converge is retried once with a fresh preconditioner and, failing that,
  with GMRES; after that the caller's ``direct`` fallback (a factorization) solves, said in the log.

Options reach PETSc under the prefix ``contopt_``, so ``PETSC_OPTIONS="-contopt_ksp_monitor"``
(or any ``-contopt_pc_gamg_*``) adds to or overrides them.

The binary wheel this uses (``dolfinx-solver-real``, see :mod:`contopt.solve.linear.petsc_install`)
links its own OpenBLAS and MPICH; :func:`load` puts its MPI library in the process and says what
to run when the wheel has not been prepared to live beside the system's OpenBLAS.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from contopt.solve.linear.base import Factor, Geometry, Unsuitable, logger
from contopt.solve.linear.options import LinearSolverOptions

PREFIX = "contopt_"
#: what to run when the wheel is installed but cannot be loaded beside the system's BLAS
PREPARE_HINT = "python -m contopt.solve.linear.petsc_install"
#: iterations and set-ups of this process's iterative solves (benchmarks and tests read them)
STATISTICS = {"setups": 0, "solves": 0, "iterations": 0, "reused": 0, "retries": 0, "fallbacks": 0}


def _preload_mpi() -> None:
    """Load the MPI library that the wheels put in ``<prefix>/lib`` (not on the loader's path)."""
    for path in sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmpi.so.*")), key=len):
        try:
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            return
        except OSError:
            continue


@functools.cache
def load() -> Any:
    """petsc4py's ``PETSc`` module, initialized once (ImportError when PETSc is not usable here)."""
    _preload_mpi()
    try:
        import petsc4py

        # no command line for PETSc (it is contopt's); PETSC_OPTIONS still reaches it
        petsc4py.init([sys.argv[0] if sys.argv else "contopt", "-options_left", "no"])
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
    """A matrix of one sparsity pattern with its Krylov solver and preconditioner, kept for reuse."""

    rows_key: np.ndarray  # (n + 1,) indptr of the free matrix
    cols_key: np.ndarray  # (nnz,) its column indices
    free: np.ndarray  # (n,) the dofs of its rows
    A: Any  # PETSc Mat, n_dofs x n_dofs
    ksp: Any  # PETSc KSP
    n_prescribed: int
    # iterations per decade of residual reduction (Newton asks for different tolerances): of the
    # first solve with the current preconditioner (-1: none yet), and of the last solve
    setup_rate: float = -1.0
    last_rate: float = 0.0
    stale: bool = True  # the preconditioner must be (re)built before the next solve
    busy: bool = False  # a live factor uses it

    def matches(self, K: sp.csr_matrix, free: np.ndarray) -> bool:
        return (
            not self.busy
            and self.rows_key.size == K.indptr.size
            and self.cols_key.size == K.indices.size
            and self.free.size == free.size
            and np.array_equal(self.rows_key, K.indptr)
            and np.array_equal(self.cols_key, K.indices)
            and np.array_equal(self.free, free)
        )

    def destroy(self) -> None:
        self.ksp.destroy()
        self.A.destroy()


#: the kept solver (one: the memory of a second matrix and hierarchy is not worth it)
_KEPT: list[_Solver] = []


def release_kept() -> None:
    """Destroy the kept matrix, solver and preconditioner (frees their memory)."""
    while _KEPT:
        _KEPT.pop().destroy()


def _full_coo(K: sp.csr_matrix, rows: np.ndarray, free: np.ndarray, n_dofs: int):
    """COO rows/cols (PETSc's int type comes later) of K on the full dofs plus the prescribed diagonal."""
    prescribed = np.setdiff1d(np.arange(n_dofs), free)
    r = np.concatenate([free[rows], prescribed])
    c = np.concatenate([free[K.indices], prescribed])
    return r, c, prescribed.size


def _values(K: sp.csr_matrix, n_prescribed: int) -> np.ndarray:
    scale = float(np.abs(K.diagonal()).mean()) or 1.0
    return np.concatenate([K.data, np.full(n_prescribed, scale)])


def _new_solver(PETSc, K: sp.csr_matrix, rows: np.ndarray, geometry: Geometry, opts: LinearSolverOptions) -> _Solver:
    comm = PETSc.COMM_SELF
    n_dofs = geometry.n_dofs
    r, c, n_prescribed = _full_coo(K, rows, geometry.free, n_dofs)
    A = PETSc.Mat().create(comm=comm)
    A.setSizes((n_dofs, n_dofs))
    A.setType("aij")
    A.setBlockSize(3)
    A.setPreallocationCOO(r.astype(PETSc.IntType), c.astype(PETSc.IntType))
    ksp = PETSc.KSP().create(comm=comm)
    ksp.setOptionsPrefix(PREFIX)
    ksp.setOperators(A)
    ksp.setType("cg")
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setInitialGuessNonzero(False)
    ksp.getPC().setType(opts.preconditioner)
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
    return _Solver(
        rows_key=K.indptr.copy(), cols_key=K.indices.copy(), free=geometry.free.copy(), A=A, ksp=ksp,
        n_prescribed=n_prescribed,
    )  # fmt: skip


def _near_null_space(PETSc, geometry: Geometry):
    coords = PETSc.Vec().createWithArray(np.ascontiguousarray(geometry.points, dtype=np.float64).ravel().copy())
    coords.setBlockSize(3)
    space = PETSc.NullSpace().createRigidBody(coords)
    coords.destroy()
    return space


class PetscSolve(Factor):
    """CG + GAMG on one matrix (see the module docstring); ``info['iterations']`` lists every solve's."""

    backend = "petsc"
    iterative = True

    def __init__(self, PETSc, solver: _Solver, K, opts: LinearSolverOptions, direct: Callable[[], Factor]):
        super().__init__(K.shape[0], f"CG + {opts.preconditioner.upper()} (PETSc)")
        self._PETSc, self._solver, self._K, self._opts, self._direct = PETSc, solver, K, opts, direct
        self._fallback: Factor | None = None
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
        for attempt in ("as set", "new preconditioner", "gmres"):
            x, reason, its = self._krylov(b, rtol, gmres=(attempt == "gmres"))
            if reason > 0:
                return x
            STATISTICS["retries"] += 1
            logger.info("PETSc %s did not converge (reason %d, %d iterations); retrying: %s", self.info["method"],
                        reason, its, attempt)  # fmt: skip
            self._solver.stale = True
        STATISTICS["fallbacks"] += 1
        logger.warning(
            "CG + GAMG did not converge on this %dx%d matrix even with a fresh preconditioner and GMRES; "
            "solving it with a direct factorization",
            *self.shape,
        )
        self._fallback = self._direct()
        self.info["fallback_from"] = "petsc"
        return self._fallback.solve(b)

    def _krylov(self, b: np.ndarray, rtol: float, gmres: bool) -> tuple[np.ndarray, int, int]:
        s, PETSc = self._solver, self._PETSc
        ksp = s.ksp
        if s.stale:
            t0 = time.perf_counter()
            ksp.getPC().setReusePreconditioner(False)
            ksp.setOperators(s.A)
            ksp.setUp()
            ksp.getPC().setReusePreconditioner(True)
            STATISTICS["setups"] += 1
            self.info["setup_seconds"] = self.info.get("setup_seconds", 0.0) + time.perf_counter() - t0
            s.setup_rate = -1.0
            s.stale = False
        ksp.setType("gmres" if gmres else "cg")
        ksp.setTolerances(rtol=rtol, atol=0.0, max_it=self._opts.krylov_max_iter)
        bv, xv = s.A.createVecs()
        bv.set(0.0)
        bv.setValues(s.free.astype(PETSc.IntType), b)
        bv.assemble()
        xv.set(0.0)
        ksp.solve(bv, xv)
        its, reason = int(ksp.getIterationNumber()), int(ksp.getConvergedReason())
        x = xv.getArray(readonly=True)[s.free].copy()
        bv.destroy()
        xv.destroy()
        STATISTICS["solves"] += 1
        STATISTICS["iterations"] += its
        self.info["iterations"].append(its)
        if reason > 0:
            rate = its / max(1.0, -np.log10(rtol))
            if s.setup_rate < 0:
                s.setup_rate = rate
            s.last_rate = rate
        return x, reason, its

    def _release(self) -> None:
        if self._fallback is not None:
            self._fallback.free()
        s = self._solver
        s.busy = False
        if self._opts.preconditioner_reuse and s.setup_rate >= 0:
            grown = s.last_rate > self._opts.reuse_growth * max(s.setup_rate, 0.1)
            s.stale = s.stale or grown
        else:
            s.stale = True
        self._K = None


def factor(
    K: sp.csr_matrix,
    rows: np.ndarray,
    opts: LinearSolverOptions,
    geometry: Geometry | None,
    direct: Callable[[], Factor],
) -> Factor:
    """A :class:`PetscSolve` of ``K`` (free x free) whose rows are the dofs ``geometry.free``.

    ``geometry`` None: every row a dof of its own and no near-null space (AMG then knows nothing
    of rigid-body modes and needs many more iterations on elasticity). ``direct()`` factors ``K``
    when the Krylov solver cannot solve with it.
    """
    PETSc = load()
    if geometry is None:
        n = K.shape[0]
        geometry = Geometry(points=np.zeros((-(-n // 3), 3)), free=np.arange(n, dtype=np.int64))
    if geometry.free.size != K.shape[0] or geometry.n_dofs < K.shape[0]:
        raise Unsuitable(f"the geometry describes {geometry.free.size} rows, the matrix has {K.shape[0]}")
    solver = next((s for s in _KEPT if s.matches(K, geometry.free)), None)
    if solver is None:
        for idle in [s for s in _KEPT if not s.busy]:
            _KEPT.remove(idle)
            idle.destroy()
        solver = _new_solver(PETSc, K, rows, geometry, opts)
        _KEPT.append(solver)
    else:
        STATISTICS["reused"] += 1
    if not opts.preconditioner_reuse:
        solver.stale = True
    solver.A.setValuesCOO(_values(K, solver.n_prescribed), addv=PETSc.InsertMode.INSERT_VALUES)
    solver.A.assemble()
    if solver.stale and np.any(geometry.points):
        space = _near_null_space(PETSc, geometry)
        solver.A.setNearNullSpace(space)
        space.destroy()
    return PetscSolve(PETSc, solver, K, opts, direct)


def describe() -> str:
    """One line: the PETSc version and what it was built with (for ``contopt info``)."""
    PETSc = load()
    major, minor, patch = PETSc.Sys.getVersion()
    have = [name for name in ("mumps", "hypre", "superlu_dist") if PETSc.Sys.hasExternalPackage(name)]
    return f"PETSc {major}.{minor}.{patch} (GAMG; with {', '.join(have) or 'no external packages'})"
