"""Adjoint sensitivities against central finite differences of the full nonlinear solve, and closed forms."""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp

from contopt.adjoint import AdjointOptions, sensitivities
from contopt.adjoint.check import TIGHT_AUGMENTATION, check_gradient
from contopt.assembly.kernels import element_residuals_tangents
from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.cases.checks import case_responses, check_case
from contopt.cases.two_blocks import two_blocks
from contopt.errors import ConfigError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.responses import Compliance, ContactForce, Functional, PressureVariance, StrainEnergy, VolumeFraction
from contopt.solve.linear import LinearSolverOptions, available_backends
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System


def _user_pi(u, G, rho):
    return rho * (u @ u) + G[2, 2] ** 2


def _responses():
    return [
        StrainEnergy(bodies="block"),
        Compliance(),
        ContactForce(),
        PressureVariance(),
        VolumeFraction(bodies="block"),
        Functional(pi=_user_pi, zeta=lambda lam: lam**2, bodies="block", name="user"),
    ]


def _grey(prob, seed=3):
    rho = np.ones(prob.disc.n_cells)
    cells = np.arange(prob.disc.n_cells)[prob.disc.cell_slice("block")]
    rho[cells] = np.random.default_rng(seed).uniform(0.5, 1.0, cells.size)
    return rho, cells


def _check_two_blocks(responses, law, tol, h_cell):
    """The two-blocks problem under a body force at a grey design, and check_gradient of ``responses``
    on it (one random direction and 5 cells, central differences over 3 load steps)."""
    prob = System.of(two_blocks(law=law, body_force=(0.0, 0.0, -0.05)))
    rho, cells = _grey(prob)
    report = check_gradient(
        prob,
        responses,
        rho=rho,
        cells=cells,
        n_random=1,
        n_cells=5,
        h=1e-4,
        h_cell=h_cell,
        tol=tol,
        stencil=2,
        n_steps=3,
    )
    return prob, cells, report


@pytest.mark.parametrize("law, tol, h_cell", [("penalty", 1e-6, 1e-4), ("alm", 1e-5, 1e-3)])
def test_two_blocks_every_response_matches_finite_differences(law, tol, h_cell):
    prob, cells, report = _check_two_blocks(_responses(), law, tol, h_cell)
    assert report.state.contact[0].n_active > 0  # contact is active
    labels = {r.direction for r in report.rows}
    assert len(labels) == 6
    # at least one checked cell touches the contact surface
    from contopt.adjoint.check import contact_cells

    near = set(contact_cells(prob, cells).tolist())
    assert any(int(lbl.split()[1]) in near for lbl in labels if lbl.startswith("cell"))
    assert report.passed, report.table()


@pytest.mark.parametrize(
    "law, tol, h_cell",
    [("penalty", 1e-6, 1e-4), pytest.param("alm", 1e-5, 1e-3, marks=pytest.mark.slow)],  # alm: 40 s idle
)
def test_responses_at_an_earlier_load_step_match_finite_differences(law, tol, h_cell):
    # the second of three load steps (t = 2/3): the adjoint of that equilibrium, each difference a whole
    # solve with the same steps; the multipliers converge at every step (intermediate = "converge")
    from dataclasses import replace

    system = System.of(two_blocks(law=law, body_force=(0.0, 0.0, -0.05)))
    rho, cells = _grey(system)
    responses = [StrainEnergy(bodies="block"), ContactForce()]
    every_step = replace(TIGHT_AUGMENTATION, intermediate="converge")
    report = check_gradient(
        system, responses, rho=rho, cells=cells, n_random=1, n_cells=2, h=1e-4, h_cell=h_cell, tol=tol,
        stencil=2, n_steps=3, step=1, augmentation=every_step,
    )  # fmt: skip
    at = report.state.path[1]
    assert at.t == pytest.approx(2 / 3) and at.contact[0].n_active > 0
    final = sensitivities(system, report.state, responses[1]).sensitivities[0]
    assert report.adjoint.sensitivities[1].value < 0.9 * final.value  # another state than the final one
    assert report.passed, report.table()
    if law == "alm":  # an augmented Lagrangian that updates once per intermediate step: refused
        state = solve_static(system, rho, NewtonOptions(n_steps=3), record_path=True)
        with pytest.raises(ConfigError, match='intermediate = "converge"'):
            sensitivities(system, state, responses, step=1)


