"""The iterative backend (CG + GAMG through PETSc): known answers, the near-null space, reuse of the
preconditioner, the fallback to a factorization, ``"auto"``, and beside the system's BLAS."""

from __future__ import annotations

import logging
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from _elasticity import cube_stiffness, x0_face_dofs

from contopt.solve import linear
from contopt.solve.linear import Geometry, LinearSolverOptions, available_backends, choice, factorize
from contopt.solve.linear import petsc as petsc_backend

pytestmark = pytest.mark.skipif(
    "petsc" not in available_backends(),
    reason="PETSc is not installed (pip install contopt[petsc], Python 3.12+): " + linear.why_unavailable("petsc"),
)

N = 8  # 8^3 cells, 2,187 free dofs
# The stop is on the recursively updated residual; the true one drifts from it by round-off
# (~1e-14 relative here), far below this factor of the tolerance.
DRIFT = 10.0


def cube(n: int = N, contrast: float = 1.0, seed: int = 0):
    """Clamped cube stiffness (free x free), its Geometry and a load; E in [contrast, 1] per cell."""
    rng = np.random.default_rng(seed)
    E = np.where(rng.uniform(size=n**3) < 0.5, contrast, 1.0) if contrast != 1.0 else rng.uniform(0.5, 2.0, n**3)
    K = cube_stiffness(n, E=E)
    g = np.linspace(0.0, 1.0, n + 1)
    points = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).transpose(2, 1, 0, 3).reshape(-1, 3)
    free = np.setdiff1d(np.arange(3 * (n + 1) ** 3), x0_face_dofs(n))
    b = rng.standard_normal(K.shape[0])
    return K, Geometry(points=points, free=free), b


def residual(K, x, b) -> float:
    return float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))


@pytest.fixture(autouse=True)
def fresh():
    petsc_backend.release_kept()
    yield
    petsc_backend.release_kept()


def test_the_node_ordering_of_the_fixture_is_the_cube_s():
    # x0_face_dofs says which nodes sit at x = 0: the points built here must agree
    K, geo, _ = cube()
    clamped = np.setdiff1d(np.arange(geo.n_dofs), geo.free)[::3] // 3
    assert np.all(geo.points[clamped, 0] == 0.0) and clamped.size == (N + 1) ** 2


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_solves_to_the_tolerance_asked(rtol):
    K, geo, b = cube()
    f = factorize(K, "petsc", geo)
    assert f.backend == "petsc" and f.iterative
    x = f.solve(b, rtol=rtol)
    assert residual(K, x, b) <= DRIFT * rtol
    assert residual(K, x, b) > 1e-3 * rtol or rtol == 1e-10  # it stopped at the tolerance, not far below
    X = f.solve(np.column_stack([b, 2 * b]))  # default tolerance, several right-hand sides
    assert residual(K, X[:, 1], 2 * b) <= DRIFT * LinearSolverOptions().krylov_rtol
    f.free()


def test_a_solve_starts_from_the_guess_and_keeps_the_right_hand_side_s_tolerance():
    K, geo, b = cube()
    f = factorize(K, "petsc", geo)
    x = f.solve(b, rtol=1e-10)
    f.solve(b, rtol=1e-8)
    from_zero = f.info["iterations"][-1]
    # the answer as the guess: nothing to do (PETSc tests |K x - b| <= rtol |b| from the guess on)
    again = f.solve(b, rtol=1e-8, x0=x)
    assert f.info["iterations"][-1] == 0 and np.array_equal(again, x)
    # a guess far off still ends at the tolerance relative to |b|, not to the guess's residual
    far = f.solve(b, rtol=1e-8, x0=x + 10.0 * np.abs(x).max())
    assert residual(K, far, b) <= DRIFT * 1e-8 and f.info["iterations"][-1] > 0
    # the next solve without a guess starts from zero again
    f.solve(b, rtol=1e-8)
    assert f.info["iterations"][-1] == from_zero > 0
    f.free()


def test_black_and_white_contrast_converges():
    # SIMP voids at 1e-6 of the solid (the paper's floor 1e-2 is easier)
    K, geo, b = cube(contrast=1e-6, seed=1)
    f = factorize(K, "petsc", geo)
    x = f.solve(b, rtol=1e-8)
    assert residual(K, x, b) <= DRIFT * 1e-8
    assert f.info["fallback_from"] is None


