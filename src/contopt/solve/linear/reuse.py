"""A direct factorization kept as the preconditioner of the next matrices (``factor_reuse``).

Between the last Newton iterations of a load step, and after a multiplier update of the
augmented Lagrangian (the tangent then changes in the contact rows only), the tangent moves
little: the factor of an earlier one preconditions GMRES so well that a few iterations reach
Newton's tolerance, each one pair of triangular solves instead of a new factorization. When
GMRES does not get there in :attr:`~LinearSolverOptions.factor_reuse_max_iter` iterations, the
matrix is factored after all (the earlier factor freed first, so that the two never coexist and
Pardiso's kept analysis serves the new one) and solved exactly.

One factor is kept per process: the last one freed. A factorization that does not reuse (the
adjoint's, a different size, ``factor_reuse=False``) releases it first.

The same GMRES makes a single-precision factor (``factor_precision="single"``) of the matrix itself
solve to float64 tolerances: its own solves are about 1e-2 accurate, and GMRES gains about two digits
an iteration with them. When that does not converge, the matrix is factored again in double.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from contopt.errors import LinearSolverError
from contopt.solve.linear.base import Factor, logger

#: iterations of this process's reusing solves (benchmarks and tests read them)
STATISTICS = {"reused": 0, "refactored": 0, "iterations": 0}

#: the kept factor and the dofs of its rows (None: unknown): at most one
_KEPT: list[tuple[Factor, np.ndarray | None]] = []


def release_kept() -> None:
    """Free the kept factor (its memory returns to the system, Pardiso's analysis to its pool)."""
    while _KEPT:
        _KEPT.pop()[0].free()


def take(n: int, free: np.ndarray | None) -> Factor | None:
    """The kept factor, handed over, when it was made for a matrix on the same rows (n, the same dofs)."""
    if not _KEPT:
        return None
    factor, rows = _KEPT[0]
    same_rows = rows is None or free is None or np.array_equal(rows, free)
    if factor.shape[0] != n or not same_rows:
        return None
    _KEPT.clear()
    return factor


class Reusing(Factor):
    """The solves of ``K`` (n x n) with a factor of ``K`` itself or, while it pays, of an earlier matrix.

    ``factor``: the factor to start from; ``own``: it is ``K``'s own (exact unless ``approximate``,
    a single-precision one). ``refactor(double)`` factors ``K`` (in double precision when ``double``)
    when the earlier one no longer preconditions well, or ``K``'s own single one does not solve it.
    Freeing keeps the factor for the next matrix (``keep``; otherwise it is freed).
    """

    def __init__(
        self,
        K: sp.csr_matrix,
        factor: Factor,
        own: bool,
        refactor: Callable[[bool], Factor],
        max_iter: int,
        krylov_rtol: float,
        free: np.ndarray | None,
        keep: bool = True,
    ):
        super().__init__(K.shape[0], "")
        self.backend = factor.backend
        self._K, self._refactor, self._keep = K, refactor, keep
        self._norm: float | None = None  # ||K||_inf, once a round-off test needs it
        self._max_iter, self._krylov_rtol, self._free = max_iter, krylov_rtol, free
        self._adopt(factor, own)
        self.info["iterations"] = []

    def _adopt(self, factor: Factor, own: bool) -> None:
        """Solve with ``factor`` from now on: exactly (``K``'s own, in double) or as GMRES's preconditioner."""
        self._factor: Factor | None = factor
        self._own = own
        self._exact = own and not factor.approximate
        # an earlier factor's solves take Newton's forcing tolerance (iterative): solving each to
        # 1e-10 lost the gain (docs/performance.md, "A kept factor as the next tangent's preconditioner")
        self.iterative = not self._exact
        self.info.update({k: v for k, v in factor.info.items() if k != "method"})
        method = factor.info["method"]
        self.info["method"] = method if self._exact else f"GMRES + {method if own else 'earlier ' + method}"
        self.info["factor_reused"] = not own

    def _solve(self, b: np.ndarray) -> np.ndarray:
        if self._factor is None:
            raise LinearSolverError("this matrix could not be factored (see the error before); factorize it again")
        if self._exact:
            return self._factor.solve(b)
        rtol = self._krylov_rtol if self.rtol is None else float(self.rtol)
        columns = [b] if b.ndim == 1 else [b[:, j] for j in range(b.shape[1])]
        xs = []
        for col in columns:
            x, its, ok = gmres(lambda v: self._K @ v, self._factor.solve, col, rtol, self._max_iter)
            STATISTICS["iterations"] += its
            self.info["iterations"].append(its)
            # a tolerance below what float64 resolves for this matrix (the adjoint asks 1e-12 of a
            # tangent whose double factor solves to 3e-11): the residual is already round-off
            if not ok and not (self._own and self._at_roundoff(x, col)):
                return self._factor_now(b, its)
            xs.append(x)
        if not self._own:
            STATISTICS["reused"] += 1
        return xs[0] if b.ndim == 1 else np.column_stack(xs)

    def _at_roundoff(self, x: np.ndarray, b: np.ndarray) -> bool:
        """``||b - K x||_inf <= 10 eps ||K||_inf ||x||_inf``: a residual no larger than the rounding
        error of computing ``K x`` itself, so no factorization in double would make it smaller
        than round-off either."""
        assert self._K is not None
        if self._norm is None:
            self._norm = norm_inf(self._K)
        r = b - self._K @ x
        return bool(np.abs(r).max() <= 10 * np.finfo(float).eps * self._norm * np.abs(x).max())

    def _factor_now(self, b: np.ndarray, its: int) -> np.ndarray:
        double = self._own  # the matrix's own single-precision factor did not do: a double one will
        logger.debug(
            "the %s factor did not reach the tolerance in %d GMRES iterations: factoring%s",
            "single-precision" if double else "earlier", its, " in double" if double else "",
        )  # fmt: skip
        STATISTICS["refactored"] += 1
        old, self._factor = self._factor, None
        if old is not None:
            old.free()  # before the new one: never two factors at once
        self._adopt(self._refactor(double), own=True)
        return self._solve(b)

    def _release(self) -> None:
        if self._K is None:  # free() again
            return
        if self._keep:
            release_kept()
            if self._factor is not None:  # None: the refactorization failed
                _KEPT.append((self._factor, self._free))
        elif self._factor is not None:
            self._factor.free()
        # the refactorization's closure holds the matrix and its row indices (215 MB on the paper-size
        # sabot): dropped with the matrix, whenever this object itself goes
        self._K, self._refactor = None, _freed_refactor


def norm_inf(K: sp.csr_matrix, rows_per_pass: int = 1 << 16) -> float:
    """``max_i sum_j |K_ij|`` of CSR ``K``, a block of rows at a time (no copy of its values)."""
    best, n = 0.0, K.shape[0]
    for lo in range(0, n, rows_per_pass):
        hi = min(n, lo + rows_per_pass)
        start, stop = int(K.indptr[lo]), int(K.indptr[hi])
        if stop == start:
            continue
        first = np.minimum(K.indptr[lo:hi] - start, stop - start - 1)
        sums = np.add.reduceat(np.abs(K.data[start:stop]), first)
        # reduceat gives an empty row the next row's first entry: such rows sum to 0
        sums[np.diff(K.indptr[lo : hi + 1]) == 0] = 0.0
        best = max(best, float(sums.max()))
    return best


def _freed_refactor(double: bool = False) -> Factor:
    raise LinearSolverError("this factorization was freed; factorize the matrix again")


def gmres(
    matvec: Callable[[np.ndarray], np.ndarray],
    precond: Callable[[np.ndarray], np.ndarray],
    b: np.ndarray,
    rtol: float,
    max_iter: int,
) -> tuple[np.ndarray, int, bool]:
    """Right-preconditioned GMRES from ``x = 0``, without restarts (a few iterations are expected).

    Stops when the residual ``||b - K x||`` (right preconditioning: the least-squares residual is
    the true one, up to round-off) is at most ``rtol ||b||``. Returns ``(x, iterations,
    converged)``; ``converged`` is checked on the true residual. Gives up early when the rate so
    far would need more than 1.5 ``max_iter`` iterations: a failed attempt then costs two or three
    triangular solves, not ``max_iter`` (GMRES's rate usually improves, hence the slack).
    """
    beta = float(np.linalg.norm(b))
    if beta == 0.0:
        return np.zeros_like(b), 0, True
    V = [b / beta]
    Z: list[np.ndarray] = []
    H = np.zeros((max_iter + 1, max_iter))
    for j in range(max_iter):
        Z.append(precond(V[j]))
        w = matvec(Z[j])
        for i in range(j + 1):  # modified Gram-Schmidt
            H[i, j] = w @ V[i]
            w = w - H[i, j] * V[i]
        H[j + 1, j] = np.linalg.norm(w)
        e1 = np.zeros(j + 2)
        e1[0] = beta
        y, *_ = np.linalg.lstsq(H[: j + 2, : j + 1], e1, rcond=None)
        estimate = float(np.linalg.norm(e1 - H[: j + 2, : j + 1] @ y))
        if estimate <= rtol * beta or H[j + 1, j] <= 1e-14 * beta or j + 1 == max_iter:
            x = np.column_stack(Z) @ y
            true = float(np.linalg.norm(b - matvec(x)))
            return x, j + 1, true <= rtol * beta
        if j >= 1 and hopeless(estimate / beta, j + 1, rtol, max_iter):
            return np.column_stack(Z) @ y, j + 1, False
        V.append(w / H[j + 1, j])
    raise AssertionError("unreachable")  # pragma: no cover


def hopeless(reduction: float, iterations: int, rtol: float, max_iter: int) -> bool:
    """At ``reduction`` of the residual in ``iterations``, reaching ``rtol`` would take > 1.5 max_iter
    (a Krylov solve that will fail: stop it and do what comes after the failure now)."""
    if reduction >= 1.0:
        return True
    needed = iterations * np.log(rtol) / np.log(reduction)
    return bool(needed > 1.5 * max_iter)