@pytest.mark.skipif("petsc" not in available_backends(), reason="PETSc is not installed (the petsc extra)")
@pytest.mark.parametrize("law, tol, h_cell", [("penalty", 1e-6, 1e-4), ("alm", 1e-5, 1e-3)])
def test_iterative_solver_keeps_the_finite_difference_agreement(law, tol, h_cell):
    # inexact Newton in every solve, CG + GAMG in the adjoint (to 1e-2 of its tolerance)
    prob = System.of(two_blocks(law=law, body_force=(0.0, 0.0, -0.05)))
    rho, cells = _grey(prob)
    responses = [StrainEnergy(bodies="block"), ContactForce()]
    report = check_gradient(
        prob, responses, rho=rho, cells=cells, n_random=1, n_cells=2, h=1e-4, h_cell=h_cell, tol=tol,
        stencil=2, n_steps=3, linear=LinearSolverOptions(backend="petsc"),
    )  # fmt: skip
    assert report.state.contact[0].n_active > 0
    assert any(lg.krylov for lg in report.state.logs)
    assert report.passed, report.table()


class _InexactSolver:
    """Solves ``K x = b`` leaving a residual of exactly ``rtol |b|`` in a random direction, and
    records the tolerances it was asked for: an iterative solver at its stopping criterion."""

    def __init__(self, K, rng):
        self.K, self.rng, self.asked = K, rng, []

    def solve(self, b, rtol=None):
        self.asked.append(rtol)
        e = self.rng.standard_normal(b.size)
        return np.linalg.solve(self.K, b + rtol * np.linalg.norm(b) * e / np.linalg.norm(e))


def test_schur_cg_loosens_its_inner_solves_and_keeps_the_saddle_point_accuracy():
    from contopt.adjoint.common import AdjointRows
    from contopt.adjoint.saddle import RELAXED_RTOL, Accurate, schur_cg

    rng = np.random.default_rng(0)
    n, m = 80, 12
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    G = sp.csr_matrix(rng.standard_normal((m, n)))
    D = np.full(m, 0.05)
    b, c = rng.standard_normal(n), rng.standard_normal(m)
    saddle = np.block([[K, -G.T.toarray()], [-G.toarray(), np.zeros((m, m))]])
    exact = np.linalg.solve(saddle, np.concatenate([b, c]))
    inner = 1e-12
    solver = _InexactSolver(K, rng)
    rows = AdjointRows(G, D, (), ())
    w, mu, solves, its, res = schur_cg(Accurate(solver, inner), rows, b, c, AdjointOptions(rtol=1e-10), "test")
    assert res <= 1e-10 and its >= 4
    # the first solve (w's start) and the first direction at the full tolerance, later ones looser
    assert solver.asked[0] == solver.asked[1] == inner
    assert max(solver.asked) > 1e3 * inner and max(solver.asked) <= RELAXED_RTOL
    # both equations hold nearly as if every solve had been at 1e-12 (measured: 3e-12 relative; with
    # every solve at 1e-4, 7e-5)
    assert np.linalg.norm(w - exact[:n]) <= 1e-9 * np.linalg.norm(exact[:n])
    assert np.linalg.norm(mu - exact[n:]) <= 1e-9 * np.linalg.norm(exact[n:])