def test_rigid_body_modes_cut_the_iterations():
    K, geo, b = cube()
    with_modes = factorize(K, "petsc", geo)
    with_modes.solve(b, rtol=1e-8)
    its_modes = with_modes.info["iterations"][0]
    with_modes.free()
    petsc_backend.release_kept()
    blind = factorize(K, "petsc", Geometry(points=np.zeros_like(geo.points), free=geo.free))
    blind.solve(b, rtol=1e-8)
    assert its_modes < blind.info["iterations"][0]


def test_preconditioner_kept_for_the_same_pattern_and_rebuilt_when_iterations_grow():
    K, geo, b = cube()
    stats = petsc_backend.STATISTICS
    f = factorize(K, "petsc", geo)
    f.solve(b)
    f.free()
    setups = stats["setups"]
    g = factorize(1.01 * K, "petsc", geo)  # a Newton iteration later: values change a little
    assert g.info["preconditioner_reused"]
    x = g.solve(b, rtol=1e-10)
    assert residual(1.01 * K, x, b) <= DRIFT * 1e-10
    g.free()
    assert stats["setups"] == setups
    # a very different matrix of the same pattern: the old hierarchy costs iterations, then is rebuilt
    D = sp.diags(np.random.default_rng(2).uniform(0.01, 1.0, K.shape[0]))
    K2 = (D @ K @ D).tocsr()
    h = factorize(K2, LinearSolverOptions(backend="petsc", reuse_growth=1.0), geo)
    h.solve(b)
    h.free()
    k = factorize(K2, "petsc", geo)
    assert not k.info["preconditioner_reused"]
    k.solve(b)
    assert stats["setups"] == setups + 1
    k.free()


def _swappable_couplings(K):
    """Distinct dofs i, j, k, l with K_ij and K_kl stored and K_il, K_kj not."""
    rows, cols = K.nonzero()
    stored = set(zip(rows.tolist(), cols.tolist()))
    pairs = [(a, c) for a, c in stored if a < c]
    for i, j in sorted(pairs):
        for k, l in sorted(pairs):
            if len({i, j, k, l}) == 4 and (i, l) not in stored and (k, j) not in stored:
                return i, j, k, l
    raise AssertionError("no two couplings to swap")


def test_the_operator_is_kept_for_the_same_pattern_and_made_anew_for_another():
    """A kept operator is recognized by its pattern's digest: new values on the same pattern reuse
    it, a pattern with the same entries a row but other columns gets a new one."""
    K, geo, b = cube()
    stats = petsc_backend.STATISTICS
    f = factorize(K, "petsc", geo)
    f.solve(b)
    f.free()
    reused = stats["reused"]
    g = factorize(2.0 * K, "petsc", geo)
    x = g.solve(b, rtol=1e-10)
    g.free()
    assert stats["reused"] == reused + 1 and residual(2.0 * K, x, b) <= DRIFT * 1e-10
    # the same count of stored entries in every row (indptr unchanged), two coupling pairs swapped
    # partners: (i, j) and (k, l) become (i, l) and (k, j), as contact pairs do between iterations
    i, j, k, l = _swappable_couplings(K)
    C = K.tolil()
    for (a, c), (a2, c2) in (((i, j), (i, l)), ((k, l), (k, j))):
        C[a2, c2] = C[c2, a2] = C[a, c]
        C[a, c] = C[c, a] = 0.0
    C = C.tocsr()
    C.eliminate_zeros()
    assert np.array_equal(C.indptr, K.indptr) and not np.array_equal(C.indices, K.indices)
    h = factorize(C, "petsc", geo)
    x = h.solve(b, rtol=1e-10)
    h.free()
    assert stats["reused"] == reused + 1 and residual(C, x, b) <= DRIFT * 1e-10


