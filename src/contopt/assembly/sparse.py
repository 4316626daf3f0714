"""CSR sparsity pattern built once, values scattered with a precomputed map.

``SparsePattern.from_blocks`` takes the global dof indices of every element
block (``(m, k)`` each, e.g. 24 dofs a hex8) and precomputes, for every
entry of every element matrix, the position in the CSR ``data`` array. An
assembly is then one ``np.bincount`` (no sorting, no duplicate summation by
scipy). ``restrict`` gives the pattern of a sub-matrix (free x free dofs for
Dirichlet elimination) as an index map into the full ``data``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True, eq=False)
class SparsePattern:
    """CSR pattern of an ``(n, n)`` matrix assembled from element blocks.

    Attributes
    ----------
    n : matrix size
    indptr, indices : CSR structure (sorted column indices)
    scatter : list of (m_i * k_i * k_i,) int64 positions in ``data`` of each block's entries
    """

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    scatter: tuple

    @property
    def nnz(self) -> int:
        return int(self.indices.size)

    @classmethod
    def from_blocks(cls, n: int, blocks: list[np.ndarray]) -> SparsePattern:
        """Pattern of the sum of element matrices with dofs ``blocks[i]`` (m_i, k_i)."""
        row_parts, col_parts, sizes = [], [], []
        for dofs in blocks:
            dofs = np.asarray(dofs, dtype=np.int64)
            k = dofs.shape[1]
            row_parts.append(np.repeat(dofs, k, axis=1).ravel())
            col_parts.append(np.tile(dofs, (1, k)).ravel())
            sizes.append(row_parts[-1].size)
        rows = np.concatenate(row_parts) if row_parts else np.zeros(0, np.int64)
        cols = np.concatenate(col_parts) if col_parts else np.zeros(0, np.int64)
        keys = rows * n + cols
        uniq, inverse = np.unique(keys, return_inverse=True)
        urows, ucols = uniq // n, uniq % n
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(urows, minlength=n), out=indptr[1:])
        scatter = tuple(np.split(inverse.astype(np.int64), np.cumsum(sizes)[:-1]))
        return cls(n=n, indptr=indptr, indices=ucols.astype(np.int64), scatter=scatter)

    def assemble_data(self, values: list[np.ndarray]) -> np.ndarray:
        """CSR ``data`` (nnz,) from element matrices ``values[i]`` (m_i, k_i, k_i)."""
        data = np.zeros(self.nnz)
        for pos, val in zip(self.scatter, values):
            if pos.size:
                data += np.bincount(pos, weights=np.asarray(val).reshape(-1), minlength=self.nnz)
        return data

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """A scipy CSR matrix sharing the pattern arrays."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))

    def restrict(self, keep: np.ndarray) -> SubPattern:
        """The pattern of ``K[keep][:, keep]`` and the map from its data into the full data."""
        keep = np.asarray(keep, dtype=np.int64)
        # the data of a marker matrix is the 1-based position in the full data, so that
        # slicing (which never drops stored entries with nonzero values) carries the map along
        marker = self.matrix(np.arange(1, self.nnz + 1, dtype=np.float64))
        sub = marker[keep][:, keep].tocsr()
        sub.sort_indices()
        take = sub.data.astype(np.int64) - 1
        return SubPattern(
            n=len(keep), indptr=sub.indptr.astype(np.int64), indices=sub.indices.astype(np.int64), take=take
        )


@dataclass(frozen=True, eq=False)
class SubPattern:
    """Pattern of a principal sub-matrix; ``data_sub = data_full[take]``."""

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    take: np.ndarray

    def matrix(self, full_data: np.ndarray) -> sp.csr_matrix:
        return sp.csr_matrix((full_data[self.take], self.indices, self.indptr), shape=(self.n, self.n))