@pytest.mark.skipif("petsc" not in available_backends(), reason="PETSc is not installed (the petsc extra)")
def test_iterative_adjoint_gives_the_direct_gradients():
    prob = System.of(two_blocks(body_force=(0.0, 0.0, -0.05)))
    rho, _ = _grey(prob)
    state = solve_static(prob, rho, newton=NewtonOptions(rtol=1e-12, n_steps=3), augmentation=TIGHT_AUGMENTATION)
    direct = sensitivities(prob, state, _responses(), AdjointOptions(method="direct"))
    krylov = sensitivities(prob, state, _responses(), linear=LinearSolverOptions(backend="petsc"))
    assert krylov.sensitivities[0].iterations >= 2  # the Schur-complement CG with loosened inner solves
    for a, b in zip(krylov.sensitivities, direct.sensitivities):
        scale = np.abs(b.gradient).max()
        np.testing.assert_allclose(a.gradient, b.gradient, atol=1e-8 * scale, err_msg=a.name)


def test_saddle_point_methods_agree():
    prob = System.of(two_blocks(body_force=(0.0, 0.0, -0.05)))
    rho, _ = _grey(prob)
    state = solve_static(prob, rho, newton=NewtonOptions(rtol=1e-12, n_steps=3), augmentation=TIGHT_AUGMENTATION)
    out = {
        m: sensitivities(prob, state, _responses(), AdjointOptions(method=m, rtol=1e-12))
        for m in ("schur-cg", "uzawa", "direct")
    }
    ref = out["direct"]
    assert ref.factorizations == 1 and ref.linear_solves == len(_responses())
    for m in ("schur-cg", "uzawa"):
        assert out[m].factorizations == 1
        for a, b in zip(out[m].sensitivities, ref.sensitivities):
            scale = np.abs(b.gradient).max()
            np.testing.assert_allclose(a.gradient, b.gradient, atol=1e-8 * scale, err_msg=f"{m} {a.name}")
            np.testing.assert_allclose(a.beta[0], b.beta[0], atol=1e-7 * max(np.abs(b.beta[0]).max(), 1e-300))
    # beta lives on the active nodes only (zero pressure is inactive)
    lam = state.contact[0].lam
    assert np.all(ref["contact_force"].beta[0][lam == 0] == 0.0)
    # the CG on the Schur complement needs fewer solves than the paper's Uzawa iteration
    assert out["schur-cg"].linear_solves <= out["uzawa"].linear_solves


def _cantilever(load):
    mesh = box((4.0, 1.0, 1.0), (8, 2, 2))
    return Model(
        bodies=(Body("beam", mesh, neo_hookean(100.0, 0.3)),),
        dirichlet=(Dirichlet("beam", "xmin", "xyz", 0.0),),
        loads=(Traction("beam", "xmax", (0.0, 0.0, -load)),),
    )


def _closed_form_error(load):
    """max |adjoint - (-2 W_e / rho_e)| / max |.| for compliance without contact."""
    prob = System.of(_cantilever(load))
    rho = np.random.default_rng(1).uniform(0.5, 1.0, prob.disc.n_cells)
    # converged to round-off: the invariant-based stresses of strains ~1e-8 carry an absolute error of
    # about 1e-14 (eps * 3 / strain * stress), so |r| stalls there; atol sits 100x above that floor
    # (an atol at the floor made the stop a matter of luck in the last bits)
    state = solve_static(prob, rho, newton=NewtonOptions(rtol=1e-11, atol=1e-12))
    sens = sensitivities(prob, state, Compliance())[0]
    # linear elasticity: C = f.u, dC/drho_e = -u_e^T K_e^0 u_e (K_e^0: unit-rho stiffness at u = 0),
    # and w = u (self-adjoint)
    b = prob.disc.blocks[0]
    _, _, K0 = element_residuals_tangents(
        np.zeros((b.n_cells, 8, 3)), b.geometry.grad, b.geometry.wdet, np.ones(b.n_cells), b.params, b.energy, b.fbar
    )
    ue = state.u[b.dofs]
    closed = -np.einsum("ei,eij,ej->e", ue, K0, ue)
    err = np.abs(sens.gradient - closed).max() / np.abs(closed).max()
    w_err = np.linalg.norm(sens.w - state.u) / np.linalg.norm(state.u)
    return err, w_err, sens