def test_a_solve_the_amg_cannot_do_switches_to_a_kept_mumps_factorization(caplog):
    K, geo, b = cube()
    opts = LinearSolverOptions(backend="petsc", krylov_max_iter=1)  # CG + GAMG cannot reach 1e-12 in one
    switches = petsc_backend.STATISTICS["switches"]
    f = factorize(K, opts, geo)
    with caplog.at_level(logging.WARNING, logger="contopt.solve.linear"):
        x = f.solve(b, rtol=1e-12)
    # GMRES preconditioned with the matrix's own factor converges in one iteration
    assert residual(K, x, b) <= DRIFT * 1e-12
    assert f.info["fallback_from"] is None and f.info["method"].startswith("GMRES + MUMPS")
    assert petsc_backend.STATISTICS["switches"] == switches + 1
    assert any("MUMPS factorization from now on" in r.getMessage() for r in caplog.records)
    f.free()
    # the next matrix (a Newton iteration later) keeps the factorization as its preconditioner
    near = (K + sp.diags(np.full(K.shape[0], 1e-3 * K.diagonal().mean()))).tocsr()
    g = factorize(near, LinearSolverOptions(backend="petsc"), geo)
    assert g.info["preconditioner_reused"] and g.info["method"].startswith("GMRES + MUMPS")
    x = g.solve(b, rtol=1e-10)
    assert residual(near, x, b) <= DRIFT * 1e-10 and 1 < g.info["iterations"][0] <= 10
    g.free()


def test_mumps_preconditioner_is_kept_while_it_needs_few_iterations_then_refactored():
    K, geo, b = cube()
    opts = LinearSolverOptions(backend="petsc", preconditioner="mumps")
    setups = petsc_backend.STATISTICS["setups"]
    for scale, reused in ((1.0, False), (1.5, True)):  # a multiple of K: one iteration with K's factor
        f = factorize(scale * K, opts, geo)
        x = f.solve(b, rtol=1e-10)
        assert residual(scale * K, x, b) <= DRIFT * 1e-10
        assert f.info["preconditioner_reused"] == reused and f.info["iterations"] == [1]
        f.free()
    assert petsc_backend.STATISTICS["setups"] == setups + 1
    # a different matrix on the same dofs: K's factor needs more than FACTOR_REFACTOR_ITER
    # iterations (or fails within FACTOR_MAX_ITER and is refactored at once)
    K2, _, _ = cube(seed=5)
    f = factorize(K2, opts, geo)
    x = f.solve(b, rtol=1e-10)
    assert residual(K2, x, b) <= DRIFT * 1e-10
    f.free()
    assert f.info["iterations"][0] > 1
    g = factorize(K2, opts, geo)
    x = g.solve(b, rtol=1e-10)
    assert petsc_backend.STATISTICS["setups"] == setups + 2  # K2 factored once, by f's retry or for g
    assert g.info["iterations"] == [1] and residual(K2, x, b) <= DRIFT * 1e-10
    g.free()


def test_gmres_with_a_stale_factorization_gives_up_early_and_refactors():
    K, geo, b = cube()
    opts = LinearSolverOptions(backend="petsc", preconditioner="mumps")
    f = factorize(K, opts, geo)
    f.solve(b)  # builds K's factor, which is kept
    f.free()
    D = sp.diags(np.random.default_rng(2).uniform(0.01, 1.0, K.shape[0]))
    far = (D @ K @ D).tocsr()  # K's factor is a poor preconditioner of this one
    retries = petsc_backend.STATISTICS["retries"]
    f = factorize(far, opts, geo)
    x = f.solve(b, rtol=1e-10)
    assert residual(far, x, b) <= DRIFT * 1e-10
    first, second = f.info["iterations"]
    # the stale factor's attempt stopped well before the limit; the fresh one needs one iteration
    assert first < petsc_backend.FACTOR_MAX_ITER and second == 1
    assert petsc_backend.STATISTICS["retries"] == retries + 1
    f.free()


def test_without_mumps_a_solve_that_cannot_converge_falls_back_to_a_factorization(caplog, monkeypatch):
    monkeypatch.setattr(petsc_backend.PetscSolve, "_mumps", lambda self: False)
    K, geo, b = cube()
    opts = LinearSolverOptions(backend="petsc", krylov_max_iter=1)
    f = factorize(K, opts, geo)
    with caplog.at_level(logging.WARNING, logger="contopt.solve.linear"):
        x = f.solve(b, rtol=1e-12)
    assert residual(K, x, b) < 1e-10  # the factorization's answer
    assert f.info["fallback_from"] == "petsc"
    assert any("direct factorization" in r.getMessage() for r in caplog.records)
    f.free()


