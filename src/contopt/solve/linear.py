"""Sparse direct solvers for (symmetric, possibly indefinite) stiffness matrices.

One entry point, :func:`factorize`, returns a factorization object that solves
``K x = b`` for one or many right-hand sides and reuses the factor::

    factor = factorize(K, "auto")        # or LinearSolverOptions(backend=...)
    x = factor.solve(b)                  # b: (n,) or (n, k)
    factor.backend, factor.info, factor.seconds
    factor.free()                        # also done on garbage collection

Backends, in the order ``"auto"`` tries them (fastest first, measured below):

``pardiso``  Intel MKL Pardiso through pypardiso. Symmetric matrices use
             ``mtype=-2`` (real symmetric indefinite, LDL^T with Bunch-Kaufman
             pivoting and pivot perturbation) on the upper triangle, so it
             handles definite and indefinite tangents alike and reports the
             inertia.
``cholmod``  CHOLMOD supernodal Cholesky (scikit-sparse, optional). Only for
             SPD matrices: on an indefinite one it falls back (to pardiso when
             available, else to CHOLMOD's unpivoted simplicial LDL^T, checked by
             a residual, else to scipy).
``scipy``    SuperLU (``scipy.sparse.linalg.splu``): always there, partial
             pivoting, but much slower on 3D models (measured ~3x at 4k dofs,
             12-13x at 26k dofs, and the gap grows with size).

A singular matrix (empty row, unsupported rigid body) raises
:class:`contopt.errors.LinearSolverError`; it never segfaults and never returns
NaN silently.

Measured on the development box (2-core Xeon VM, MKL 2026.2 via pypardiso
0.4.7, Debian SuiteSparse 5 + OpenBLAS-pthread via scikit-sparse 0.4.16,
scipy 1.17), 3D Q1 elasticity on an n^3 cube clamped on one face; time of
``factorize`` (input checks included, best of 2) relative to the default
pardiso (mtype -2 with scaling + matching); the command runs in about 35 s::

    .venv/bin/python benchmarks/linear_solvers.py --out bench-out/linear.json --sizes 10 16 20 24 --scipy-max-dofs 30000

     n   dofs    nnz(K)  pardiso      pardiso     pardiso   cholmod  scipy
                         (default)    no scaling  mtype 11
    10   3630    242k    1 (0.035 s)  0.84        1.08      0.91     2.7
    16  13872    994k    1 (0.189 s)  0.9-1.3     1.50      1.46     7.1
    20  26460    1.94M   1 (0.497 s)  0.97        1.35      1.29     11.7
    24  45000    3.36M   1 (1.07 s)   0.92        1.48      1.41     (skipped)

Pardiso was ahead at n >= 16 in all three runs on a quiet box; in two runs
disturbed by another process cholmod was ahead at some sizes (Pardiso's
OpenMP threads lose up to 2x when another process takes a core). One solve costs 2-3 % of a factorization (pardiso 11 ms,
cholmod 12 ms at n = 20); pypardiso's own ``solve(A, b)`` after
``factorize(A)`` takes 3.5-4x as long as ours (16 vs 4 ms at n = 16, 69 vs
19 ms at n = 24) because it compares A with the stored matrix and rebuilds
1-based index arrays on every call. mtype -2 stores half the factor of
mtype 11 (14.7M vs 28.3M entries at n = 20). Below ~5000 dofs all backends
take a few ms and cholmod is marginally ahead; that does not matter.
Hence ``auto`` = pardiso (mtype -2) > cholmod > scipy.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import time
import weakref
from dataclasses import dataclass, replace
from typing import Any, Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from contopt.errors import ConfigError, LinearSolverError

logger = logging.getLogger(__name__)

#: Backends in order of preference for ``backend="auto"`` (see module docstring).
BACKENDS: tuple[str, ...] = ("pardiso", "cholmod", "scipy")
_BACKEND_CHOICES = ("auto",) + BACKENDS
_PARDISO_MATRIX_TYPES = {"symmetric_indefinite": -2, "general": 11}
_SINGULAR_CHECKS = ("auto", "always", "never")
_PARDISO_SCALINGS = ("always", "retry")

_SINGULAR_HINT = (
    "Likely cause: a body or direction without support: check Dirichlet "
    "conditions / contact (every body needs its 6 rigid-body modes removed by "
    "supports or active contact), a load at a limit/bifurcation point "
    "(reduce the load step), or an extreme stiffness contrast (void E_min/E "
    "below ~1e-10)."
)
_INSTALL_HINT = (
    "Install a fast sparse solver: `pip install pypardiso` (MKL Pardiso, "
    "fastest) or `pip install scikit-sparse` (CHOLMOD; needs libsuitesparse-dev)."
)

#: A Cholesky pivot ratio min(D)/max(D) below this makes the ``"auto"``
#: singularity check run its probe solve. Measured: floating bodies 1e-14..2e-13
#: (when LL^T does not refuse them outright), sound meshes 1e-4..1e-1, SIMP voids
#: 1e-10 (E_min = 1e-9 E) and 1e-13 (1e-12 E): the pivots alone cannot tell, the
#: probe (one extra solve, ~2.5 % of the factorization) can.
_PIVOT_RATIO_PROBE = 1e-8


# --------------------------------------------------------------------------- options


@dataclass(frozen=True)
class LinearSolverOptions:
    """How :func:`factorize` factors a stiffness matrix.

    Attributes
    ----------
    backend : ``"auto"`` (fastest available), ``"pardiso"``, ``"cholmod"`` or
        ``"scipy"``.
    symmetric : the matrix is symmetric (stiffness matrices always are). Only the
        upper (pardiso) or lower (cholmod) triangle is then read. ``False``
        excludes cholmod and makes pardiso use ``mtype=11``.
    pardiso_matrix_type : ``"symmetric_indefinite"`` (mtype -2, upper triangle,
        LDL^T; the measured faster one) or ``"general"`` (mtype 11, full
        matrix, LU). Ignored unless ``symmetric``; non-symmetric is always 11.
    pardiso_scaling : ``"always"`` factor with Pardiso's symmetric scaling and
        weighted matching (iparm 11 and 13), or ``"retry"`` only refactor with
        them when pivots were perturbed and a probe solve is inaccurate. Without
        them a high-contrast matrix (SIMP voids with E_min = 1e-9 E) has
        pivots below Pardiso's 1e-8 perturbation threshold and the plain
        factor is wrong (measured: 59 perturbed pivots, residual 0.17). They
        cost ~10 % on well-scaled matrices, a retry costs a second
        factorization; hence ``"always"``.
    fallback : on a matrix the chosen backend cannot factor try the others
        instead of raising (cholmod on an indefinite matrix -> pardiso, else
        CHOLMOD LDL^T, else scipy; pardiso defeated by extreme stiffness
        contrast -> cholmod); said in the log (warning) and in
        ``factor.info["fallback_from"]``. ``"auto"`` always falls back.
    singular_check : ``"auto"`` runs one probe solve with a fixed random
        right-hand side only when the factorization hints at singularity
        (perturbed pardiso pivots, tiny Cholesky pivots, unpivoted LDL^T,
        SuperLU), ``"always"`` after every factorization, ``"never"`` skips it
        (solutions are still checked for NaN/inf).
    singular_rtol : the probe's ``||K x - b|| / ||b||`` above which the factor is
        not trusted (see ``_probe`` for the measured range of both sides).
    check_symmetry : verify ``K == K.T`` (one O(nnz) transpose) when
        ``symmetric``; off by default because assemblers build symmetric
        matrices by construction.
    pardiso_reuse : keep a freed Pardiso factor's analysis (fill-reducing
        ordering, symbolic factorization, scaling) and reuse it for the next
        matrix with the same sparsity pattern, which then costs only the
        numeric factorization. Newton iterations, load steps, the adjoint and
        every design of an optimization share one pattern (without contact, or
        while the contact pairs stay). Measured on 3D elasticity: the analysis is
        55-68 % of a factorization (6k dofs: 0.094 s of 0.138 s; 26k dofs:
        0.595 s of 1.09 s). One freed factor is kept (its memory too).
    """

    backend: str = "auto"
    symmetric: bool = True
    pardiso_matrix_type: str = "symmetric_indefinite"
    pardiso_scaling: str = "always"
    fallback: bool = True
    singular_check: str = "auto"
    singular_rtol: float = 1e-4
    check_symmetry: bool = False
    pardiso_reuse: bool = True

    def __post_init__(self):
        _check_choice("backend", self.backend, _BACKEND_CHOICES)
        _check_choice("pardiso_matrix_type", self.pardiso_matrix_type,
                      tuple(_PARDISO_MATRIX_TYPES))
        _check_choice("singular_check", self.singular_check, _SINGULAR_CHECKS)
        _check_choice("pardiso_scaling", self.pardiso_scaling, _PARDISO_SCALINGS)
        for key in ("symmetric", "fallback", "check_symmetry", "pardiso_reuse"):
            if not isinstance(getattr(self, key), (bool, np.bool_)):
                raise ConfigError(f"LinearSolverOptions.{key} must be True or False, "
                                  f"got {getattr(self, key)!r}")
        rtol = self.singular_rtol
        if not (isinstance(rtol, (int, float)) and 0.0 < float(rtol) < 1.0):
            raise ConfigError(f"LinearSolverOptions.singular_rtol must be a number in (0, 1), "
                              f"got {rtol!r}")
        if self.backend == "cholmod" and not self.symmetric:
            raise ConfigError("LinearSolverOptions.backend='cholmod' needs symmetric=True "
                              "(Cholesky); use 'pardiso', 'scipy' or 'auto' for a "
                              "non-symmetric matrix")


def _check_choice(key: str, value: Any, allowed: tuple[str, ...]) -> None:
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(f"LinearSolverOptions.{key}={value!r} is not one of "
                          + ", ".join(repr(a) for a in allowed))


# --------------------------------------------------------------------------- backends


@functools.lru_cache(maxsize=None)
def _pardiso_library():
    """The MKL ``pardiso`` ctypes function, loaded once.

    Why not one ``PyPardisoSolver()`` per factor: its constructor runs
    ``ctypes.util.find_library`` (subprocesses, ~0.1 s), more than a whole
    factorization of a small model. Each factor still owns its own Pardiso
    handle (``pt``) and parameters, so factors never share memory or state.
    """
    from pypardiso import PyPardisoSolver

    return PyPardisoSolver()._mkl_pardiso


@functools.lru_cache(maxsize=None)
def _is_available(name: str) -> bool:
    try:
        if name == "pardiso":
            _pardiso_library()
        elif name == "cholmod":
            import sksparse.cholmod  # noqa: F401
        elif name != "scipy":
            return False
    except Exception as exc:  # ImportError, or OSError when mkl_rt is missing
        logger.debug("linear-solver backend %s unavailable: %s", name, exc)
        return False
    return True


def available_backends() -> list[str]:
    """Installed backends, fastest first (``scipy`` is always last and always there)."""
    return [name for name in BACKENDS if _is_available(name)]


# --------------------------------------------------------------------------- factor objects


@runtime_checkable
class Factorization(Protocol):
    """What :func:`factorize` returns.

    Attributes
    ----------
    backend : the backend that produced the factor (after any fallback).
    info : dict with at least ``method`` (str), ``indefinite`` (bool, or None
        when the backend cannot tell), ``negative_pivots`` and
        ``perturbed_pivots`` (int or None), ``fallback_from`` (None, or the
        backend/method that failed first), ``fallback_reason``,
        ``probe_residual`` (float or None) and ``attempts`` (list of
        ``(method, reason)`` of failed attempts).
    seconds : wall time of :func:`factorize` (checks, fallbacks and probe included).
    shape : (n, n)
    """

    backend: str
    info: dict
    seconds: float
    shape: tuple[int, int]

    def solve(self, b: np.ndarray) -> np.ndarray: ...

    def free(self) -> None: ...


class _Factor:
    """Shared shape/finite checks around a backend's ``_solve``."""

    backend = ""

    def __init__(self, n: int, method: str):
        self.shape = (n, n)
        self.seconds = float("nan")
        self.info: dict[str, Any] = {
            "method": method, "indefinite": None, "negative_pivots": None,
            "perturbed_pivots": None, "fallback_from": None, "fallback_reason": None,
            "probe_residual": None, "attempts": [],
        }
        self._freed = False

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``K x = b``; b of shape (n,) or (n, k), x of the same shape (float64)."""
        if self._freed:
            raise LinearSolverError("this factorization was freed; factorize the matrix again")
        b = np.asarray(b)
        if b.ndim not in (1, 2) or b.shape[0] != self.shape[0]:
            raise ValueError(f"right-hand side has shape {b.shape}, expected "
                             f"({self.shape[0]},) or ({self.shape[0]}, k)")
        if np.iscomplexobj(b):
            raise TypeError("complex right-hand sides are not supported (float64 only)")
        b = b.astype(np.float64, copy=False)
        if b.ndim == 2 and b.shape[1] == 0:
            return np.zeros(b.shape)
        x = self._solve(b)
        # O(n k): cheap next to the triangular solves, and the last line of
        # defence against a silent NaN answer.
        if not np.isfinite(x).all():
            if not np.isfinite(b).all():
                raise LinearSolverError("the right-hand side contains NaN or inf")
            raise LinearSolverError(
                f"{self.backend} returned a non-finite solution: the stiffness matrix "
                f"is singular or numerically singular. {_SINGULAR_HINT}")
        return x

    def _solve(self, b: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def free(self) -> None:
        """Release the factor's memory now (idempotent); later solves raise."""
        self._freed = True
        self._release()

    def _release(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()

    def __repr__(self):
        state = "freed" if self._freed else f"{self.seconds:.3g} s"
        return (f"<{type(self).__name__} backend={self.backend!r} n={self.shape[0]} "
                f"method={self.info['method']!r} {state}>")


def _pardiso_call(fn, pt, iparm, mtype, phase, n, a, ia, ja, nrhs, b, x) -> int:
    perm = np.zeros(1, dtype=np.int32)
    error = ctypes.c_int32(0)
    i32p = ctypes.POINTER(ctypes.c_int32)
    f64p = ctypes.POINTER(ctypes.c_double)
    fn(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
       ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
       ctypes.byref(ctypes.c_int32(mtype)), ctypes.byref(ctypes.c_int32(phase)),
       ctypes.byref(ctypes.c_int32(n)),
       a.ctypes.data_as(f64p), ia.ctypes.data_as(i32p), ja.ctypes.data_as(i32p),
       perm.ctypes.data_as(i32p), ctypes.byref(ctypes.c_int32(nrhs)),
       iparm.ctypes.data_as(i32p), ctypes.byref(ctypes.c_int32(0)),
       b.ctypes.data_as(f64p), x.ctypes.data_as(f64p), ctypes.byref(error))
    return int(error.value)


def _pardiso_release(fn, pt, iparm, mtype, n, a, ia, ja) -> None:
    dummy = np.zeros(1)
    try:
        _pardiso_call(fn, pt, iparm, mtype, -1, n, a, ia, ja, 1, dummy, dummy)
    except Exception:  # never raise from a finalizer
        pass


_PARDISO_ERRORS = {
    -1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
    -4: "zero pivot, numerical factorization or iterative refinement problem",
    -5: "unclassified (internal) error", -6: "reordering failed",
    -7: "diagonal matrix is singular", -8: "32-bit integer overflow problem",
    -9: "not enough memory for out-of-core", -10: "error opening OOC files",
    -11: "read/write error with OOC files", -12: "pardiso_64 called from 32-bit library",
}


class _PardisoHandle:
    """One Pardiso instance (``pt``) with its matrix arrays: analysis and numeric factor live here.

    A freed factor may hand its handle to :data:`_PARDISO_POOL`; the next matrix
    with the same pattern then refactors with phase 22 (numeric only).
    """

    def __init__(self, n: int, mtype: int, matching: bool, a, ia, ja):
        self.n, self.mtype, self.matching = n, mtype, matching
        self.a = np.ascontiguousarray(a, dtype=np.float64)
        self.ia = np.ascontiguousarray(ia, dtype=np.int32)
        self.ja = np.ascontiguousarray(ja, dtype=np.int32)
        self.fn = _pardiso_library()
        self.pt = np.zeros(64, dtype=np.int64)
        iparm = np.zeros(64, dtype=np.int32)
        # 1-based indices as in the MKL manual: iparm(k) is iparm[k-1].
        iparm[0] = 1                       # (1) use the values below, not defaults
        iparm[1] = 2                       # (2) METIS nested-dissection ordering
        iparm[7] = 0                       # (8) auto: 2 refinement steps if pivots were perturbed
        # (10) perturb pivots < 10^-x ||A||. Not 13 for mtype -2 as well: then
        # rigid-body pivots of larger free meshes escape perturbation (measured:
        # 0 of 6 perturbed at n = 12) and singularity would go unnoticed.
        iparm[9] = 8 if mtype == -2 else 13
        iparm[10] = 1 if matching else 0   # (11) scaling  } see LinearSolverOptions.
        iparm[12] = 1 if matching else 0   # (13) matching } pardiso_scaling
        iparm[17] = -1                     # (18) report nnz of the factor
        iparm[20] = 1                      # (21) Bunch-Kaufman 1x1 and 2x2 pivots
        iparm[34] = 1                      # (35) zero-based indexing
        self.iparm = iparm
        self.analysed = False
        self.finalizer = weakref.finalize(self, _pardiso_release, self.fn, self.pt, iparm,
                                          mtype, n, self.a, self.ia, self.ja)
        # Releasing MKL memory at interpreter exit is pointless and can crash.
        self.finalizer.atexit = False

    def matches(self, mtype: int, matching: bool, ia: np.ndarray, ja: np.ndarray) -> bool:
        return (self.analysed and self.mtype == mtype and self.matching == matching
                and self.ia.shape == ia.shape and self.ja.shape == ja.shape
                and np.array_equal(self.ia, ia) and np.array_equal(self.ja, ja))

    def call(self, phase: int, nrhs: int = 1, b=None, x=None) -> int:
        dummy = np.zeros(1)
        return _pardiso_call(self.fn, self.pt, self.iparm, self.mtype, phase, self.n, self.a, self.ia,
                             self.ja, nrhs, dummy if b is None else b, dummy if x is None else x)

    def release(self) -> None:
        self.finalizer()


#: freed Pardiso handles whose analysis the next matrix of the same pattern reuses (most recent last)
_PARDISO_POOL: list = []
PARDISO_POOL_SIZE = 1


def _take_pooled(mtype: int, matching: bool, ia: np.ndarray, ja: np.ndarray) -> _PardisoHandle | None:
    for i in range(len(_PARDISO_POOL) - 1, -1, -1):
        if _PARDISO_POOL[i].matches(mtype, matching, ia, ja):
            return _PARDISO_POOL.pop(i)
    return None


def _pool(handle: _PardisoHandle) -> None:
    _PARDISO_POOL.append(handle)
    while len(_PARDISO_POOL) > PARDISO_POOL_SIZE:
        _PARDISO_POOL.pop(0).release()


def release_pardiso_pool() -> None:
    """Free the Pardiso analyses kept for reuse (their memory returns to the system)."""
    while _PARDISO_POOL:
        _PARDISO_POOL.pop().release()


class _PardisoFactor(_Factor):
    backend = "pardiso"

    def __init__(self, K: sp.csr_matrix, rows: np.ndarray, mtype: int, matching: bool, reuse: bool = False):
        n = K.shape[0]
        kind = "LDL^T Bunch-Kaufman" if mtype == -2 else "LU"
        super().__init__(n, f"pardiso mtype={mtype} ({kind}"
                         + (", scaling+matching)" if matching else ")"))
        if mtype == -2:
            a, ia, ja = _upper_with_diagonal(K, rows)
        else:
            a, ia, ja = K.data, K.indptr, K.indices
        if len(a) >= np.iinfo(np.int32).max:
            raise LinearSolverError(f"matrix has {len(a)} stored entries, too many for "
                                    "32-bit Pardiso; use backend='cholmod'")
        # Own, 0-based, int32 copies: pypardiso's own solve() re-creates the
        # 1-based index arrays and compares the whole matrix on every call.
        ia32, ja32 = np.asarray(ia, dtype=np.int32), np.asarray(ja, dtype=np.int32)
        handle = _take_pooled(mtype, matching, ia32, ja32) if reuse else None
        if handle is not None:
            handle.a[:] = a
            phase = 22  # numeric factorization with the pooled handle's ordering and symbolic factor
        else:
            handle = _PardisoHandle(n, mtype, matching, a, ia32, ja32)
            phase = 12
        self._handle, self._reuse = handle, reuse
        err = handle.call(phase)
        if err != 0:
            handle.release()
            raise LinearSolverError(f"Pardiso factorization failed with error {err} "
                                    f"({_PARDISO_ERRORS.get(err, 'unknown')})")
        handle.analysed = True
        iparm = handle.iparm
        perturbed = int(iparm[13])
        self.info.update(perturbed_pivots=perturbed, nnz_factor=int(iparm[17]),
                         peak_memory_kb=int(max(iparm[14], iparm[15] + iparm[16])),
                         analysis_reused=phase == 22)
        if mtype == -2:
            neg = int(iparm[22])
            self.info.update(negative_pivots=neg, positive_pivots=int(iparm[21]),
                             indefinite=neg > 0)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        bf = np.asfortranarray(b)
        x = np.empty_like(bf, order="F")
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        err = self._handle.call(33, nrhs, bf, x)
        if err != 0:
            raise LinearSolverError(f"Pardiso solve failed with error {err} "
                                    f"({_PARDISO_ERRORS.get(err, 'unknown')})")
        return x

    def _release(self) -> None:
        handle, self._handle = self._handle, None
        if handle is None:
            return
        if self._reuse and self.info.get("perturbed_pivots") == 0:
            _pool(handle)  # keep the analysis for the next matrix of this pattern
        else:
            handle.release()


class _CholmodFactor(_Factor):
    backend = "cholmod"

    def __init__(self, factor, n: int, method: str):
        super().__init__(n, method)
        self._factor = factor
        D = factor.D()
        dmax = float(np.abs(D).max()) if D.size else 1.0
        self.pivot_ratio = float(np.abs(D).min()) / dmax if dmax > 0 else 0.0
        neg = int(np.count_nonzero(D < 0))
        self.info.update(negative_pivots=neg, indefinite=neg > 0, perturbed_pivots=0,
                         pivot_ratio=self.pivot_ratio)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor.solve_A(b)

    def _release(self) -> None:
        self._factor = None  # scikit-sparse frees the CHOLMOD factor on deallocation


class _ScipyFactor(_Factor):
    backend = "scipy"

    def __init__(self, lu, n: int, method: str):
        super().__init__(n, method)
        self._lu = lu

    def _solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(b)

    def _release(self) -> None:
        self._lu = None


# --------------------------------------------------------------------------- helpers


class _Unsuitable(Exception):
    """This method could not produce a trustworthy factor of this matrix.

    ``singular`` is True when the failure says the matrix is (numerically)
    singular rather than that the method does not fit (Cholesky of an
    indefinite matrix, unpivoted LDL^T).
    """

    def __init__(self, reason: str, singular: bool = False):
        super().__init__(reason)
        self.singular = singular


def _singular_error(detail: str) -> LinearSolverError:
    return LinearSolverError(f"The stiffness matrix is singular or numerically singular: "
                             f"{detail}. {_SINGULAR_HINT}")


def _as_canonical_csr(K) -> sp.csr_matrix:
    if not sp.issparse(K):
        raise TypeError(f"K must be a scipy.sparse matrix, got {type(K).__name__}")
    if K.ndim != 2 or K.shape[0] != K.shape[1]:
        raise ValueError(f"K must be square, got shape {K.shape}")
    if np.iscomplexobj(K.data if hasattr(K, "data") else np.zeros(0)):
        raise TypeError("complex matrices are not supported (float64 only)")
    K = sp.csr_matrix(K)  # no copy when K is already a CSR matrix/array
    if K.dtype != np.float64:
        K = K.astype(np.float64)
    if not K.has_canonical_format:
        # Pardiso silently mis-solves with unsorted indices; duplicates would
        # be dropped by the triangle extraction.
        K = K.copy()
        K.sum_duplicates()
    return K


def _check_matrix(K: sp.csr_matrix, rows: np.ndarray, opts: LinearSolverOptions) -> None:
    """Reject what must never reach a factorization: NaN/inf, empty rows, asymmetry."""
    if not np.isfinite(K.data).all():
        raise LinearSolverError("the stiffness matrix contains NaN or inf entries (check the "
                                "material state: inverted element, J <= 0?)")
    n = K.shape[0]
    stiffened = np.zeros(n, dtype=bool)
    stiffened[rows[K.data != 0]] = True
    if not opts.symmetric:
        # a zero column is the same defect as a zero row, and no longer implied by it
        stiffened &= np.bincount(K.indices[K.data != 0], minlength=n) > 0
    if not stiffened.all():
        # Also what makes Pardiso segfault, so it is checked first.
        bad = np.flatnonzero(~stiffened)
        shown = ", ".join(map(str, bad[:10])) + (", ..." if bad.size > 10 else "")
        raise _singular_error(f"{bad.size} of {n} rows/columns are entirely zero (dofs {shown}; "
                              "a node in no element, or a dof nothing stiffens)")
    if opts.symmetric and opts.check_symmetry:
        diff = abs(K - K.T)
        scale = float(np.abs(K.data).max())
        if diff.nnz and float(diff.max()) > 1e-10 * scale:
            raise LinearSolverError(
                f"the matrix is not symmetric (max |K - K^T| = {float(diff.max()):.3g}, "
                f"max |K| = {scale:.3g}); pass symmetric=False")


def _row_indices(K: sp.csr_matrix) -> np.ndarray:
    return np.repeat(np.arange(K.shape[0], dtype=np.int64), np.diff(K.indptr))


def _upper_with_diagonal(K: sp.csr_matrix, rows: np.ndarray):
    """Upper triangle of canonical CSR ``K`` with every diagonal entry stored.

    Pardiso's symmetric types need the diagonal present even where it is zero
    (the multiplier block of a saddle-point matrix); scipy's own ``triu`` +
    ``diags`` would drop explicit zeros. Returns ``(data, indptr, indices)``.
    """
    n = K.shape[0]
    keep = K.indices >= rows
    r, c, v = rows[keep], K.indices[keep].astype(np.int64), K.data[keep]
    has_diag = np.zeros(n, dtype=bool)
    has_diag[r[c == r]] = True
    if not has_diag.all():
        missing = np.flatnonzero(~has_diag)
        r = np.concatenate([r, missing])
        c = np.concatenate([c, missing])
        v = np.concatenate([v, np.zeros(missing.size)])
        order = np.lexsort((c, r))
        r, c, v = r[order], c[order], v[order]
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=n), out=indptr[1:])
    return v, indptr, c


