"""The ``pardiso`` backend: Intel MKL Pardiso, called through ctypes with the library pypardiso loads.

Symmetric matrices use ``mtype=-2`` (real symmetric indefinite, LDL^T with Bunch-Kaufman
pivoting and pivot perturbation) on the upper triangle, so definite and indefinite tangents
alike are factored and the inertia is reported; non-symmetric ones ``mtype=11`` (LU). A freed
factor keeps its analysis (ordering, symbolic factor, scaling) in a pool of
:data:`PARDISO_POOL_SIZE` handles, and the next matrix of the same pattern only pays the numeric
factorization (``LinearSolverOptions.pardiso_reuse``).
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import site
import sys
import weakref
from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from contopt.errors import LinearSolverError
from contopt.solve.linear.base import Factor, Unsuitable, logger, probe, upper_with_diagonal
from contopt.solve.linear.options import PARDISO_MATRIX_TYPES, LinearSolverOptions

#: where pip's ``mkl`` package puts the runtime (relative to an install prefix)
_MKL_RT_GLOBS = ("lib/libmkl_rt.so*", "lib/libmkl_rt*.dylib", "Library/bin/mkl_rt*.dll")


def _mkl_rt_paths() -> list[str]:
    """Candidate paths of MKL's runtime library: ``$PYPARDISO_MKL_RT``, then the install prefixes."""
    env = os.environ.get("PYPARDISO_MKL_RT")
    found = [env] if env else []
    for prefix in dict.fromkeys(p for p in (sys.prefix, site.USER_BASE) if p):
        for pattern in _MKL_RT_GLOBS:
            found += sorted(glob.glob(os.path.join(prefix, pattern)), key=len)
    return found


@functools.cache
def library():
    """The MKL ``pardiso`` ctypes function, loaded once (ImportError/OSError when missing).

    The runtime is looked up where pip's ``mkl`` package installs it before asking pypardiso:
    importing pypardiso builds a solver at module level, whose library search (``find_library``
    subprocesses and a recursive glob of the prefix) took 0.5 s of every process's first
    factorization (docs/performance.md). Each factor owns its own Pardiso handle (``pt``) and
    parameters, so factors never share memory or state.
    """
    for path in _mkl_rt_paths():
        try:
            return ctypes.CDLL(path).pardiso
        except (OSError, AttributeError):
            continue
    from pypardiso import PyPardisoSolver  # its own search, and its error when MKL is missing

    return PyPardisoSolver()._mkl_pardiso


def _pardiso_call(fn, pt, iparm, mtype, phase, n, a, ia, ja, nrhs, b, x) -> int:
    perm = np.zeros(1, dtype=np.int32)
    error = ctypes.c_int32(0)
    i32p = ctypes.POINTER(ctypes.c_int32)
    f64p = ctypes.POINTER(ctypes.c_double)
    fn(
        pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
        ctypes.byref(ctypes.c_int32(1)),
        ctypes.byref(ctypes.c_int32(1)),
        ctypes.byref(ctypes.c_int32(mtype)),
        ctypes.byref(ctypes.c_int32(phase)),
        ctypes.byref(ctypes.c_int32(n)),
        a.ctypes.data_as(f64p),
        ia.ctypes.data_as(i32p),
        ja.ctypes.data_as(i32p),
        perm.ctypes.data_as(i32p),
        ctypes.byref(ctypes.c_int32(nrhs)),
        iparm.ctypes.data_as(i32p),
        ctypes.byref(ctypes.c_int32(0)),
        b.ctypes.data_as(f64p),
        x.ctypes.data_as(f64p),
        ctypes.byref(error),
    )
    return int(error.value)


def _pardiso_release(fn, pt, iparm, mtype, n, a, ia, ja) -> None:
    dummy = np.zeros(1)
    try:
        _pardiso_call(fn, pt, iparm, mtype, -1, n, a, ia, ja, 1, dummy, dummy)
    except Exception:  # never raise from a finalizer
        pass


_PARDISO_ERRORS = {
    -1: "input inconsistent",
    -2: "not enough memory",
    -3: "reordering problem",
    -4: "zero pivot, numerical factorization or iterative refinement problem",
    -5: "unclassified (internal) error",
    -6: "reordering failed",
    -7: "diagonal matrix is singular",
    -8: "32-bit integer overflow problem",
    -9: "not enough memory for out-of-core",
    -10: "error opening OOC files",
    -11: "read/write error with OOC files",
    -12: "pardiso_64 called from 32-bit library",
}


