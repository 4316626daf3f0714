"""A direct factor kept as the preconditioner of the next matrices (``factor_reuse``): the GMRES
that uses it, when it is used and when the matrix is factored after all, and Newton's answer."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from _elasticity import cube_stiffness

from contopt.solve.linear import LinearSolverOptions, factorize, reuse

REUSE = LinearSolverOptions(factor_reuse=True)


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


@pytest.mark.parametrize("enforcement", ["penalty", "alm"])
def test_newton_with_a_kept_factor_reaches_the_same_state(enforcement):
    from contopt.adjoint.check import TIGHT_AUGMENTATION
    from contopt.cases.two_blocks import two_blocks
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(two_blocks(enforcement=enforcement, body_force=(0.0, 0.0, -0.05)))
    newton = NewtonOptions(rtol=1e-11, n_steps=3)
    aug = TIGHT_AUGMENTATION if enforcement == "alm" else None
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