def _probe(factor: _Factor, K: sp.csr_matrix) -> float:
    """Relative residual ``||K x - b|| / ||b||`` of one solve with a fixed random b.

    Why a random b: it has a component along any (near-)null vector. Measured
    on the test cubes (up to 15k dofs): unsupported bodies give 0.1..10 with
    every backend; regular matrices 1e-15, SIMP voids with E_min = 1e-9 E
    ~5e-9 and with E_min = 1e-12 E up to 4e-5 (cholmod, scipy), hence the
    default ``singular_rtol`` = 1e-4. The backward error is no use here: a
    backward-stable solve of a singular matrix has it at round-off.
    """
    b = np.random.default_rng(20240531).standard_normal(K.shape[0])
    try:
        x = factor._solve(b)
    except LinearSolverError:
        return float("inf")
    if not np.isfinite(x).all():
        return float("inf")
    res = float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))
    factor.info["probe_residual"] = res
    return res


# --------------------------------------------------------------------------- methods


def _factor_pardiso(K, rows, opts, *, matching=None) -> _Factor:
    mtype = _PARDISO_MATRIX_TYPES[opts.pardiso_matrix_type] if opts.symmetric else 11
    if matching is None:
        # (mtype 11 has them on by default in MKL too)
        matching = opts.pardiso_scaling == "always" or mtype == 11
    f = _PardisoFactor(K, rows, mtype, matching, reuse=opts.pardiso_reuse)
    check = opts.singular_check
    if check == "always" or (check == "auto" and f.info["perturbed_pivots"] > 0):
        res = _probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            if f.info["analysis_reused"]:
                # the ordering and scaling were made for other values: analyse this matrix afresh
                logger.info("pardiso: reused analysis gave probe residual %.2g; analysing again", res)
                return _factor_pardiso(K, rows, replace(opts, pardiso_reuse=False), matching=matching)
            if not matching:
                # Perturbed pivots may come from bad scaling (high stiffness
                # contrast) or strong indefiniteness rather than singularity;
                # scaling + matching fixes those, so one retry first.
                logger.info("pardiso: %d perturbed pivots, probe residual %.2g; retrying "
                            "with scaling and weighted matching",
                            f.info["perturbed_pivots"], res)
                return _factor_pardiso(K, rows, opts, matching=True)
            # Singular, or so ill-conditioned that static pivoting fails
            # (measured: SIMP voids with E_min = 1e-12 E); Cholesky, if
            # installed, gets the second word.
            raise _Unsuitable(f"Pardiso perturbed {f.info['perturbed_pivots']} pivot(s) and a "
                              f"test solve has relative residual {res:.2g}", singular=True)
    return f


