import numpy as np
import scipy.sparse as sp

from contopt.assembly.sparse import SparsePattern


def _blocks(rng):
    a = rng.integers(0, 30, size=(20, 6))
    b = rng.integers(0, 30, size=(7, 4))
    return [a, b]


def _coo_reference(n, blocks, values):
    rows, cols, data = [], [], []
    for dofs, val in zip(blocks, values):
        k = dofs.shape[1]
        rows.append(np.repeat(dofs, k, axis=1).ravel())
        cols.append(np.tile(dofs, (1, k)).ravel())
        data.append(val.ravel())
    return sp.coo_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()


def test_assembly_matches_scipy_coo_sum(rng):
    blocks = _blocks(rng)
    values = [rng.standard_normal((len(d), d.shape[1], d.shape[1])) for d in blocks]
    pat = SparsePattern.from_blocks(30, blocks)
    K = pat.matrix(pat.assemble_data(values))
    ref = _coo_reference(30, blocks, values)
    assert np.abs((K - ref).toarray()).max() < 1e-13
    assert np.all(np.diff(K.indptr) >= 0) and K.has_sorted_indices


def test_restrict_matches_slicing(rng):
    blocks = _blocks(rng)
    values = [rng.standard_normal((len(d), d.shape[1], d.shape[1])) for d in blocks]
    pat = SparsePattern.from_blocks(30, blocks)
    data = pat.assemble_data(values)
    keep = np.sort(rng.choice(30, size=17, replace=False))
    sub = pat.restrict(keep)
    ref = pat.matrix(data)[keep][:, keep].toarray()
    assert np.abs(sub.matrix(data).toarray() - ref).max() == 0.0
