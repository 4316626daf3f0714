"""The sparse linear-solver layer against dense numpy solves, for every installed direct backend
(the iterative one has tests/solve/test_petsc.py)."""

from __future__ import annotations

import gc
import logging

import numpy as np
import pytest
import scipy.sparse as sp
from _elasticity import cube_stiffness, keep_dofs, x0_face_dofs

from contopt.errors import ConfigError, LinearSolverError
from contopt.solve import linear
from contopt.solve.linear import LinearSolverOptions, available_backends, factorize
from contopt.solve.linear.options import ITERATIVE

BACKENDS = [b for b in available_backends() if b not in ITERATIVE]
N = 4  # 4^3 elements, 300 free dofs: dense references stay instant
RTOL = 1e-10


def rel_err(x, ref):
    return np.linalg.norm(x - ref) / np.linalg.norm(ref)


@pytest.fixture(scope="module")
def K():
    """SPD stiffness, heterogeneous E so that no two rows look alike; shape (300, 300)."""
    E = np.random.default_rng(0).uniform(0.5, 2.0, N**3)
    return cube_stiffness(N, E=E)


@pytest.fixture(scope="module")
def K_shifted(K):
    """K - sigma I with sigma between the 10th and 11th eigenvalue: 10 negative eigenvalues."""
    ev = np.linalg.eigvalsh(K.toarray())
    sigma = 0.5 * (ev[9] + ev[10])
    return (K - sigma * sp.eye(K.shape[0])).tocsr(), 10


@pytest.fixture(scope="module")
def K_saddle(K):
    """KKT matrix [[K, B^T], [B, 0]] of 12 random linear constraints; zero diagonal block."""
    B = sp.random(12, K.shape[0], density=0.05, random_state=3, format="csr")
    B = B + sp.csr_matrix((np.ones(12), (np.arange(12), 7 * np.arange(12))), shape=B.shape)
    A = sp.bmat([[K, B.T], [B, None]], format="csr")
    assert (A.diagonal()[-12:] == 0).all()
    return A, 12


@pytest.fixture
def rhs(K):
    return np.random.default_rng(1).standard_normal(K.shape[0])


def without(monkeypatch, *names):
    """Pretend the named backends are not installed."""
    real = linear._is_available
    monkeypatch.setattr(linear, "_is_available", lambda name: name not in names and real(name))


# ----------------------------------------------------------------------------- availability


def test_available_backends_ordered_and_scipy_always_there():
    assert BACKENDS[-1] == "scipy"
    assert BACKENDS == [b for b in linear.BACKENDS if b in BACKENDS]
    assert "petsc" in linear.BACKENDS and linear.BACKENDS.index("petsc") > linear.BACKENDS.index("pardiso")
    assert linear.BACKENDS[0] == "pardiso"  # the measured fastest, see module docstring


def test_auto_picks_first_available(K, rhs):
    f = factorize(K)
    assert f.backend == BACKENDS[0]
    assert factorize(K, "auto").backend == BACKENDS[0]


def test_auto_without_fast_backends_uses_scipy_and_warns(K, rhs, monkeypatch, caplog):
    without(monkeypatch, "pardiso", "cholmod", "petsc")
    monkeypatch.setattr(linear, "_SCIPY_WARNED", False)
    assert available_backends() == ["scipy"]
    with caplog.at_level(logging.WARNING, logger="contopt.solve.linear"):
        f = factorize(K)
        factorize(K)
    assert f.backend == "scipy"
    warnings = [r for r in caplog.records if "slower" in r.getMessage()]
    assert len(warnings) == 1  # once, not per factorization
    assert "pip install" in warnings[0].getMessage()


# ----------------------------------------------------------------------------- SPD solves


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
def test_spd_solution_matches_dense(K, rhs, backend):
    f = factorize(K, backend)
    x = f.solve(rhs)
    assert x.shape == rhs.shape and x.dtype == np.float64
    assert rel_err(x, np.linalg.solve(K.toarray(), rhs)) < RTOL
    assert f.info["fallback_from"] is None
    assert f.info["indefinite"] in (False, None)
    assert f.seconds > 0
    f.free()