def _factor_cholmod_llt(K, rows, opts) -> _Factor:
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

    # CSR of a symmetric matrix is its CSC: no copy, and CHOLMOD reads the lower triangle.
    A = sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)
    try:
        fac = cholesky(A, mode="supernodal")
    except CholmodNotPositiveDefiniteError as exc:
        raise _Unsuitable(f"not positive definite ({exc})") from None
    f = _CholmodFactor(fac, K.shape[0], "cholmod supernodal LL^T")
    check = opts.singular_check
    if check == "always" or (check == "auto" and f.pivot_ratio < _PIVOT_RATIO_PROBE):
        res = _probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            # Cholesky is backward stable: a bad residual means singular.
            raise _Unsuitable(f"Cholesky pivot ratio min/max = {f.pivot_ratio:.2g} and a "
                              f"test solve has relative residual {res:.2g}", singular=True)
    return f


def _factor_cholmod_ldlt(K, rows, opts) -> _Factor:
    from sksparse.cholmod import CholmodError, cholesky

    A = sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)
    try:
        fac = cholesky(A, mode="simplicial")
    except CholmodError as exc:  # zero pivot
        raise _Unsuitable(f"zero pivot in LDL^T ({exc})") from None
    f = _CholmodFactor(fac, K.shape[0], "cholmod simplicial LDL^T (no pivoting)")
    if opts.singular_check != "never":
        # Without pivoting the factor may be inaccurate or the matrix
        # singular; it cannot tell which, so a bad probe means "try another".
        res = _probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            raise _Unsuitable(f"unpivoted LDL^T is inaccurate (test residual {res:.2g})")
    return f


