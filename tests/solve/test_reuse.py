"""A direct factor kept as the preconditioner of the next matrices (``factor_reuse``): the GMRES
that uses it, when it is used and when the matrix is factored after all, and Newton's answer; and a
single-precision Pardiso factor (``factor_precision="single"``), float32 as GMRES's preconditioner
for float64 answers to the tolerance asked, factored again in double where it does not solve."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from _elasticity import cube_stiffness

from contopt.errors import ConfigError
from contopt.solve.linear import LinearSolverOptions, available_backends, factorize, reuse

REUSE = LinearSolverOptions(factor_reuse=True)
SINGLE = LinearSolverOptions(backend="pardiso", factor_precision="single")
needs_pardiso = pytest.mark.skipif("pardiso" not in available_backends(), reason="needs MKL Pardiso")


@pytest.fixture(autouse=True)
def fresh():
    reuse.release_kept()
    yield
    reuse.release_kept()


def _relative_residual(K, x, b) -> float:
    return float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))


def test_gmres_converges_with_a_good_preconditioner_and_gives_up_early_with_a_poor_one():
    K = cube_stiffness(3)
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    exact = sp.linalg.factorized(K.tocsc())
    x, its, ok = reuse.gmres(lambda v: K @ v, exact, b, rtol=1e-12, max_iter=5)
    assert ok and its == 1 and _relative_residual(K, x, b) <= 1e-12
    # the inverse of a nearby matrix: a few iterations, converged on the true residual
    near = sp.linalg.factorized((K + 1e-3 * K.diagonal().mean() * sp.identity(K.shape[0])).tocsc())
    x, its, ok = reuse.gmres(lambda v: K @ v, near, b, rtol=1e-10, max_iter=8)
    assert ok and 1 < its <= 8 and _relative_residual(K, x, b) <= 1e-10
    # Jacobi on elasticity: far from 1e-10 in 8 iterations, and seen to be so before the 8th
    jacobi = 1.0 / K.diagonal()
    x, its, ok = reuse.gmres(lambda v: K @ v, lambda v: jacobi * v, b, rtol=1e-10, max_iter=8)
    assert not ok and its < 8 and _relative_residual(K, x, b) > 1e-10


def test_a_nearby_matrix_is_solved_with_the_kept_factor_to_the_tolerance_asked():
    K = cube_stiffness(4)
    b = np.random.default_rng(1).standard_normal(K.shape[0])
    f = factorize(K, REUSE)
    assert not f.info["factor_reused"] and not f.iterative
    np.testing.assert_allclose(f.solve(b), sp.linalg.spsolve(K.tocsc(), b), rtol=1e-9, atol=0)
    f.free()
    # a Newton iteration later: the values moved a little (the contact rows, a small increment)
    near = (K + sp.diags(np.linspace(0.0, 1e-3, K.shape[0])) * K.diagonal().mean()).tocsr()
    stats = dict(reuse.STATISTICS)
    g = factorize(near, REUSE)
    assert g.info["factor_reused"] and g.iterative
    for rtol in (1e-4, 1e-11):
        x = g.solve(b, rtol=rtol)
        assert _relative_residual(near, x, b) <= rtol
    assert reuse.STATISTICS["refactored"] == stats["refactored"]
    assert 1 <= g.info["iterations"][-1] <= REUSE.factor_reuse_max_iter
    g.free()


def test_a_far_matrix_is_factored_after_all_and_solved_exactly():
    K = cube_stiffness(4)
    b = np.random.default_rng(2).standard_normal(K.shape[0])
    factorize(K, REUSE).free()
    E = np.random.default_rng(3).uniform(1e-3, 1.0, 4**3)  # another design: stiffness per cell x 1000
    far = cube_stiffness(4, E=E)
    refactored = reuse.STATISTICS["refactored"]
    g = factorize(far, REUSE)
    x = g.solve(b, rtol=1e-6)
    assert reuse.STATISTICS["refactored"] == refactored + 1
    assert not g.iterative and not g.info["factor_reused"]
    assert _relative_residual(far, x, b) <= 1e-12  # the new factor's answer, better than asked
    g.free()
    # the kept factor is now far's own: the next solve of far takes one iteration
    h = factorize(far, REUSE)
    h.solve(b, rtol=1e-10)
    assert h.info["iterations"] == [1]
    h.free()


def test_a_refactorization_that_fails_raises_and_keeps_no_freed_factor():
    from contopt.errors import LinearSolverError

    K = cube_stiffness(3)
    b = np.ones(K.shape[0])
    factorize(K, REUSE).free()
    far = cube_stiffness(3, E=np.random.default_rng(5).uniform(1e-3, 1.0, 27))
    g = factorize(far, REUSE)

    def singular(double=False):
        raise LinearSolverError("singular")

    g._refactor = singular  # what a singular matrix does to the refactorization
    with pytest.raises(LinearSolverError, match="singular"):
        g.solve(b, rtol=1e-12)
    with pytest.raises(LinearSolverError, match="could not be factored"):
        g.solve(b)
    g.free()
    assert not reuse._KEPT  # the freed factor is not handed to the next matrix
    h = factorize(K, REUSE)
    assert _relative_residual(K, h.solve(b), b) <= 1e-12
    h.free()


def test_off_by_default():
    assert not LinearSolverOptions().factor_reuse


def test_another_size_or_a_factorization_without_reuse_releases_the_kept_factor():
    K = cube_stiffness(3)
    factorize(K, REUSE).free()
    assert len(reuse._KEPT) == 1
    g = factorize(cube_stiffness(4), REUSE)  # other rows: the kept factor cannot serve
    assert not g.info["factor_reused"] and len(reuse._KEPT) == 0
    g.free()
    assert len(reuse._KEPT) == 1 and reuse._KEPT[0][0].shape[0] == g.shape[0]
    h = factorize(cube_stiffness(4), LinearSolverOptions(factor_reuse=False))  # the adjoint's way
    assert len(reuse._KEPT) == 0
    h.free()
    assert len(reuse._KEPT) == 0


def test_several_right_hand_sides_with_the_kept_factor():
    K = cube_stiffness(3)
    B = np.random.default_rng(4).standard_normal((K.shape[0], 3))
    factorize(K, REUSE).free()
    near = (1.001 * K).tocsr()
    g = factorize(near, REUSE)
    X = g.solve(B, rtol=1e-10)
    assert X.shape == B.shape
    for j in range(3):
        assert _relative_residual(near, X[:, j], B[:, j]) <= 1e-10
    g.free()


@pytest.mark.parametrize("law", ["penalty", "alm"])
def test_newton_with_a_kept_factor_reaches_the_same_state(law):
    from contopt.adjoint.check import TIGHT_AUGMENTATION
    from contopt.cases.two_blocks import two_blocks
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(two_blocks(law=law, body_force=(0.0, 0.0, -0.05)))
    newton = NewtonOptions(rtol=1e-11, n_steps=3)
    aug = TIGHT_AUGMENTATION if law == "alm" else None
    states = {}
    for flag in (False, True):
        reused = reuse.STATISTICS["reused"]
        linear = LinearSolverOptions(factor_reuse=flag)
        states[flag] = solve_static(system, newton=newton, linear=linear, augmentation=aug)
        assert (reuse.STATISTICS["reused"] > reused) == flag
    ref, got = states[False], states[True]
    assert got.contact[0].n_active == ref.contact[0].n_active > 0
    # both stop at |r| <= 1e-11 |f|: the states differ by that over the smallest stiffness
    np.testing.assert_allclose(got.u, ref.u, atol=1e-7 * np.abs(ref.u).max())


@needs_pardiso
def test_a_single_factor_solves_to_the_tolerance_asked_in_float64():
    K = cube_stiffness(5)
    b = np.random.default_rng(2).standard_normal(K.shape[0])
    f = factorize(K, SINGLE)
    assert f.iterative and "single precision" in f.info["method"] and f.info["method"].startswith("GMRES")
    x = f.solve(b)  # no tolerance given: krylov_rtol (1e-10)
    assert x.dtype == np.float64 and _relative_residual(K, x, b) <= SINGLE.krylov_rtol
    # float32 alone is far from it: the GMRES iterations are what make the answer float64's
    assert 2 <= f.info["iterations"][-1] <= SINGLE.factor_reuse_max_iter
    loose = f.solve(b, rtol=1e-3)
    assert _relative_residual(K, loose, b) <= 1e-3 and f.info["iterations"][-1] < f.info["iterations"][-2]
    f.free()
    assert not reuse._KEPT  # factor_reuse is off: nothing is kept


@needs_pardiso
def test_a_matrix_the_single_factor_does_not_solve_is_factored_in_double():
    # one GMRES iteration with a float32 factor reaches about 1e-7, not 1e-12: the matrix is factored
    # again in double, which solves it exactly
    K = cube_stiffness(4)
    b = np.random.default_rng(3).standard_normal(K.shape[0])
    refactored = reuse.STATISTICS["refactored"]
    f = factorize(K, replace(SINGLE, factor_reuse_max_iter=1))
    assert "single precision" in f.info["method"]
    x = f.solve(b, rtol=1e-12)
    assert reuse.STATISTICS["refactored"] == refactored + 1
    assert "single precision" not in f.info["method"] and not f.iterative
    assert _relative_residual(K, x, b) <= 1e-12
    f.free()


@needs_pardiso
def test_a_kept_single_factor_preconditions_the_next_matrix():
    options = LinearSolverOptions(backend="pardiso", factor_precision="single", factor_reuse=True)
    K = cube_stiffness(4)
    b = np.random.default_rng(4).standard_normal(K.shape[0])
    f = factorize(K, options)
    assert not f.info["factor_reused"] and f.iterative
    f.solve(b)
    f.free()
    assert reuse._KEPT and reuse._KEPT[0][0].approximate  # the float32 factor, handed on
    near = (K + sp.diags(np.linspace(0.0, 1e-3, K.shape[0])) * K.diagonal().mean()).tocsr()
    refactored = reuse.STATISTICS["refactored"]
    g = factorize(near, options)
    assert g.info["factor_reused"] and "earlier" in g.info["method"]
    x = g.solve(b, rtol=1e-10)
    assert _relative_residual(near, x, b) <= 1e-10 and reuse.STATISTICS["refactored"] == refactored
    g.free()


@needs_pardiso
def test_a_single_factor_is_not_pooled_for_a_double_one():
    from contopt.solve.linear import pardiso

    K = cube_stiffness(3)
    pardiso.release_pardiso_pool()
    factorize(K, SINGLE).free()
    double = factorize(K, LinearSolverOptions(backend="pardiso"))
    # the single factor's analysis is kept, but a double factorization does not take it
    assert not double.info["analysis_reused"] and "single" not in double.info["method"]
    double.free()
    again = factorize(K, SINGLE)
    assert "single precision" in again.info["method"]
    again.free()
    pardiso.release_pardiso_pool()


def test_factor_precision_is_validated():
    with pytest.raises(ConfigError, match="factor_precision"):
        LinearSolverOptions(factor_precision="half")


@needs_pardiso
def test_newton_and_the_adjoint_with_a_single_factor_give_the_double_answer():
    from contopt.adjoint.check import TIGHT_AUGMENTATION
    from contopt.adjoint.sensitivity import sensitivities
    from contopt.cases.two_blocks import two_blocks
    from contopt.responses import StrainEnergy
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(two_blocks(law="alm", body_force=(0.0, 0.0, -0.05)))
    newton = NewtonOptions(rtol=1e-11, n_steps=3)
    out = {}
    for precision in ("double", "single"):
        linear = LinearSolverOptions(backend="pardiso", factor_precision=precision, factor_reuse=True)
        state = solve_static(system, newton=newton, linear=linear, augmentation=TIGHT_AUGMENTATION)
        grad = sensitivities(system, state, [StrainEnergy()], linear=linear).sensitivities[0].gradient
        out[precision] = (state, grad)
    (ref, g_ref), (got, g_got) = out["double"], out["single"]
    assert got.contact[0].n_active == ref.contact[0].n_active > 0
    # both stop at |r| <= 1e-11 |f|: the states differ by that over the smallest stiffness
    np.testing.assert_allclose(got.u, ref.u, atol=1e-7 * np.abs(ref.u).max())
    np.testing.assert_allclose(g_got, g_ref, rtol=1e-6, atol=1e-6 * np.abs(g_ref).max())


def test_norm_inf_of_a_csr_matrix_a_block_of_rows_at_a_time():
    from contopt.solve.linear.reuse import norm_inf

    rng = np.random.default_rng(5)
    K = sp.random(50, 50, density=0.1, random_state=rng, format="lil")
    K = sp.csr_matrix(K.multiply(rng.choice([-1.0, 1.0], size=K.shape)))
    keep = np.ones(50)
    keep[[0, 1, 2, 49]] = 0.0  # empty rows: the first, and the last (in the last block)
    K = (sp.diags(keep) @ K).tocsr()
    K.eliminate_zeros()
    assert np.diff(K.indptr)[[0, 49]].max() == 0
    for rows in (1, 7, 64):
        assert norm_inf(K, rows_per_pass=rows) == pytest.approx(abs(K).sum(axis=1).max(), rel=1e-14)


@needs_pardiso
def test_a_tolerance_below_round_off_is_met_at_round_off_not_by_a_double_factor():
    # a penalty 1e6 times the stiffness (a grown contact penalty): 1e-15 is below what float64
    # resolves for this matrix; GMRES with the single factor stops at round-off and that stands
    K = cube_stiffness(4)
    n = K.shape[0]
    w = sp.csr_matrix(([1.0, -1.0], ([0, 0], [0, n - 3])), shape=(1, n))
    K = (K + 1e6 * K.diagonal().max() * (w.T @ w)).tocsr()
    b = np.random.default_rng(6).standard_normal(n)
    refactored = reuse.STATISTICS["refactored"]
    f = factorize(K, SINGLE)
    x = f.solve(b, rtol=1e-15)
    assert reuse.STATISTICS["refactored"] == refactored and f.iterative
    assert np.linalg.norm(K @ x - b) > 1e-15 * np.linalg.norm(b)  # the tolerance itself was not met
    r = np.abs(K @ x - b).max()
    assert r <= 10 * np.finfo(float).eps * abs(K).sum(axis=1).max() * np.abs(x).max()
    f.free()