@pytest.mark.parametrize("backend", BACKENDS)
def test_multiple_rhs(K, backend):
    B = np.random.default_rng(2).standard_normal((K.shape[0], 5))
    f = factorize(K, backend)
    X = f.solve(B)
    assert X.shape == B.shape
    assert rel_err(X, np.linalg.solve(K.toarray(), B)) < RTOL
    # column k of a block solve equals the single solve of column k
    assert rel_err(X[:, 3], f.solve(B[:, 3])) < 1e-13
    assert f.solve(B[:, :1]).shape == (K.shape[0], 1)


@pytest.mark.parametrize("backend", BACKENDS)
def test_repeated_solves_reuse_the_factor(K, backend, monkeypatch):
    calls = []
    for name, fn in list(linear._METHODS.items()):
        monkeypatch.setitem(linear._METHODS, name, lambda *a, _fn=fn, _n=name, **k: calls.append(_n) or _fn(*a, **k))
    Kc = K.copy()
    Kd = K.toarray()
    f = factorize(Kc, backend)
    assert calls == [backend]
    # The factor must not look at (or refactor) the caller's matrix again.
    Kc.data *= 3.0
    rng = np.random.default_rng(4)
    for _ in range(3):
        b = rng.standard_normal(K.shape[0])
        assert rel_err(f.solve(b), np.linalg.solve(Kd, b)) < RTOL
    assert calls == [backend]


def test_pardiso_general_matrix_type(K, rhs):
    if "pardiso" not in BACKENDS:
        pytest.skip("pypardiso not installed")
    f = factorize(K, LinearSolverOptions("pardiso", pardiso_matrix_type="general"))
    assert "mtype=11" in f.info["method"]
    assert rel_err(f.solve(rhs), np.linalg.solve(K.toarray(), rhs)) < RTOL
    f2 = factorize(K, "pardiso")
    assert "mtype=-2" in f2.info["method"]
    # the symmetric factor stores only a triangle: clearly fewer entries
    assert f2.info["nnz_factor"] < 0.8 * f.info["nnz_factor"]


def test_accepts_non_canonical_input(K, rhs):
    # duplicates, unsorted indices and COO format: Pardiso would mis-solve these silently
    C = K.tocoo()
    perm = np.random.default_rng(5).permutation(C.nnz)
    half = C.data[perm] / 2
    dup = sp.coo_matrix(
        (np.r_[half, half], (np.r_[C.row[perm], C.row[perm]], np.r_[C.col[perm], C.col[perm]])), shape=K.shape
    )
    ref = np.linalg.solve(K.toarray(), rhs)
    for backend in BACKENDS:
        assert rel_err(factorize(dup, backend).solve(rhs), ref) < RTOL
        assert rel_err(factorize(sp.csr_array(K), backend).solve(rhs), ref) < RTOL


@pytest.mark.parametrize("backend", [b for b in BACKENDS if b != "cholmod"])
def test_non_symmetric_matrix(K, rhs, backend):
    A = (K + sp.diags(np.linspace(0, 1, K.shape[0] - 1) * K.diagonal()[1:], 1, shape=K.shape)).tocsr()
    f = factorize(A, LinearSolverOptions(backend, symmetric=False))
    assert rel_err(f.solve(rhs), np.linalg.solve(A.toarray(), rhs)) < RTOL
    # Treated as symmetric it would read one triangle only: the check catches it.
    with pytest.raises(LinearSolverError, match="not symmetric"):
        factorize(A, LinearSolverOptions(backend, check_symmetry=True))


@pytest.fixture(scope="module")
def K_contrast():
    """SIMP-like stiffness: half the elements void with E_min = 1e-9 (regular, cond ~1e12)."""
    rho = (np.random.default_rng(1).random(N**3) < 0.5).astype(float)
    return cube_stiffness(N, E=1e-9 + (1 - 1e-9) * rho)


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
def test_high_contrast_is_solved_not_called_singular(K_contrast, backend):
    b = np.random.default_rng(10).standard_normal(K_contrast.shape[0])
    ref = np.linalg.solve(K_contrast.toarray(), b)
    f = factorize(K_contrast, backend)
    x = f.solve(b)
    # cond ~2e10 and |x| ~ 1e11 |b|: all backends and the dense solve agree to
    # ~3e-8 (measured), a perturbed-pivot factor is off by O(1).
    assert np.linalg.norm(K_contrast @ x - b) < 1e-6 * np.linalg.norm(b)
    assert rel_err(x, ref) < 1e-6
    assert f.info["fallback_from"] is None