_SCIPY_WARNED = False


def _factor_scipy(K, rows, opts) -> _Factor:
    global _SCIPY_WARNED
    from scipy.sparse.linalg import splu

    if not _SCIPY_WARNED:
        _SCIPY_WARNED = True
        logger.warning("Using scipy's SuperLU for sparse factorization: much slower than "
                       "Pardiso/CHOLMOD on 3D models (measured ~3x at 4k dofs, 12-13x at "
                       "26k dofs, and the gap grows with size). %s", _INSTALL_HINT)
    # Symmetric mode (ordering of K + K^T, diagonal pivots preferred, still
    # threshold partial pivoting) measured 1-2x faster than the default COLAMD.
    kw = (dict(permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True))
          if opts.symmetric else {})
    try:
        lu = splu(K.tocsc(), **kw)
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise _Unsuitable(f"SuperLU: {exc}", singular=True) from None
    f = _ScipyFactor(lu, K.shape[0], "scipy SuperLU")
    f.info["nnz_factor"] = int(lu.nnz)
    if opts.singular_check != "never":
        # SuperLU reports no pivot statistics; its factorization is so slow
        # that one probe solve is noise.
        res = _probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            raise _Unsuitable(f"a test solve with SuperLU has relative residual {res:.2g}",
                              singular=True)
    return f