class _PardisoHandle:
    """One Pardiso instance (``pt``) with its matrix arrays: analysis and numeric factor live here.

    A freed factor may hand its handle to :data:`PARDISO_POOL`; the next matrix
    with the same pattern then refactors with phase 22 (numeric only).
    """

    def __init__(self, n: int, mtype: int, matching: bool, a, ia, ja, single: bool = False):
        self.n, self.mtype, self.matching, self.single = n, mtype, matching, single
        # a single-precision factorization reads and writes float32 values and vectors (iparm 28)
        self.dtype = np.float32 if single else np.float64
        self.a = np.ascontiguousarray(a, dtype=self.dtype)
        self.ia = np.ascontiguousarray(ia, dtype=np.int32)
        self.ja = np.ascontiguousarray(ja, dtype=np.int32)
        self.fn = library()
        self.pt = np.zeros(64, dtype=np.int64)
        iparm = np.zeros(64, dtype=np.int32)
        # 1-based indices as in the MKL manual: iparm(k) is iparm[k-1].
        iparm[0] = 1  # (1) use the values below, not defaults
        iparm[1] = 2  # (2) METIS nested-dissection ordering
        iparm[7] = 0  # (8) auto: 2 refinement steps if pivots were perturbed
        # (10) perturb pivots < 10^-x ||A||. Not 13 for mtype -2 as well: then
        # rigid-body pivots of larger free meshes escape perturbation (measured:
        # 0 of 6 perturbed at n = 12) and singularity would go unnoticed.
        iparm[9] = 8 if mtype == -2 else 13
        iparm[10] = 1 if matching else 0  # (11) scaling  } see LinearSolverOptions.
        iparm[12] = 1 if matching else 0  # (13) matching } pardiso_scaling
        iparm[17] = -1  # (18) report nnz of the factor
        iparm[20] = 1  # (21) Bunch-Kaufman 1x1 and 2x2 pivots
        iparm[27] = 1 if single else 0  # (28) single-precision factor and solves
        iparm[34] = 1  # (35) zero-based indexing
        self.iparm = iparm
        self.analysed = False
        self.finalizer = weakref.finalize(
            self, _pardiso_release, self.fn, self.pt, iparm, mtype, n, self.a, self.ia, self.ja
        )
        # Releasing MKL memory at interpreter exit is pointless and can crash.
        self.finalizer.atexit = False

    def matches(self, mtype: int, matching: bool, ia: np.ndarray, ja: np.ndarray, single: bool = False) -> bool:
        return (
            self.analysed
            and self.mtype == mtype
            and self.matching == matching
            and self.single == single
            and self.ia.shape == ia.shape
            and self.ja.shape == ja.shape
            and np.array_equal(self.ia, ia)
            and np.array_equal(self.ja, ja)
        )

    def call(self, phase: int, nrhs: int = 1, b=None, x=None) -> int:
        dummy = np.zeros(1)
        return _pardiso_call(
            self.fn,
            self.pt,
            self.iparm,
            self.mtype,
            phase,
            self.n,
            self.a,
            self.ia,
            self.ja,
            nrhs,
            dummy if b is None else b,
            dummy if x is None else x,
        )

    def release(self) -> None:
        self.finalizer()


#: freed Pardiso handles whose analysis the next matrix of the same pattern reuses (most recent last)
PARDISO_POOL: list = []
#: how many freed analyses are kept; to change it, set it here (``contopt.solve.linear.pardiso``):
#: ``contopt.solve.linear.PARDISO_POOL_SIZE`` is a copy
PARDISO_POOL_SIZE = 1


def _take_pooled(mtype: int, matching: bool, ia: np.ndarray, ja: np.ndarray, single: bool) -> _PardisoHandle | None:
    for i in range(len(PARDISO_POOL) - 1, -1, -1):
        if PARDISO_POOL[i].matches(mtype, matching, ia, ja, single):
            return PARDISO_POOL.pop(i)
    return None


def _pool(handle: _PardisoHandle) -> None:
    PARDISO_POOL.append(handle)
    _trim_pool(PARDISO_POOL_SIZE)


def _trim_pool(size: int) -> None:
    """Release the oldest pooled handles until at most ``size`` remain."""
    while len(PARDISO_POOL) > max(size, 0):
        PARDISO_POOL.pop(0).release()


def release_pardiso_pool() -> None:
    """Free the Pardiso analyses kept for reuse (their memory returns to the system)."""
    while PARDISO_POOL:
        PARDISO_POOL.pop().release()


