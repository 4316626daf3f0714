"""What every backend shares: the :class:`Factorization` protocol, the common :class:`Factor`
class, the input checks (canonical CSR, empty rows, symmetry), the upper triangle, the probe
solve and the errors.

A backend's ``factor(K, rows, opts)`` receives ``K`` already through :func:`as_canonical_csr`
and :func:`check_matrix` (``rows`` from :func:`row_indices`), returns a :class:`Factor`
subclass, and raises :class:`Unsuitable` when it cannot produce a trustworthy factor.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import logging
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from contopt.errors import LinearSolverError
from contopt.parallel import SERIAL, Comm
from contopt.solve.linear.options import LinearSolverOptions

#: One logger for the whole package, under the name it had as one module.
logger = logging.getLogger("contopt.solve.linear")

SINGULAR_HINT = (
    "Likely cause: a body or direction without support: check Dirichlet "
    "conditions / contact (every body needs its 6 rigid-body modes removed by "
    "supports or active contact), a load at a limit/bifurcation point "
    "(reduce the load step), or an extreme stiffness contrast (void E_min/E "
    "below ~1e-10)."
)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Where the rows of a stiffness matrix sit: what an AMG preconditioner needs besides the matrix.

    Attributes
    ----------
    points : (n_nodes, 3) float64, the nodes' current positions (reference + displacement); the
        dofs are node-major, dof ``3 a + i`` is component i of node a
    free : (n,) int64, increasing: the dof of each row of the (free x free) matrix; the other dofs
        are prescribed
    comm : the ranks among which the matrix is split: on several, each rank passes the part its
        cells contribute and only a distributed backend (petsc) can solve
    contact : the matrix holds contact terms: AMG's rigid-body modes do not describe them and the
        tangent may be indefinite, so ``"auto"`` measures the AMG against a direct factor while
        the factor fits (:mod:`contopt.solve.linear.choice`)
    """

    points: np.ndarray
    free: np.ndarray
    comm: Comm = SERIAL  # several ranks: each holds its part of the matrix (contopt.parallel)
    contact: bool = False

    @property
    def n_dofs(self) -> int:
        return 3 * int(self.points.shape[0])


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

    def solve(self, b: np.ndarray, rtol: float | None = None, x0: np.ndarray | None = None) -> np.ndarray: ...

    def free(self) -> None: ...


class Factor:
    """Shared shape/finite checks around a backend's ``_solve``.

    A backend subclasses it, sets ``backend`` and implements ``_solve(b)`` (b float64 of shape
    (n,) or (n, k), non-empty) and, when it holds memory outside Python, ``_release()``.
    """

    backend = ""

    def __init__(self, n: int, method: str):
        self.shape = (n, n)
        self.seconds = float("nan")
        self.info: dict[str, Any] = {
            "method": method,
            "indefinite": None,
            "negative_pivots": None,
            "perturbed_pivots": None,
            "fallback_from": None,
            "fallback_reason": None,
            "probe_residual": None,
            "attempts": [],
        }
        self._freed = False
        self.rtol: float | None = None  # the tolerance of the solve under way (iterative backends)
        self.x0: np.ndarray | None = None  # its initial guess (iterative backends, one right-hand side)

    #: an iterative backend's solves stop at a tolerance (the ``rtol`` of :meth:`solve`)
    iterative = False
    #: its solves only approximate ``K^-1 b`` (a single-precision factor): :func:`factorize` hands
    #: out such a factor as the preconditioner of GMRES, never alone
    approximate = False

    def solve(self, b: np.ndarray, rtol: float | None = None, x0: np.ndarray | None = None) -> np.ndarray:
        """Solve ``K x = b``; b of shape (n,) or (n, k), x of the same shape (float64).

        ``rtol``: an iterative backend stops at ``||K x - b|| <= rtol ||b||`` (None: its
        ``krylov_rtol``); a direct one ignores it. ``x0`` (n,): where an iterative backend starts
        (None: zero); a direct one, and any backend with several right-hand sides, ignores it.
        """
        if self._freed:
            raise LinearSolverError("this factorization was freed; factorize the matrix again")
        b = np.asarray(b)
        if b.ndim not in (1, 2) or b.shape[0] != self.shape[0]:
            raise ValueError(
                f"right-hand side has shape {b.shape}, expected ({self.shape[0]},) or ({self.shape[0]}, k)"
            )
        if np.iscomplexobj(b):
            raise TypeError("complex right-hand sides are not supported (float64 only)")
        b = b.astype(np.float64, copy=False)
        if b.ndim == 2 and b.shape[1] == 0:
            return np.zeros(b.shape)
        self.rtol = rtol
        self.x0 = None if x0 is None or b.ndim != 1 else np.asarray(x0, dtype=np.float64).reshape(b.shape)
        x = self._solve(b)
        # O(n k): cheap next to the triangular solves, and the last line of
        # defence against a silent NaN answer.
        if not np.isfinite(x).all():
            if not np.isfinite(b).all():
                raise LinearSolverError("the right-hand side contains NaN or inf")
            raise LinearSolverError(
                f"{self.backend} returned a non-finite solution: the stiffness matrix "
                f"is singular or numerically singular. {SINGULAR_HINT}"
            )
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
        return (
            f"<{type(self).__name__} backend={self.backend!r} n={self.shape[0]} method={self.info['method']!r} {state}>"
        )