def test_pardiso_retry_mode_recovers_from_perturbed_pivots(K_contrast, caplog):
    if "pardiso" not in BACKENDS:
        pytest.skip("pypardiso not installed")
    b = np.random.default_rng(11).standard_normal(K_contrast.shape[0])
    ref = np.linalg.solve(K_contrast.toarray(), b)
    # Without scaling the void pivots fall under Pardiso's 1e-8 perturbation
    # threshold: that factor alone gives a wrong answer ...
    plain = factorize(K_contrast, LinearSolverOptions("pardiso", pardiso_scaling="retry", singular_check="never"))
    assert plain.info["perturbed_pivots"] > 0
    assert rel_err(plain.solve(b), ref) > 1e-3
    # ... which the probe notices, and the retry with scaling + matching fixes.
    with caplog.at_level(logging.INFO, logger="contopt.solve.linear"):
        f = factorize(K_contrast, LinearSolverOptions("pardiso", pardiso_scaling="retry"))
    assert "scaling+matching" in f.info["method"]
    assert any("retrying" in r.getMessage() for r in caplog.records)
    x = f.solve(b)
    assert np.linalg.norm(K_contrast @ x - b) < 1e-6 * np.linalg.norm(b)
    assert rel_err(x, ref) < 1e-6


def test_extreme_contrast_defeating_pardiso_goes_to_cholmod():
    # E_min = 1e-12 E: even with scaling Pardiso's static pivoting perturbs
    # pivots and its answer is wrong; Cholesky is still fine.
    if not {"pardiso", "cholmod"} <= set(BACKENDS):
        pytest.skip("needs pardiso and cholmod")
    rho = (np.random.default_rng(1).random(N**3) < 0.5).astype(float)
    A = cube_stiffness(N, E=1e-12 + (1 - 1e-12) * rho)
    b = np.random.default_rng(12).standard_normal(A.shape[0])
    f = factorize(A)
    assert f.backend == "cholmod" and f.info["fallback_from"] == "pardiso"
    assert np.linalg.norm(A @ f.solve(b) - b) < 1e-4 * np.linalg.norm(b)


# ----------------------------------------------------------------------------- indefinite


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
def test_shifted_indefinite(K_shifted, backend):
    A, n_neg = K_shifted
    b = np.random.default_rng(6).standard_normal(A.shape[0])
    f = factorize(A, backend)
    assert rel_err(f.solve(b), np.linalg.solve(A.toarray(), b)) < RTOL
    _check_indefinite_info(f, backend, n_neg)


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
def test_saddle_point_indefinite(K_saddle, backend):
    A, n_neg = K_saddle
    b = np.random.default_rng(7).standard_normal((A.shape[0], 2))
    f = factorize(A, backend)
    assert rel_err(f.solve(b), np.linalg.solve(A.toarray(), b)) < RTOL
    _check_indefinite_info(f, backend, n_neg)


def _check_indefinite_info(f, backend, n_neg):
    # "auto" tries the fastest direct backend first: cholmod where pardiso is missing (no MKL)
    if backend == "auto":
        backend = next(b for b in BACKENDS if b != "petsc")
    if backend == "cholmod":
        # Cholesky must have refused, and said so
        assert f.info["fallback_from"] == "cholmod"
        assert "positive definite" in f.info["fallback_reason"]
        assert f.info["method"] != "cholmod supernodal LL^T"
    else:
        assert f.info["fallback_from"] is None
    if f.backend == "pardiso":
        assert f.info["indefinite"] is True
        assert f.info["negative_pivots"] == n_neg  # Sylvester inertia
    if f.backend == "cholmod":
        assert f.info["indefinite"] is True