def test_contact_free_compliance_matches_the_self_adjoint_closed_form():
    err_small, w_small, sens = _closed_form_error(1e-6)
    assert sens.linear_solves == 1 and sens.iterations == 0
    assert err_small < 1e-5 and w_small < 1e-5
    # the remaining difference is the geometric nonlinearity: it grows in proportion to the load
    err_big, w_big, _ = _closed_form_error(1e-4)
    assert 50 < err_big / err_small < 200
    assert 50 < w_big / w_small < 200


def test_adjoint_needs_the_full_load():
    prob = System.of(_cantilever(1e-3))
    state = solve_static(prob)
    from dataclasses import replace

    with pytest.raises(ConfigError, match="t = 1"):
        sensitivities(prob, replace(state, t=0.5), Compliance())
    with pytest.raises(ConfigError, match="adjoint.method"):
        AdjointOptions(method="gmres")


@pytest.mark.slow
@pytest.mark.parametrize("law", ["penalty", "alm"])
def test_die_slab_coarse_every_response_matches_finite_differences(law):
    report = check_case("die-slab", mesh="coarse", law=law, n_random=1, n_cells=5)
    assert report.state.contact[0].n_active >= 40  # the fitted die (docs/die.md) presses 44 nodes
    assert len({r.response for r in report.rows}) == 4
    assert report.passed, report.table()


@pytest.mark.slow
def test_die_slab_coarse_compliance_and_user_functional():
    from contopt.cases.die_slab import die_slab

    # the die that rests on the slab: the body force sags the slab by about 0.17, most of the fitted
    # die's 0.1955 indentation, which would leave almost no contact
    prob = System.of(die_slab("coarse", body_force=(0.0, 0.0, -0.05), die="resting"))
    disc = prob.disc
    cells = np.arange(disc.n_cells)[disc.cell_slice("slab")]
    rho = np.ones(disc.n_cells)
    rho[cells] = np.random.default_rng(0).uniform(0.5, 1.0, cells.size)
    user = Functional(pi=lambda u, G, r: r * jnp.sum(u * u), zeta=lambda lam: lam**2, bodies="slab", name="user")
    report = check_gradient(
        prob, [Compliance(), PressureVariance(normalized=True), user], rho=rho, cells=cells, n_steps=6, tol=1e-5
    )
    assert report.state.contact[0].n_active > 50
    assert report.passed, report.table()


def test_case_responses_skip_identically_zero_ones():
    names = [r.name for r in case_responses("die-slab", two_blocks())]
    assert "compliance" not in names and "contact_force" in names
    from contopt.cases.forward import block_compression

    names = [r.name for r in case_responses("block-compression", block_compression(divisions=2))]
    assert names == ["strain_energy", "volume_fraction"]
    # the stress only when asked for (contopt check-gradient --response stress), over the designed body
    (stress,) = case_responses("two-blocks", two_blocks(), ["stress"])
    assert stress.name == "stress" and stress.bodies == ("block",)


@pytest.mark.parametrize(
    "law, tol, h_cell", [("penalty", 1e-6, 1e-4), pytest.param("alm", 1e-5, 1e-3, marks=pytest.mark.slow)]
)
def test_two_blocks_stress_matches_finite_differences_with_the_peaks_under_the_punch(law, tol, h_cell):
    from contopt.adjoint.check import contact_cells
    from contopt.responses import Fields, Stress

    stress = Stress(bodies="block", p=8.0, q=0.5)
    ks = Stress(bodies="block", aggregate="ks", sharpness=100.0, name="stress_ks")  # ~10 / the peak
    prob, cells, report = _check_two_blocks(
        [stress, Stress(bodies="block", p=2.0, q=0.0, name="stress_solid"), ks], law, tol, h_cell
    )
    assert report.state.contact[0].n_active > 0
    # the peaks are where the punch presses: the largest relaxed stress is in a cell at the contact
    peak = int(np.argmax(stress.per_cell(Fields.from_state(prob, report.state))))
    assert peak in set(contact_cells(prob, cells).tolist())
    assert report.passed, report.table()
