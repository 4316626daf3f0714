import numpy as np
import pytest
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


def _node_blocks(rng, n_nodes, specs):
    """Blocks numbering dofs node by node (3 per node), as the discretization does: (m, 3 k) each."""
    out = []
    for m, k in specs:
        nodes = rng.integers(0, n_nodes, size=(m, k))
        out.append((3 * nodes[:, :, None] + np.arange(3)).reshape(m, 3 * k))
    return out


def _reference_pattern(n, blocks):
    ones = [np.ones((len(d), d.shape[1], d.shape[1])) for d in blocks]
    ref = _coo_reference(n, blocks, ones)
    ref.sum_duplicates()
    ref.sort_indices()
    return ref


# hex8 cells, quad faces and single nodes (different k), with repeated nodes within a cell
NODE_SPECS = [(40, 8), (9, 4), (5, 1)]


def test_node_pattern_is_the_dof_pair_pattern(rng):
    n_nodes = 50
    blocks = _node_blocks(rng, n_nodes, NODE_SPECS)
    pat = SparsePattern.from_blocks(3 * n_nodes, blocks)
    ref = _reference_pattern(3 * n_nodes, blocks)
    assert pat.nnz == ref.nnz
    assert np.array_equal(pat.indptr, ref.indptr) and np.array_equal(pat.indices, ref.indices)


def test_node_scatter_assembles_the_scipy_matrix(rng):
    n_nodes = 50
    blocks = _node_blocks(rng, n_nodes, NODE_SPECS)
    values = [rng.standard_normal((len(d), d.shape[1], d.shape[1])) for d in blocks]
    pat = SparsePattern.from_blocks(3 * n_nodes, blocks)
    K = pat.matrix(pat.assemble_data(values))
    ref = _coo_reference(3 * n_nodes, blocks, values)
    assert K.has_sorted_indices
    assert np.abs((K - ref).toarray()).max() <= 1e-14 * np.abs(ref).max()
    # every entry of every element matrix has its own place in data, within the pattern
    for pos, dofs in zip(pat.scatter, blocks):
        k = dofs.shape[1]
        rows = np.repeat(dofs, k, axis=1).ravel()
        assert np.array_equal(pat.indices[pos], np.tile(dofs, (1, k)).ravel())
        assert np.all((pat.indptr[rows] <= pos) & (pos < pat.indptr[rows + 1]))


def test_indices_are_int32_where_they_fit(rng):
    pat = SparsePattern.from_blocks(150, _node_blocks(rng, 50, NODE_SPECS))
    sub = pat.restrict(np.arange(0, 150, 2))
    arrays = (pat.indptr, pat.indices, *pat.scatter, sub.indptr, sub.indices, sub.take)
    assert {a.dtype for a in arrays} == {np.dtype(np.int32)}


def test_blocks_not_numbered_by_node_give_the_dof_pair_pattern(rng):
    # one block breaks the node-by-node numbering: the pattern is built from dof pairs
    blocks = _node_blocks(rng, 50, NODE_SPECS)
    blocks.append(rng.integers(0, 150, size=(6, 5)))
    pat = SparsePattern.from_blocks(150, blocks)
    ref = _reference_pattern(150, blocks)
    assert np.array_equal(pat.indptr, ref.indptr) and np.array_equal(pat.indices, ref.indices)


def test_restrict_of_node_pattern_matches_slicing(rng):
    blocks = _node_blocks(rng, 50, NODE_SPECS)
    values = [rng.standard_normal((len(d), d.shape[1], d.shape[1])) for d in blocks]
    pat = SparsePattern.from_blocks(150, blocks)
    data = pat.assemble_data(values)
    keep = np.sort(rng.choice(150, size=101, replace=False))
    sub = pat.restrict(keep).matrix(data)
    ref = pat.matrix(data)[keep][:, keep]
    assert sub.has_sorted_indices and sub.nnz == ref.nnz
    assert np.abs((sub - ref).toarray()).max() == 0.0


def test_restrict_refuses_unsorted_keep(rng):
    pat = SparsePattern.from_blocks(30, _blocks(rng))
    with pytest.raises(ValueError, match="strictly increasing"):
        pat.restrict(np.array([3, 1, 2]))


def test_pieces_in_cell_order_give_the_whole_assembly_bitwise(rng):
    blocks = _node_blocks(rng, 40, [(37, 8), (11, 4)])
    values = [rng.standard_normal((len(d), d.shape[1], d.shape[1])) for d in blocks]
    pat = SparsePattern.from_blocks(120, blocks)
    data = np.zeros(pat.nnz)
    for i, val in enumerate(values):
        for start in range(0, len(val), 5):  # pieces of 5 cells, the last one shorter
            pat.add_cells(data, i, start, min(start + 5, len(val)), val[start : start + 5])
    assert np.array_equal(data, pat.assemble_data(values))
    ref = _coo_reference(120, blocks, values)
    assert np.abs((pat.matrix(data) - ref).toarray()).max() < 1e-13