_METHODS = {
    "pardiso": _factor_pardiso,
    "cholmod": _factor_cholmod_llt,
    "cholmod_ldlt": _factor_cholmod_ldlt,
    "scipy": _factor_scipy,
}


def _method_chain(opts: LinearSolverOptions) -> list[str]:
    """Methods to try in order: the chosen backend, then its fallbacks."""
    avail = [b for b in available_backends() if opts.symmetric or b != "cholmod"]
    if opts.backend == "auto":
        first = avail[0]
    else:
        if opts.backend not in avail:
            raise LinearSolverError(
                f"linear-solver backend {opts.backend!r} is not available here (available: "
                f"{', '.join(avail)}). {_INSTALL_HINT} Or use backend='auto'.")
        first = opts.backend
    chain = [first]
    if not (opts.backend == "auto" or opts.fallback):
        return chain
    if first == "cholmod":
        # Cholesky refuses indefinite matrices. Then: pardiso (pivoting, fast)
        # before CHOLMOD's unpivoted simplicial LDL^T (~10x slower than
        # supernodal, measured), before SuperLU.
        chain += [m for m in ("pardiso", "cholmod_ldlt", "scipy")
                  if (m if m != "cholmod_ldlt" else "cholmod") in avail]
    elif first == "pardiso" and "cholmod" in avail:
        chain.append("cholmod")  # for what defeats Pardiso's static pivoting (see there)
    return chain