class _PardisoFactor(Factor):
    backend = "pardiso"

    def __init__(
        self, K: sp.csr_matrix, rows: np.ndarray, mtype: int, matching: bool, reuse: bool = False, single: bool = False
    ):
        n = K.shape[0]
        kind = "LDL^T Bunch-Kaufman" if mtype == -2 else "LU"
        kind += ", single precision" if single else ""
        super().__init__(n, f"pardiso mtype={mtype} ({kind}" + (", scaling+matching)" if matching else ")"))
        # its solves are a float32 factor's: a preconditioner for GMRES (factorize wraps it), not exact
        self.approximate = single
        if mtype == -2:
            a, ia, ja = upper_with_diagonal(K, rows)
        else:
            a, ia, ja = K.data, K.indptr, K.indices
        if len(a) >= np.iinfo(np.int32).max:
            raise LinearSolverError(
                f"matrix has {len(a)} stored entries, too many for 32-bit Pardiso; use backend='cholmod'"
            )
        # Own, 0-based, int32 copies: pypardiso's own solve() re-creates the
        # 1-based index arrays and compares the whole matrix on every call.
        ia32, ja32 = np.asarray(ia, dtype=np.int32), np.asarray(ja, dtype=np.int32)
        handle = _take_pooled(mtype, matching, ia32, ja32, single) if reuse else None
        if handle is not None:
            handle.a[:] = a
            phase = 22  # numeric factorization with the pooled handle's ordering and symbolic factor
        else:
            if reuse:
                # drop what pooling this one would evict before its analysis, not after: the pooled
                # analyses (ordering, symbolic factor, a copy of the matrix) would coexist with it
                _trim_pool(PARDISO_POOL_SIZE - 1)
            handle = _PardisoHandle(n, mtype, matching, a, ia32, ja32, single)
            phase = 12
        self._handle: _PardisoHandle | None = handle  # None once released
        self._reuse = reuse
        err = handle.call(phase)
        if err != 0:
            handle.release()
            raise LinearSolverError(
                f"Pardiso factorization failed with error {err} ({_PARDISO_ERRORS.get(err, 'unknown')})"
            )
        handle.analysed = True
        iparm = handle.iparm
        perturbed = int(iparm[13])
        self.info.update(
            perturbed_pivots=perturbed,
            nnz_factor=int(iparm[17]),
            peak_memory_kb=int(max(iparm[14], iparm[15] + iparm[16])),
            analysis_reused=phase == 22,
        )
        if mtype == -2:
            neg = int(iparm[22])
            self.info.update(negative_pivots=neg, positive_pivots=int(iparm[21]), indefinite=neg > 0)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        assert self._handle is not None  # Factor.solve refuses a freed factor
        bf = np.asfortranarray(b, dtype=self._handle.dtype)
        x = np.empty_like(bf, order="F")
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        err = self._handle.call(33, nrhs, bf, x)
        if err != 0:
            raise LinearSolverError(f"Pardiso solve failed with error {err} ({_PARDISO_ERRORS.get(err, 'unknown')})")
        return x.astype(np.float64, copy=False)

    def _release(self) -> None:
        handle, self._handle = self._handle, None
        if handle is None:
            return
        if self._reuse and self.info.get("perturbed_pivots") == 0:
            # keep the analysis for the next matrix of this pattern, not the numeric factor (phase
            # 0): the largest part by far, and phase 22 makes a new one
            handle.call(0)
            _pool(handle)
        else:
            handle.release()


def factor(K: sp.csr_matrix, rows: np.ndarray, opts: LinearSolverOptions, *, matching=None) -> Factor:
    """Pardiso's factor of ``K``, refactored with scaling and matching or a fresh analysis when
    perturbed pivots and a bad probe say the first try is wrong (:class:`Unsuitable` when that
    does not help either)."""
    mtype = PARDISO_MATRIX_TYPES[opts.pardiso_matrix_type] if opts.symmetric else 11
    if matching is None:
        # (mtype 11 has them on by default in MKL too)
        matching = opts.pardiso_scaling == "always" or mtype == 11
    single = opts.factor_precision == "single"
    f = _PardisoFactor(K, rows, mtype, matching, reuse=opts.pardiso_reuse, single=single)
    check = opts.singular_check
    if single and (check == "always" or f.info["perturbed_pivots"] > 0):
        # a float32 factor's probe residual says nothing of singularity (it is 1e-2 on a sound
        # tangent): such a matrix is factored, and checked, in double
        logger.info("pardiso: a single-precision factor cannot be probed for singularity; factoring in double")
        f.free()
        return factor(K, rows, replace(opts, factor_precision="double"), matching=matching)
    if check == "always" or (check == "auto" and f.info["perturbed_pivots"] > 0):
        res = probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            if f.info["analysis_reused"]:
                # the ordering and scaling were made for other values: analyse this matrix afresh
                logger.info("pardiso: reused analysis gave probe residual %.2g; analysing again", res)
                return factor(K, rows, replace(opts, pardiso_reuse=False), matching=matching)
            if not matching:
                # Perturbed pivots may come from bad scaling (high stiffness
                # contrast) or strong indefiniteness rather than singularity;
                # scaling + matching fixes those, so one retry first.
                logger.info(
                    "pardiso: %d perturbed pivots, probe residual %.2g; retrying with scaling and weighted matching",
                    f.info["perturbed_pivots"],
                    res,
                )
                return factor(K, rows, opts, matching=True)
            # Singular, or so ill-conditioned that static pivoting fails
            # (measured: SIMP voids with E_min = 1e-12 E); Cholesky, if
            # installed, gets the second word.
            raise Unsuitable(
                f"Pardiso perturbed {f.info['perturbed_pivots']} pivot(s) and a "
                f"test solve has relative residual {res:.2g}",
                singular=True,
            )
    return f