class Unsuitable(Exception):
    """This method could not produce a trustworthy factor of this matrix.

    ``singular`` is True when the failure says the matrix is (numerically)
    singular rather than that the method does not fit (Cholesky of an
    indefinite matrix, unpivoted LDL^T).
    """

    def __init__(self, reason: str, singular: bool = False):
        super().__init__(reason)
        self.singular = singular


def singular_error(detail: str) -> LinearSolverError:
    return LinearSolverError(f"The stiffness matrix is singular or numerically singular: {detail}. {SINGULAR_HINT}")


def as_canonical_csr(K) -> sp.csr_matrix:
    """``K`` as float64 CSR with sorted indices and no duplicates (no copy when it already is)."""
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


def check_matrix(K: sp.csr_matrix, rows: np.ndarray, opts: LinearSolverOptions) -> None:
    """Reject what must never reach a factorization: NaN/inf, empty rows, asymmetry."""
    if not np.isfinite(K.data).all():
        raise LinearSolverError(
            "the stiffness matrix contains NaN or inf entries (check the material state: inverted element, J <= 0?)"
        )
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
        raise singular_error(
            f"{bad.size} of {n} rows/columns are entirely zero (dofs {shown}; "
            "a node in no element, or a dof nothing stiffens)"
        )
    if opts.symmetric and opts.check_symmetry:
        diff = abs(K - K.T)
        scale = float(np.abs(K.data).max())
        if diff.nnz and float(diff.max()) > 1e-10 * scale:
            raise LinearSolverError(
                f"the matrix is not symmetric (max |K - K^T| = {float(diff.max()):.3g}, "
                f"max |K| = {scale:.3g}); pass symmetric=False"
            )


def check_parts(K: sp.csr_matrix, rows: np.ndarray, comm: Comm) -> None:
    """:func:`check_matrix` of a matrix whose parts ``K`` the ranks of ``comm`` hold (collective)."""
    if not comm.all(bool(np.isfinite(K.data).all())):
        raise LinearSolverError(
            "the stiffness matrix contains NaN or inf entries (check the material state: inverted element, J <= 0?)"
        )
    n = K.shape[0]
    stiffened = np.zeros(n)
    stiffened[rows[K.data != 0]] = 1.0
    empty = np.flatnonzero(comm.sum(stiffened) == 0)
    if empty.size:
        shown = ", ".join(map(str, empty[:10])) + (", ..." if empty.size > 10 else "")
        raise singular_error(
            f"{empty.size} of {n} rows/columns are entirely zero (dofs {shown}; a node in no element, or a dof "
            "nothing stiffens)"
        )