def test_a_mumps_failure_on_a_later_refactorization_falls_back_with_contopts_message(caplog, monkeypatch):
    K, geo, b = cube()
    opts = LinearSolverOptions(backend="petsc", preconditioner="mumps")
    f = factorize(K, opts, geo)
    f.solve(b)  # K's factor is built and kept
    f.free()
    PETSc = petsc_backend.load()
    real = petsc_backend._Solver.rebuild

    def mumps_fails(self, P):  # the next factorization fails, as MUMPS does out of workspace
        if self.factored:
            raise PETSc.Error(76)
        return real(self, P)

    monkeypatch.setattr(petsc_backend._Solver, "rebuild", mumps_fails)
    D = sp.diags(np.random.default_rng(2).uniform(0.01, 1.0, K.shape[0]))
    far = (D @ K @ D).tocsr()  # K's kept factor does not do: it must be refactored
    fallbacks = petsc_backend.STATISTICS["fallbacks"]
    g = factorize(far, opts, geo)
    with caplog.at_level(logging.WARNING, logger="contopt.solve.linear"):
        x = g.solve(b, rtol=1e-10)
    assert residual(far, x, b) < 1e-10  # the serial direct factorization's answer
    assert g.info["fallback_from"] == "petsc" and petsc_backend.STATISTICS["fallbacks"] == fallbacks + 1
    assert any("MUMPS could not factor" in r.getMessage() for r in caplog.records)
    g.free()
    # a distributed run has no direct solver: contopt's message names the failure and what to do
    monkeypatch.setattr(type(g._solver.comm), "distributed", property(lambda self: True))
    with pytest.raises(linear.LinearSolverError, match="MUMPS could not factor this .*contopt_mat_mumps_icntl_14"):
        g._fall_back(b, 0, 0, mumps_failed="error code 76")


def test_auto_takes_the_iterative_solver_from_the_threshold_on_and_only_with_a_geometry():
    K, geo, b = cube()
    small = LinearSolverOptions(iterative_above=K.shape[0] + 1)
    large = LinearSolverOptions(iterative_above=K.shape[0])
    assert factorize(K, small, geo).backend != "petsc"
    assert factorize(K, large, geo).backend == "petsc"
    assert factorize(K, large).backend != "petsc"  # no rigid-body modes without the geometry


def _trial_set_up(monkeypatch):
    """The cube as a contact tangent whose direct factor fits, with a trial from its size on."""
    K, geo, b = cube()
    contact = Geometry(points=geo.points, free=geo.free, contact=True)
    monkeypatch.setattr(linear.base, "memory_available", lambda: 2**40)
    choice.forget()
    return K, contact, b, LinearSolverOptions(trial_above=K.shape[0])


def test_auto_keeps_the_amg_on_a_contact_tangent_where_it_beats_the_factor(monkeypatch):
    K, contact, b, opts = _trial_set_up(monkeypatch)
    for _ in range(choice.DIRECT_MATRICES):
        f = factorize(K, opts, contact)
        assert f.backend != "petsc"  # the first matrices: the yardstick
        f.free()
    record = choice.choice_for(opts, K.shape[0], contact, amg_available=lambda: True)
    assert record.verdict == "trial" and record.direct_seconds > 0.0
    record.direct_seconds = 1e3  # a factorization far slower than the AMG's solves
    for _ in range(choice.TRIAL_MATRICES):
        g = factorize(K, opts, contact)
        assert g.backend == "petsc"
        assert residual(K, g.solve(b, rtol=1e-10), b) < DRIFT * 1e-10
        g.free()
    assert record.verdict == "amg" and len(record.amg_seconds) == choice.TRIAL_MATRICES
    assert factorize(K, opts, contact).backend == "petsc"


def test_auto_goes_back_to_the_factor_when_the_amg_runs_past_its_trial_time(caplog, monkeypatch):
    K, contact, b, opts = _trial_set_up(monkeypatch)
    for _ in range(choice.DIRECT_MATRICES):
        factorize(K, opts, contact).free()
    record = choice.choice_for(opts, K.shape[0], contact, amg_available=lambda: True)
    record.direct_seconds = 1e-9  # no AMG solve is that fast: stopped after its first iteration
    g = factorize(K, opts, contact)
    assert g.backend == "petsc"
    with caplog.at_level(logging.INFO, logger="contopt.solve.linear"):
        x = g.solve(b, rtol=1e-12)
    assert residual(K, x, b) < 1e-10 and g.info["fallback_from"] == "petsc"  # the factor solved it
    assert g.info["iterations"] == [1]  # no retry, no switch to MUMPS
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]  # a trial lost is no warning
    g.free()
    assert record.verdict == "direct"
    assert not petsc_backend.kept_solvers()  # its operator and hierarchy freed
    assert factorize(K, opts, contact).backend != "petsc"