def test_cholmod_fallback_is_logged(K_shifted, caplog):
    if "cholmod" not in BACKENDS:
        pytest.skip("scikit-sparse not installed")
    with caplog.at_level(logging.WARNING, logger="contopt.solve.linear"):
        factorize(K_shifted[0], "cholmod")
    assert any("falling back" in r.getMessage() for r in caplog.records)


def test_cholmod_without_pardiso_uses_ldlt_then_scipy(K_shifted, K_saddle, monkeypatch):
    if "cholmod" not in BACKENDS:
        pytest.skip("scikit-sparse not installed")
    without(monkeypatch, "pardiso")
    A, n_neg = K_shifted
    b = np.random.default_rng(8).standard_normal(A.shape[0])
    f = factorize(A)  # auto -> cholmod -> LDL^T
    assert f.backend == "cholmod" and "LDL^T" in f.info["method"]
    assert f.info["fallback_from"] == "cholmod"
    assert f.info["negative_pivots"] == n_neg
    assert rel_err(f.solve(b), np.linalg.solve(A.toarray(), b)) < RTOL
    # zero diagonal block: unpivoted LDL^T meets a zero pivot, SuperLU does it
    A, _ = K_saddle
    b = np.random.default_rng(9).standard_normal(A.shape[0])
    f = factorize(A, "cholmod")
    assert f.backend == "scipy"
    assert [m for m, _ in f.info["attempts"]] == ["cholmod", "cholmod_ldlt"]
    assert rel_err(f.solve(b), np.linalg.solve(A.toarray(), b)) < RTOL


def test_cholmod_without_fallback_raises(K_shifted):
    if "cholmod" not in BACKENDS:
        pytest.skip("scikit-sparse not installed")
    with pytest.raises(LinearSolverError, match="positive definite"):
        factorize(K_shifted[0], LinearSolverOptions("cholmod", fallback=False))


# ----------------------------------------------------------------------------- singular


def _assert_singular_message(exc):
    msg = str(exc.value)
    assert "singular" in msg
    assert "Dirichlet" in msg and "contact" in msg


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
def test_unsupported_body_is_singular(backend):
    K_free = cube_stiffness(3, clamp=False)  # 6 rigid body modes
    with pytest.raises(LinearSolverError) as exc:
        factorize(K_free, backend)
    _assert_singular_message(exc)


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
def test_direction_without_support_is_singular(backend):
    # Only u_x fixed on x = 0: translations in y, z and rotation about x stay free.
    n = 3
    K_free = cube_stiffness(n, clamp=False)
    keep = np.setdiff1d(np.arange(K_free.shape[0]), x0_face_dofs(n, components=(0,)))
    with pytest.raises(LinearSolverError) as exc:
        factorize(keep_dofs(K_free, keep), backend)
    _assert_singular_message(exc)


@pytest.mark.parametrize("backend", ["auto"] + BACKENDS)
@pytest.mark.parametrize("kind", ["empty", "explicit_zeros"])
def test_zero_row_is_singular(K, backend, kind):
    n = K.shape[0]
    if kind == "empty":  # an extra dof no element touches: no stored entry at all
        A = sp.block_diag([K, sp.csr_matrix((1, 1))], format="csr")
        bad = n
    else:  # row and column 17 stored but zero
        A = K.copy()
        rows = np.repeat(np.arange(n), np.diff(A.indptr))
        A.data[(rows == 17) | (A.indices == 17)] = 0.0
        assert A.nnz == K.nnz
        bad = 17
    with pytest.raises(LinearSolverError) as exc:
        factorize(A, backend)
    _assert_singular_message(exc)
    assert f"dofs {bad}" in str(exc.value)


def test_nan_in_matrix_or_rhs_raises(K, rhs):
    A = K.copy()
    A.data[5] = np.nan
    with pytest.raises(LinearSolverError, match="NaN"):
        factorize(A)
    f = factorize(K)
    b = rhs.copy()
    b[3] = np.inf
    with pytest.raises(LinearSolverError, match="right-hand side"):
        f.solve(b)


# ----------------------------------------------------------------------------- options / errors