def _index_type(limit: int) -> type:
    """int32 where every index is at most ``limit``, else int64."""
    return np.int32 if limit <= np.iinfo(np.int32).max else np.int64


def row_indices(K: sp.csr_matrix) -> np.ndarray:
    """The row of every stored entry of CSR ``K`` (shape (nnz,); int32 where n allows, else int64).

    It lives through the factorization (the backends take it): int32 halves it, 14 MB on the
    fine die-slab's 3.5M entries.
    """
    return np.repeat(np.arange(K.shape[0], dtype=_index_type(K.shape[0])), np.diff(K.indptr))


def upper_with_diagonal(K: sp.csr_matrix, rows: np.ndarray):
    """Upper triangle of canonical CSR ``K`` with every diagonal entry stored.

    Pardiso's symmetric types need the diagonal present even where it is zero
    (the multiplier block of a saddle-point matrix); scipy's own ``triu`` +
    ``diags`` would drop explicit zeros. Returns ``(data, indptr, indices)``, the index arrays
    int32 where n and the entries allow (Pardiso takes them without a copy).
    """
    n = K.shape[0]
    keep = K.indices >= rows
    index = _index_type(max(n, K.nnz + n))
    r, c, v = rows[keep].astype(index, copy=False), K.indices[keep].astype(index, copy=False), K.data[keep]
    del keep
    has_diag = np.zeros(n, dtype=bool)
    has_diag[r[c == r]] = True
    if not has_diag.all():
        missing: np.ndarray = np.flatnonzero(~has_diag).astype(index)
        r = np.concatenate([r, missing])
        c = np.concatenate([c, missing])
        v = np.concatenate([v, np.zeros(missing.size)])
        order = np.lexsort((c, r))
        r, c, v = r[order], c[order], v[order]
    indptr = np.zeros(n + 1, dtype=index)
    np.cumsum(np.bincount(r, minlength=n), out=indptr[1:])
    return v, indptr, c


def probe(factor: Factor, K: sp.csr_matrix) -> float:
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


def return_free_heap() -> None:
    """Give the C heap's freed pages back to the system (glibc's ``malloc_trim``; elsewhere nothing).

    Arrays of up to 32 MB live on the heap once glibc has raised its mmap threshold, and the
    pages of freed ones stay resident, scattered between live ones. Called before a
    factorization, whose factor (hundreds of MB on large meshes) is allocated beside them.
    """
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.cache
def _malloc_trim():
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


#: bytes of a direct factorization of a 3D elasticity tangent per n^(4/3) rows (nested dissection's
#: fill): Pardiso's peak on the xl die-slab's first tangent, 5.9 GB at 336,141 rows (docs/scaling.md)
FACTOR_BYTES_PER_N43 = 5.9e9 / 336_141 ** (4 / 3)
#: the share of the available memory a direct factor may take (the rest: the model, the tangent, JAX)
FACTOR_MEMORY_SHARE = 0.6


def direct_factor_bytes(n: int) -> float:
    """The memory a direct factorization of an ``n``-row 3D tangent needs (an estimate, see above)."""
    return FACTOR_BYTES_PER_N43 * float(n) ** (4 / 3)


def memory_available() -> int | None:
    """Bytes this process could still use: the kernel's MemAvailable (Linux) and what ``ulimit -v``
    leaves, the smaller of the two; None where neither can be read."""
    from contopt.config import address_space_left

    known = [b for b in (_meminfo_available(), address_space_left()) if b is not None]
    return min(known) if known else None


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def direct_fits(n: int, available: int | None = None) -> bool:
    """Whether a direct factor of ``n`` rows fits in :data:`FACTOR_MEMORY_SHARE` of the available
    memory (``available`` bytes; None: :func:`memory_available`, and False where that is unknown)."""
    available = memory_available() if available is None else available
    return available is not None and direct_factor_bytes(n) <= FACTOR_MEMORY_SHARE * available