def _resolve_options(options) -> LinearSolverOptions:
    if options is None:
        return LinearSolverOptions()
    if isinstance(options, str):
        return LinearSolverOptions(backend=options)
    if isinstance(options, LinearSolverOptions):
        return options
    raise ConfigError("linear solver options must be a backend name ("
                      + ", ".join(repr(a) for a in _BACKEND_CHOICES)
                      + f") or LinearSolverOptions, got {type(options).__name__}")


def factorize(K, options: LinearSolverOptions | str | None = None) -> Factorization:
    """Factor the sparse matrix ``K`` (float64, shape (n, n)) for repeated solves.

    Parameters
    ----------
    K : scipy.sparse matrix or array, shape (n, n); symmetric unless
        ``options.symmetric`` is False. CSR avoids a conversion copy.
    options : :class:`LinearSolverOptions`, a backend name, or None (``"auto"``).

    Returns
    -------
    A :class:`Factorization`: ``solve(b)`` for b of shape (n,) or (n, k),
    ``backend``, ``info``, ``seconds``, ``free()``.

    Raises
    ------
    LinearSolverError
        singular matrix (empty row, unsupported rigid-body mode), NaN/inf
        entries, a requested backend that is not installed, or a backend
        failure after all fallbacks.
    ConfigError
        invalid options.
    """
    t0 = time.perf_counter()
    opts = _resolve_options(options)
    K = _as_canonical_csr(K)
    n = K.shape[0]
    if n == 0:
        raise LinearSolverError("empty (0 x 0) stiffness matrix: no free dofs")
    rows = _row_indices(K)
    _check_matrix(K, rows, opts)
    queue = _method_chain(opts)
    attempts: list[tuple[str, str]] = []
    singular = False
    while queue:
        method = queue.pop(0)
        try:
            factor = _METHODS[method](K, rows, opts)
        except _Unsuitable as exc:
            attempts.append((method, str(exc)))
            if exc.singular:
                singular = True
                # Pivoting LU/LDL^T would say the same; only a Cholesky not
                # yet tried can still decide (it may be the SPD extreme case).
                queue = [m for m in queue if m == "cholmod"]
            if queue:
                logger.warning("%s cannot factor this %dx%d matrix (%s); falling back to %s",
                               method, n, n, exc, queue[0])
            continue
        if attempts:
            factor.info["fallback_from"] = attempts[0][0]
            factor.info["fallback_reason"] = attempts[0][1]
            factor.info["attempts"] = attempts
        factor.seconds = time.perf_counter() - t0
        logger.debug("factorized %dx%d (nnz %d) with %s in %.3f s", n, n, K.nnz,
                     factor.info["method"], factor.seconds)
        return factor
    tried = "; ".join(f"{m}: {r}" for m, r in attempts)
    if singular:
        raise _singular_error(tried)
    if opts.backend != "auto" and not opts.fallback:
        raise LinearSolverError(f"{opts.backend} cannot factor this matrix ({tried}); allow "
                                "fallback=True or choose backend='pardiso'/'scipy'")
    raise LinearSolverError(f"no backend could factor the {n}x{n} matrix ({tried})")