def test_auto_decides_by_size_where_there_is_no_trial(monkeypatch):
    K, contact, _, opts = _trial_set_up(monkeypatch)
    n = K.shape[0]
    plain = Geometry(points=contact.points, free=contact.free)
    assert choice.choice_for(opts, n, plain, amg_available=lambda: True) is None  # no contact
    assert choice.choice_for(replace(opts, trial_above=n + 1), n, contact, amg_available=lambda: True) is None
    assert choice.choice_for(replace(opts, factor_reuse=True), n, contact, amg_available=lambda: True) is None
    assert choice.choice_for(replace(opts, backend="pardiso"), n, contact, amg_available=lambda: True) is None
    assert choice.choice_for(opts, n, contact, amg_available=lambda: False) is None
    need = linear.base.direct_factor_bytes(n)
    monkeypatch.setattr(linear.base, "memory_available", lambda: int(need))  # the factor does not fit
    assert choice.choice_for(opts, n, contact, amg_available=lambda: True) is None
    assert factorize(K, replace(opts, iterative_above=n), contact).backend == "petsc"  # the size rule
    assert factorize(K, replace(opts, iterative_above=n + 1), contact).backend != "petsc"


def test_auto_goes_to_a_direct_factor_before_mumps_and_stays_there(caplog, monkeypatch):
    K, geo, b = cube()
    monkeypatch.setattr(linear.base, "memory_available", lambda: 2**40)
    opts = LinearSolverOptions(iterative_above=K.shape[0], krylov_max_iter=1)  # the AMG cannot do it in one
    switches, fallbacks = petsc_backend.STATISTICS["switches"], petsc_backend.STATISTICS["fallbacks"]
    f = factorize(K, opts, geo)
    assert f.backend == "petsc"
    with caplog.at_level(logging.WARNING, logger="contopt.solve.linear"):
        x = f.solve(b, rtol=1e-12)
    assert residual(K, x, b) < 1e-10 and f.info["fallback_from"] == "petsc"
    assert petsc_backend.STATISTICS["switches"] == switches  # no MUMPS
    f.free()
    # the next matrix on the same dofs (a Newton iteration later) is factored at once
    near = (K + sp.diags(np.full(K.shape[0], 1e-3 * K.diagonal().mean()))).tocsr()
    g = factorize(near, opts, geo)
    assert g.backend != "petsc" and residual(near, g.solve(b), b) < 1e-10
    assert petsc_backend.STATISTICS["fallbacks"] == fallbacks + 2
    g.free()
    # an explicit petsc backend keeps PETSc's own switch to MUMPS
    h = factorize(K, LinearSolverOptions(backend="petsc", krylov_max_iter=1), geo)
    h.solve(b, rtol=1e-12)
    assert h.info["method"].startswith("GMRES + MUMPS")
    h.free()


