"""The ``cholmod`` backend: SuiteSparse CHOLMOD through scikit-sparse (optional).

Supernodal Cholesky (LL^T) for SPD matrices. An indefinite matrix makes it raise
:class:`~contopt.solve.linear.base.Unsuitable`; the dispatcher then falls back (to pardiso when
available, else to CHOLMOD's unpivoted simplicial LDL^T, :func:`factor_ldlt`, checked by a
residual, else to scipy).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from contopt.solve.linear.base import Factor, Unsuitable, probe
from contopt.solve.linear.options import LinearSolverOptions

#: A Cholesky pivot ratio min(D)/max(D) below this makes the ``"auto"``
#: singularity check run its probe solve. Measured: floating bodies 1e-14..2e-13
#: (when LL^T does not refuse them outright), sound meshes 1e-4..1e-1, SIMP voids
#: 1e-10 (E_min = 1e-9 E) and 1e-13 (1e-12 E): the pivots alone cannot tell, the
#: probe (one extra solve, ~2.5 % of the factorization) can.
_PIVOT_RATIO_PROBE = 1e-8


def load() -> None:
    """Import scikit-sparse's CHOLMOD (ImportError when it is not installed)."""
    import sksparse.cholmod  # noqa: F401


class _CholmodFactor(Factor):
    backend = "cholmod"

    def __init__(self, factor, n: int, method: str):
        super().__init__(n, method)
        self._factor = factor
        D = factor.D()
        dmax = float(np.abs(D).max()) if D.size else 1.0
        self.pivot_ratio = float(np.abs(D).min()) / dmax if dmax > 0 else 0.0
        neg = int(np.count_nonzero(D < 0))
        self.info.update(negative_pivots=neg, indefinite=neg > 0, perturbed_pivots=0, pivot_ratio=self.pivot_ratio)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor.solve_A(b)

    def _release(self) -> None:
        self._factor = None  # scikit-sparse frees the CHOLMOD factor on deallocation


def factor_llt(K: sp.csr_matrix, rows: np.ndarray, opts: LinearSolverOptions) -> Factor:
    """Supernodal LL^T of ``K`` (the ``"cholmod"`` method)."""
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

    # CSR of a symmetric matrix is its CSC: no copy, and CHOLMOD reads the lower triangle.
    A = sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)
    try:
        fac = cholesky(A, mode="supernodal")
    except CholmodNotPositiveDefiniteError as exc:
        raise Unsuitable(f"not positive definite ({exc})") from None
    f = _CholmodFactor(fac, K.shape[0], "cholmod supernodal LL^T")
    check = opts.singular_check
    if check == "always" or (check == "auto" and f.pivot_ratio < _PIVOT_RATIO_PROBE):
        res = probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            # Cholesky is backward stable: a bad residual means singular.
            raise Unsuitable(
                f"Cholesky pivot ratio min/max = {f.pivot_ratio:.2g} and a test solve has relative residual {res:.2g}",
                singular=True,
            )
    return f


def factor_ldlt(K: sp.csr_matrix, rows: np.ndarray, opts: LinearSolverOptions) -> Factor:
    """Simplicial LDL^T of ``K`` without pivoting (the ``"cholmod_ldlt"`` fallback method)."""
    from sksparse.cholmod import CholmodError, cholesky

    A = sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)
    try:
        fac = cholesky(A, mode="simplicial")
    except CholmodError as exc:  # zero pivot
        raise Unsuitable(f"zero pivot in LDL^T ({exc})") from None
    f = _CholmodFactor(fac, K.shape[0], "cholmod simplicial LDL^T (no pivoting)")
    if opts.singular_check != "never":
        # Without pivoting the factor may be inaccurate or the matrix
        # singular; it cannot tell which, so a bad probe means "try another".
        res = probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            raise Unsuitable(f"unpivoted LDL^T is inaccurate (test residual {res:.2g})")
    return f
