"""The ``scipy`` backend: SuperLU (``scipy.sparse.linalg.splu``).

Always there, threshold partial pivoting, any non-singular matrix; but much slower than
pardiso or cholmod on 3D models, and the gap grows with size (docs/performance.md). The
module is not called ``scipy`` so that it cannot be mistaken for the library.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from contopt.solve.linear.base import Factor, Unsuitable, probe
from contopt.solve.linear.options import LinearSolverOptions


def load() -> None:
    """Nothing to load: scipy is a dependency of contopt."""


class _ScipyFactor(Factor):
    backend = "scipy"

    def __init__(self, lu, n: int, method: str):
        super().__init__(n, method)
        self._lu = lu

    def _solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(b)

    def _release(self) -> None:
        self._lu = None


def factor(K: sp.csr_matrix, rows: np.ndarray, opts: LinearSolverOptions) -> Factor:
    """SuperLU's factor of ``K``, always checked by a probe solve unless ``singular_check="never"``."""
    from scipy.sparse.linalg import splu  # 0.3 s to import; SuperLU is the last resort of the backends

    # Symmetric mode (ordering of K + K^T, diagonal pivots preferred, still
    # threshold partial pivoting) measured 1-2x faster than the default COLAMD.
    kw = dict(permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True)) if opts.symmetric else {}
    try:
        lu = splu(K.tocsc(), **kw)
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise Unsuitable(f"SuperLU: {exc}", singular=True) from None
    f = _ScipyFactor(lu, K.shape[0], "scipy SuperLU")
    f.info["nnz_factor"] = int(lu.nnz)
    if opts.singular_check != "never":
        # SuperLU reports no pivot statistics; its factorization is so slow
        # that one probe solve is noise.
        res = probe(f, K)
        if res > opts.singular_rtol:
            f.free()
            raise Unsuitable(f"a test solve with SuperLU has relative residual {res:.2g}", singular=True)
    return f