def test_loads_beside_cholmod_and_ipopt_in_either_order():
    # the wheel's OpenBLAS and the system's share a name (see contopt.solve.linear.petsc_install)
    code = (
        "import importlib, sys\n"
        "for m in sys.argv[1:]:\n"
        "    try:\n"
        "        importlib.import_module(m)\n"
        "    except ModuleNotFoundError:\n"
        "        pass\n"
        "from contopt.solve.linear import petsc\n"
        "petsc.load()\n"
        "print('ok')\n"
    )
    for first in (["sksparse.cholmod", "cyipopt"], []):
        out = subprocess.run([sys.executable, "-c", code, *first], capture_output=True, text=True, timeout=120)
        assert out.stdout.strip() == "ok", out.stderr[-2000:]
    code_after = "from contopt.solve.linear import petsc\npetsc.load()\nimport sksparse.cholmod\nprint('ok')\n"
    out = subprocess.run([sys.executable, "-c", code_after], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "ok" or "No module named 'sksparse'" in out.stderr, out.stderr[-2000:]


def test_loading_petsc_leaves_contopt_s_sigterm_handler_in_place():
    # a run stopped by SIGTERM ends in one line with its checkpoint (tests/cli/test_exit_codes.py), also
    # once the AMG (or auto's trial of it) has loaded PETSc: PETSc's own handler would abort through MPI
    code = (
        "import os, signal, sys, time\n"
        "signal.signal(signal.SIGTERM, lambda *a: sys.exit(43))\n"
        "from contopt.solve.linear import petsc\n"
        "petsc.load()\n"
        "os.kill(os.getpid(), signal.SIGTERM)\n"
        "time.sleep(30)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 43, out.stderr[-2000:]
    assert "PETSC ERROR" not in out.stderr


def _two_blocks_state(backend: str, law: str, trial_above: int = 30_000):
    from contopt.adjoint.check import TIGHT_AUGMENTATION
    from contopt.cases.two_blocks import two_blocks
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(two_blocks(law=law, body_force=(0.0, 0.0, -0.05)))
    newton = NewtonOptions(rtol=1e-11, n_steps=3)
    aug = TIGHT_AUGMENTATION if law == "alm" else None
    # the direct reference: exact solves
    linear = LinearSolverOptions(backend=backend, factor_reuse=False, trial_above=trial_above)
    return system, solve_static(system, newton=newton, linear=linear, augmentation=aug)


@pytest.mark.parametrize("law", ["penalty", "alm"])
def test_contact_forward_with_inexact_newton_reaches_the_direct_solver_s_state(law):
    system, ref = _two_blocks_state("pardiso" if "pardiso" in available_backends() else "scipy", law)
    _, it = _two_blocks_state("petsc", law)
    assert it.contact[0].n_active == ref.contact[0].n_active > 0
    assert any(lg.krylov for lg in it.logs) and not any(lg.krylov for lg in ref.logs)
    # both stop at |r| <= 1e-11 |f|: the states differ by that over the smallest stiffness
    scale = np.abs(ref.u).max()
    np.testing.assert_allclose(it.u, ref.u, atol=1e-7 * scale)
    f_ref = system.contact.total_force(ref.u, tuple(r.lam for r in ref.contact))
    f_it = system.contact.total_force(it.u, tuple(r.lam for r in it.contact))
    np.testing.assert_allclose(f_it, f_ref, rtol=1e-7, atol=1e-7 * np.abs(f_ref).max())


def test_auto_s_trial_inside_newton_reaches_the_direct_solver_s_state(monkeypatch):
    monkeypatch.setattr(linear.base, "memory_available", lambda: 2**40)
    choice.forget()
    system, ref = _two_blocks_state("pardiso" if "pardiso" in available_backends() else "scipy", "penalty")
    _, trial = _two_blocks_state("auto", "penalty", trial_above=1)
    opts = LinearSolverOptions(trial_above=1)
    record = choice.choice_for(opts, system.disc.free.size, system.geometry(), lambda: True)
    # whichever solver won (it depends on this machine's timings), the trial ran its course
    assert record.verdict in ("amg", "direct") and record.direct_seconds > 0.0
    assert any(lg.krylov for lg in trial.logs)  # the AMG solved at least one Newton iteration
    np.testing.assert_allclose(trial.u, ref.u, atol=1e-7 * np.abs(ref.u).max())  # as the inexact Newton above
    choice.forget()


def test_an_indefinite_matrix_is_solved_by_gmres_without_a_factorization():
    # a tangent past a limit point: the cube's stiffness shifted below its two lowest eigenvalues
    from scipy.sparse.linalg import eigsh

    K, geo, b = cube()
    low = np.sort(eigsh(K, k=3, sigma=0.0, return_eigenvectors=False))
    shifted = (K - sp.identity(K.shape[0]) * 0.5 * (low[1] + low[2])).tocsr()
    retries = petsc_backend.STATISTICS["retries"]
    f = factorize(shifted, "petsc", geo)
    x = f.solve(b, rtol=1e-8)
    assert residual(shifted, x, b) <= DRIFT * 1e-8
    assert f.info["fallback_from"] is None  # GMRES solved it, no factorization
    assert petsc_backend.STATISTICS["retries"] == retries + 1
    f.free()


def test_auto_s_trial_leaves_an_indefinite_contact_tangent_to_the_factor(monkeypatch):
    from scipy.sparse.linalg import eigsh

    K, contact, b, opts = _trial_set_up(monkeypatch)
    for _ in range(choice.DIRECT_MATRICES):
        factorize(K, opts, contact).free()
    record = choice.choice_for(opts, K.shape[0], contact, amg_available=lambda: True)
    record.direct_seconds = 1e3  # the AMG would have all the time it wants
    low = np.sort(eigsh(K, k=3, sigma=0.0, return_eigenvectors=False))
    shifted = (K - sp.identity(K.shape[0]) * 0.5 * (low[1] + low[2])).tocsr()  # past a limit point
    retries = petsc_backend.STATISTICS["retries"]
    f = factorize(shifted, opts, contact)
    assert f.backend == "petsc"
    x = f.solve(b, rtol=1e-10)
    assert residual(shifted, x, b) < 1e-8 and f.info["fallback_from"] == "petsc"  # factored, not GMRES
    assert petsc_backend.STATISTICS["retries"] == retries
    f.free()
    assert record.verdict == "direct"


def _unsymmetric(K, seed: int = 2, strength: float = 0.2):
    """K plus a skew part on its own pattern (|skew| up to ``strength`` of K's entries): the kind of
    unsymmetric matrix frictional contact adds to a stiffness."""
    rng = np.random.default_rng(seed)
    S = K.copy()
    S.data = strength * rng.uniform(-1.0, 1.0, S.nnz) * np.abs(S.data)
    return (K + S - S.T).tocsr()


@pytest.mark.parametrize("method", ["gmres", "bicgstab"])
def test_an_unsymmetric_matrix_is_solved_by_the_unsymmetric_krylov_method_with_gamg(method):
    K, geo, b = cube()
    A = _unsymmetric(K)
    assert abs(A - A.T).max() > 0.1 * abs(K).max()
    opts = LinearSolverOptions(backend="petsc", symmetric=False, unsymmetric_krylov=method, fallback=False)
    f = factorize(A, opts, geo)
    name = {"gmres": "GMRES", "bicgstab": "BiCGStab"}[method]
    assert f.info["method"] == f"{name} + GAMG (PETSc)"
    for rtol in (1e-6, 1e-10):
        x = f.solve(b, rtol=rtol)
        assert residual(A, x, b) <= DRIFT * rtol
    assert f.info["fallback_from"] is None and max(f.info["iterations"]) < 200
    f.free()
    # the symmetric solver kept for these dofs is not the one an unsymmetric matrix gets, nor back
    g = factorize(K, LinearSolverOptions(backend="petsc"), geo)
    assert g.info["method"] == "CG + GAMG (PETSc)"
    assert residual(K, g.solve(b, rtol=1e-8), b) <= DRIFT * 1e-8
    g.free()


def test_an_unsymmetric_matrix_the_amg_cannot_do_is_solved_with_mumps_lu():
    K, geo, b = cube()
    A = _unsymmetric(K)
    f = factorize(A, LinearSolverOptions(backend="petsc", symmetric=False, preconditioner="mumps"), geo)
    assert f.info["method"] == "GMRES + MUMPS LU (PETSc)"
    x = f.solve(b, rtol=1e-10)
    assert residual(A, x, b) <= DRIFT * 1e-10 and f.info["iterations"][-1] <= 3
    f.free()


def test_a_frictional_forward_with_gmres_reaches_the_direct_solver_s_state(monkeypatch):
    from contopt.cases.sliding_block import sliding_block
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static

    methods = []
    real = petsc_backend.PetscSolve.__init__

    def spy(self, *args, **kwargs):
        real(self, *args, **kwargs)
        methods.append(self.info["method"])

    monkeypatch.setattr(petsc_backend.PetscSolve, "__init__", spy)
    model = sliding_block(divisions=3, mu=0.3, pull=0.05)
    newton = NewtonOptions(rtol=1e-11, utol=1e-11, n_steps=4)
    direct = "pardiso" if "pardiso" in available_backends() else "scipy"
    ref = solve_static(model, newton=newton, linear=LinearSolverOptions(backend=direct))
    it = solve_static(model, newton=newton, linear=LinearSolverOptions(backend="petsc"))
    assert any(lg.krylov for lg in it.logs) and set(methods) == {"GMRES + GAMG (PETSc)"}
    # both stop at |r| <= 1e-11 |f|: the states differ by that over the smallest stiffness
    np.testing.assert_allclose(it.u, ref.u, atol=1e-7 * np.abs(ref.u).max())
    t_ref, t_it = ref.contact[0].traction, it.contact[0].traction
    assert np.abs(t_ref).max() > 0
    np.testing.assert_allclose(t_it, t_ref, atol=1e-6 * np.abs(t_ref).max())