@pytest.mark.parametrize(
    "kwargs, key",
    [
        (dict(backend="superlu"), "backend"),
        (dict(backend="Pardiso"), "backend"),
        (dict(pardiso_matrix_type="spd"), "pardiso_matrix_type"),
        (dict(singular_check="sometimes"), "singular_check"),
        (dict(pardiso_scaling="never"), "pardiso_scaling"),
        (dict(singular_rtol=2.0), "singular_rtol"),
        (dict(symmetric="yes"), "symmetric"),
        (dict(backend="cholmod", symmetric=False), "cholmod"),
    ],
)
def test_bad_options_raise_config_error(kwargs, key):
    with pytest.raises(ConfigError, match=key) as exc:
        LinearSolverOptions(**kwargs)
    if "backend" in kwargs and key == "backend":
        for allowed in ("'auto'", "'pardiso'", "'cholmod'", "'scipy'"):
            assert allowed in str(exc.value)


def test_bad_backend_string_in_factorize(K):
    with pytest.raises(ConfigError, match="backend"):
        factorize(K, "mumps")
    with pytest.raises(ConfigError):
        factorize(K, 42)


def test_options_are_frozen():
    opts = LinearSolverOptions()
    with pytest.raises(AttributeError):
        opts.backend = "scipy"


@pytest.mark.parametrize("missing", ["pardiso", "cholmod"])
def test_unavailable_backend_raises_clear_error(K, monkeypatch, missing):
    without(monkeypatch, missing)
    assert missing not in available_backends()
    with pytest.raises(LinearSolverError) as exc:
        factorize(K, missing)
    msg = str(exc.value)
    assert f"{missing!r} is not available" in msg and "pip install" in msg
    # auto still works with what is left: the fastest direct backend at this size
    assert factorize(K).backend == next(b for b in available_backends() if b != "petsc")


def test_bad_rhs_shape(K):
    f = factorize(K)
    with pytest.raises(ValueError, match="shape"):
        f.solve(np.ones(K.shape[0] + 1))


# ----------------------------------------------------------------------------- memory


@pytest.mark.parametrize("backend", BACKENDS)
def test_free_and_garbage_collection(K, rhs, backend):
    f = factorize(K, backend)
    f.solve(rhs)
    f.free()
    f.free()  # idempotent
    with pytest.raises(LinearSolverError, match="freed"):
        f.solve(rhs)
    with factorize(K, backend) as g:
        g.solve(rhs)
    with pytest.raises(LinearSolverError, match="freed"):
        g.solve(rhs)
    if backend == "pardiso":
        h = factorize(K, LinearSolverOptions(backend=backend, factor_reuse=False))
        fin = h._handle.finalizer
        assert fin.alive
        del h
        gc.collect()
        assert not fin.alive  # MKL memory released on collection (not kept for reuse)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="needs pypardiso")
def test_pardiso_reuses_the_analysis_of_a_freed_factor_of_the_same_pattern(K, rhs):
    linear.release_pardiso_pool()
    # every factorize factors (a kept factor would serve K2 without factoring: tests/solve/test_reuse.py)
    pardiso = LinearSolverOptions(backend="pardiso", factor_reuse=False)
    first = factorize(K, pardiso)
    assert not first.info["analysis_reused"]
    first.free()
    assert len(linear._PARDISO_POOL) == 1
    # same pattern, other values (a stiffer diagonal and a scaled matrix): numeric phase only
    K2 = (2.5 * K + sp.diags(np.linspace(1.0, 3.0, K.shape[0]))).tocsr()
    K2 = (K2 + sp.csr_matrix((np.zeros(K.nnz), K.indices, K.indptr), shape=K.shape)).tocsr()  # keep K's pattern
    second = factorize(K2, pardiso)
    assert second.info["analysis_reused"] and not linear._PARDISO_POOL
    x = second.solve(rhs)
    assert np.linalg.norm(K2 @ x - rhs) <= 1e-10 * np.linalg.norm(rhs)
    second.free()
    assert len(linear._PARDISO_POOL) == 1
    # another pattern is analysed afresh and replaces the kept one, released before the analysis
    # (its numeric factor would coexist with the new one: peak memory)
    K3 = sp.block_diag([K, sp.identity(3)]).tocsr()
    third = factorize(K3, pardiso)
    assert not third.info["analysis_reused"] and not linear._PARDISO_POOL
    third.free()
    assert len(linear._PARDISO_POOL) == 1 and linear._PARDISO_POOL[0].n == K3.shape[0]
    # opting out: nothing kept, nothing reused
    off = LinearSolverOptions(backend="pardiso", pardiso_reuse=False, factor_reuse=False)
    linear.release_pardiso_pool()
    factorize(K, off).free()
    assert not linear._PARDISO_POOL
    with pytest.raises(ConfigError, match="pardiso_reuse"):
        LinearSolverOptions(pardiso_reuse="yes")


