"""A single-precision Pardiso factor (``factor_precision="single"``): float32 factors as GMRES's
preconditioner, float64 answers to the tolerance asked, and a factorization in double where the
single one does not solve."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from _elasticity import cube_stiffness

from contopt.errors import ConfigError
from contopt.solve.linear import LinearSolverOptions, available_backends, factorize, reuse

pytestmark = pytest.mark.skipif("pardiso" not in available_backends(), reason="needs MKL Pardiso")

SINGLE = LinearSolverOptions(backend="pardiso", factor_precision="single")


@pytest.fixture(autouse=True)
def fresh():
    reuse.release_kept()
    yield
    reuse.release_kept()


def _relative_residual(K, x, b) -> float:
    return float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))


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


def test_newton_and_the_adjoint_with_a_single_factor_give_the_double_answer():
    from contopt.adjoint.check import TIGHT_AUGMENTATION
    from contopt.adjoint.sensitivity import sensitivities
    from contopt.cases.two_blocks import two_blocks
    from contopt.responses import StrainEnergy
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(two_blocks(enforcement="alm", body_force=(0.0, 0.0, -0.05)))
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
