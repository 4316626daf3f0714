"""CSR sparsity pattern built once, values scattered with a precomputed map.

``SparsePattern.from_blocks`` takes the global dof indices of every element
block (``(m, k)`` each, e.g. 24 dofs a hex8) and precomputes, for every
entry of every element matrix, the position in the CSR ``data`` array. An
assembly is then one unbuffered ``np.add.at`` per block (no sorting, no duplicate summation by
scipy). ``restrict`` gives the pattern of a sub-matrix (free x free dofs for
Dirichlet elimination) as an index map into the full ``data``.

Where every block numbers its dofs node by node (dof ``3 node + c`` at column
``3 a + c`` of the block, as the discretization does) the pattern is built
from node pairs and expanded to 3 x 3 dof blocks: 9x fewer keys to sort than
dof pairs, which bounded the peak memory of large meshes. Index arrays are
int32 where the sizes allow (the scatter map lives as long as the model).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

#: element entries whose scatter positions are computed at once: bounds from_blocks' int64
#: temporaries (about 40 bytes an entry)
_ENTRIES_PER_PASS = 1 << 21


def _index_dtype(limit: int) -> np.dtype:
    """int32 when ``limit`` (every index is at most it) fits, else int64."""
    return np.dtype(np.int32) if limit <= np.iinfo(np.int32).max else np.dtype(np.int64)


def _node_size(n: int, blocks: list[np.ndarray], size: int = 3) -> int:
    """``size`` when every block numbers its dofs node by node in groups of ``size``, else 1."""
    if n % size:
        return 1
    for dofs in blocks:
        m, k = dofs.shape
        if k % size:
            return 1
        grouped = dofs.reshape(m, k // size, size)
        first = grouped[:, :, :1]
        if (first % size).any() or (grouped != first + np.arange(size)).any():
            return 1
    return size


@dataclass(frozen=True, eq=False)
class SparsePattern:
    """CSR pattern of an ``(n, n)`` matrix assembled from element blocks.

    Attributes
    ----------
    n : matrix size
    indptr, indices : CSR structure (sorted column indices; int32 where n and nnz allow, else int64)
    scatter : per block, (m_i * k_i * k_i,) positions in ``data`` of its entries (int32 where nnz allows)
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
        blocks = [np.asarray(d, dtype=np.int64).reshape(len(d), -1) for d in blocks]
        s = _node_size(n, blocks)
        n_nodes = n // s
        # node pairs (A, B) of every block: position p in the node-level CSR (sorted by A, then B)
        nodes = [d[:, ::s] // s for d in blocks]
        keys = [(a[:, :, None] * n_nodes + a[:, None, :]).ravel() for a in nodes]
        uniq, inverse = np.unique(np.concatenate(keys) if keys else np.zeros(0, np.int64), return_inverse=True)
        del keys
        urows, ucols = np.divmod(uniq, n_nodes)
        del uniq
        counts = np.bincount(urows, minlength=n_nodes)
        node_ptr = np.zeros(n_nodes + 1, dtype=np.int64)
        np.cumsum(counts, out=node_ptr[1:])
        nnz = s * s * int(node_ptr[-1])
        # dof (s A + c, s B + d) sits at start(A) + c * s counts(A) + s (p - node_ptr(A)) + d:
        # the s rows of node A hold, each in turn, the s columns of every B of A's node row
        base = s * np.arange(node_ptr[-1], dtype=np.int64) + (s * s - s) * node_ptr[urows]
        stride = s * counts
        idx = _index_dtype(max(n, nnz))
        indptr = np.empty(n + 1, dtype=idx)
        indptr[:-1] = (s * s * node_ptr[:-1, None] + np.arange(s) * stride[:, None]).ravel()
        indptr[-1] = nnz
        indices = np.empty(nnz, dtype=idx)
        cd = np.arange(s)
        for c in range(s):
            where = (base + c * stride[urows])[:, None] + cd
            indices[where.ravel()] = (s * ucols[:, None] + cd).ravel()
        del urows, ucols
        scatter, start = [], 0
        pos_dtype = _index_dtype(nnz)
        for a in nodes:
            m, ka = a.shape
            p = inverse[start : start + m * ka * ka].reshape(m, ka, ka)
            start += p.size
            out = np.empty((m, ka, s, ka, s), dtype=pos_dtype)
            step = max(1, _ENTRIES_PER_PASS // max(1, ka * ka * s * s))
            for lo in range(0, m, step):
                hi = min(lo + step, m)
                row = (stride[a[lo:hi]][:, :, None] * cd)[:, :, :, None, None]  # (cells, ka, s, 1, 1)
                out[lo:hi] = row + base[p[lo:hi]][:, :, None, :, None] + cd
            scatter.append(out.reshape(-1))
        return cls(n=n, indptr=indptr, indices=indices, scatter=tuple(scatter))

    def assemble_data(self, values: list[np.ndarray]) -> np.ndarray:
        """CSR ``data`` (nnz,) from element matrices ``values[i]`` (m_i, k_i, k_i)."""
        data = np.zeros(self.nnz)
        for i, val in enumerate(values):
            self.add_cells(data, i, 0, len(val), val)
        return data

    def add_cells(self, data: np.ndarray, block: int, start: int, stop: int, values: np.ndarray) -> None:
        """Add the element matrices ``values`` (stop - start, k, k) of cells ``start:stop`` of
        block ``block`` into ``data`` (nnz,): :meth:`assemble_data` a piece at a time, the same
        sums bitwise when the pieces come in cell order."""
        per = int(np.prod(np.shape(values)[1:]))  # entries of one element matrix
        pos = self.scatter[block][start * per : stop * per]
        # unbuffered add in entry order, without bincount's int64 copy of the positions and
        # its (nnz,) temporary: the same sums bitwise where blocks share no entry (bodies)
        np.add.at(data, pos, np.asarray(values, dtype=np.float64).reshape(-1))

    @cached_property
    def diagonal(self) -> np.ndarray | None:
        """(n,) positions in ``data`` of the diagonal entries; None when some row has none."""
        rows = np.repeat(np.arange(self.n, dtype=self.indices.dtype), np.diff(self.indptr))
        pos = np.flatnonzero(self.indices == rows)
        return pos.astype(_index_dtype(self.nnz)) if pos.size == self.n else None

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """A scipy CSR matrix sharing the pattern arrays."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))

    def restrict(self, keep: np.ndarray, columns: np.ndarray | None = None) -> SubPattern:
        """The pattern of ``K[keep][:, columns]`` (default ``columns = keep``) and the map from its
        data into the full data.

        keep, columns : strictly increasing indices (the order keeps the column indices sorted)
        """
        keep = _increasing(keep, self.n, "keep")
        columns = keep if columns is None else _increasing(columns, self.n, "columns")
        new = np.full(self.n, -1, dtype=np.int64)
        new[columns] = np.arange(columns.size)
        starts = self.indptr[keep].astype(np.int64)
        lengths = self.indptr[keep + 1] - starts
        ends = np.zeros(keep.size + 1, dtype=np.int64)
        np.cumsum(lengths, out=ends[1:])
        # position in the full data of every entry of the kept rows, then those in kept columns
        pos = np.arange(ends[-1]) + np.repeat(starts - ends[:-1], lengths)
        cols = new[self.indices[pos]]
        inside = cols >= 0
        kept_before = np.zeros(pos.size + 1, dtype=np.int64)
        np.cumsum(inside, out=kept_before[1:])
        idx = _index_dtype(max(keep.size, columns.size, int(kept_before[-1])))
        return SubPattern(
            n=keep.size,
            indptr=kept_before[ends].astype(idx),
            indices=cols[inside].astype(idx),
            take=pos[inside].astype(_index_dtype(self.nnz)),
            n_columns=columns.size,
        )


def _increasing(index: np.ndarray, n: int, name: str) -> np.ndarray:
    """``index`` as int64, checked to be strictly increasing in [0, n)."""
    index = np.asarray(index, dtype=np.int64).reshape(-1)
    if index.size and (index[0] < 0 or index[-1] >= n or (np.diff(index) <= 0).any()):
        raise ValueError(f"{name} must be strictly increasing indices in [0, {n}), got {index}")
    return index


@dataclass(frozen=True, eq=False)
class SubPattern:
    """Pattern of a sub-matrix of ``n`` rows and ``n_columns`` columns (default: ``n``, a principal
    one); ``data_sub = data_full[take]``.

    indptr (n + 1,), indices (nnz_sub,): CSR structure (sorted); take (nnz_sub,): positions in
    the full data (int32 where the sizes allow)
    """

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    take: np.ndarray
    n_columns: int | None = None

    def matrix(self, full_data: np.ndarray) -> sp.csr_matrix:
        shape = (self.n, self.n if self.n_columns is None else self.n_columns)
        return sp.csr_matrix((full_data[self.take], self.indices, self.indptr), shape=shape)