def test_upper_triangle_stores_every_diagonal_entry(K_saddle):
    # Pardiso's symmetric types require the diagonal present even where zero.
    A, m = K_saddle
    A = sp.csr_matrix(A)
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    data, indptr, indices = linear._upper_with_diagonal(A, rows)
    U = sp.csr_matrix((data, indices, indptr), shape=A.shape)
    assert U.has_sorted_indices
    assert (indices[indptr[:-1]] == np.arange(A.shape[0])).all()  # diagonal first in each row
    assert U.nnz == sp.triu(A).nnz + m
    assert abs(U - sp.triu(A)).max() == 0


@pytest.mark.parametrize("backend", [b for b in BACKENDS if b != "cholmod"])
def test_non_symmetric_zero_column_is_singular(K, backend):
    A = K.tolil()
    A[:, 11] = 0.0  # row 11 keeps its entries, column 11 is empty
    with pytest.raises(LinearSolverError, match="dofs 11"):
        factorize(A.tocsr(), LinearSolverOptions(backend, symmetric=False))


def test_cholmod_singular_with_tiny_positive_pivots_is_caught():
    # On this mesh CHOLMOD's LL^T of the floating cube happens to "succeed"
    # (rigid-mode pivots ~1e-14 > 0): the pivot ratio must trigger the probe.
    if "cholmod" not in BACKENDS:
        pytest.skip("scikit-sparse not installed")
    K_free = cube_stiffness(8, clamp=False)
    with pytest.raises(LinearSolverError) as exc:
        factorize(K_free, LinearSolverOptions("cholmod", fallback=False))
    assert "singular" in str(exc.value) or "positive definite" in str(exc.value)


def test_pardiso_library_is_found_without_pypardisos_search(monkeypatch):
    """MKL's runtime is loaded from the install prefix (pypardiso's own search took 0.5 s per
    process); a wrong $PYPARDISO_MKL_RT is tried first and skipped."""
    import sys

    from contopt.solve.linear import pardiso

    if "pardiso" not in BACKENDS:
        pytest.skip("pardiso is not available here")
    if not pardiso._mkl_rt_paths():
        pytest.skip("no MKL runtime in this install prefix (pypardiso finds it elsewhere)")
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/nonexistent/libmkl_rt.so")
    assert pardiso._mkl_rt_paths()[0] == "/nonexistent/libmkl_rt.so"
    monkeypatch.delitem(sys.modules, "pypardiso", raising=False)
    pardiso.library.cache_clear()
    try:
        fn = pardiso.library()
        assert fn is not None and "pypardiso" not in sys.modules
    finally:
        pardiso.library.cache_clear()
    K = sp.csr_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    assert np.allclose(factorize(K, "pardiso").solve(np.array([1.0, 2.0])), np.linalg.solve(K.toarray(), [1, 2]))


def test_a_direct_factor_fits_by_the_n_to_the_four_thirds_estimate():
    from contopt.solve.linear import base

    # calibrated on the xl die-slab: 5.9 GB at 336,141 rows; eight times the rows, 16 times the bytes
    assert base.direct_factor_bytes(336_141) == pytest.approx(5.9e9)
    assert base.direct_factor_bytes(8 * 336_141) == pytest.approx(16 * 5.9e9)
    assert base.direct_fits(336_141, available=int(5.9e9 / base.FACTOR_MEMORY_SHARE) + 1)
    assert not base.direct_fits(336_141, available=int(5.9e9 / base.FACTOR_MEMORY_SHARE) - 1)
    assert base.memory_available() is None or base.memory_available() > 0
