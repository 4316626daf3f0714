"""The paper's die cases (sections 7.1-7.3) as optimization cases: sizes, the first iterations, a full run.

The design sizes are combinatorial facts the paper's table 1 states: n_d = 13 x 8 x 7
control points or one variable per cell, and the nonzeros of G (64 per cell for tri-cubic
B-splines; the cone filter's neighbour pairs within r = 0.7, recounted here by brute force).
The first iterations are checked against physics that does not depend on the code under test:
on the uniform grey start every cell has the stiffness factor rho(0.4), and with a nearly
rigid die whose motion is prescribed the slab's displacement does not change when its modulus
is scaled uniformly, so its strain energy and the contact force scale by rho(0.4) too.
"""

import json

import numpy as np
import pytest

from contopt.cases.optimization import OPTIMIZATION_CASES, optimization_case
from contopt.errors import ConfigError
from contopt.optimize.driver import GREY_BAND, OutputOptions, grey_fraction, optimize
from contopt.optimize.mma import MMAOptions
from contopt.optimize.problem import DesignNLP

DIE_CASES = ("die-slab", "die-cantilever", "die-slab-contact-force")
#: paper table 1: (n_d, nonzeros of G) per parameterization and mesh
PAPER_SIZES = {
    ("bspline", "coarse"): (728, 117_760),
    ("density", "coarse"): (1840, 41_272),
    ("bspline", "fine"): (728, 864_000),
    ("density", "fine"): (13_500, 2_009_512),
}
#: the paper's slab meshes
SLAB_MESHES = {"coarse": (23, 10, 8), "fine": (45, 20, 15)}
VOLUME_FRACTION = 0.4
#: MMA approximates the volume constraint (a tanh of G x) by a convex separable function that is
#: exact at the current point only; the next iterate can overshoot the bound by a second-order
#: amount. 1e-3 is 0.25 % of the bound; the runs below stay well inside it (about -0.01 to -0.04).
VOLUME_TOL = 1e-3


def _rho(nu, p=3.0, nu0=1e-2):
    return (1.0 - nu0) * nu**p + nu0


def _cone_pairs(points, radius):
    """Number of centroid pairs closer than ``radius`` (brute force, no KD-tree)."""
    d2 = ((points[:, None, :] - points[None, :, :]) ** 2).sum(-1)
    return int(np.sum(d2 < radius * radius))


@pytest.mark.parametrize("design, mesh", list(PAPER_SIZES))
def test_design_sizes_are_the_papers(design, mesh):
    nlp = DesignNLP(optimization_case("die-slab", design, mesh))
    part = nlp.space.parts[0]
    n_cells = int(np.prod(SLAB_MESHES[mesh]))
    assert part.spec.body == "slab" and part.G.shape[0] == n_cells
    assert (nlp.n, part.nnz) == PAPER_SIZES[design, mesh]
    if design == "bspline":
        assert part.nnz == n_cells * 64 and nlp.n == 13 * 8 * 7
        assert part.spec.parameterization.patches == (10, 5, 4)  # h = 0.9, 0.8, 0.75 over 9 x 4 x 3
    elif mesh == "coarse":
        assert part.nnz == _cone_pairs(part.centroids, 0.7)
    # the B-spline rows are a partition of unity, the filter's rows weighted means: grey stays uniform
    np.testing.assert_allclose(np.asarray(part.G.sum(axis=1)).ravel(), 1.0, rtol=1e-12)


def test_cases_are_registered_with_their_options():
    for name in DIE_CASES:
        case = OPTIMIZATION_CASES[name]
        # the paper's two meshes; the die-slab adds two larger ones for the iterative solver
        larger = ("xl", "xxl") if name == "die-slab" else ()
        assert case.default_design == "bspline" and case.meshes == ("coarse", "fine", *larger)
    assert OPTIMIZATION_CASES["die-slab-contact-force"].designs == ("bspline",)
    right = optimization_case("die-cantilever")
    assert right.model.dirichlet[0].node_set == "xmax"
    assert optimization_case("die-slab").model.dirichlet[0].node_set == "zmin"
    assert optimization_case("die-slab", eta=4.0).design.heaviside.eta == 4.0
    assert optimization_case("die-slab").design.heaviside.eta == 10.0
    assert optimization_case("die-slab").newton.n_steps == 6
    with pytest.raises(ConfigError, match="--design must be one of"):
        optimization_case("die-slab-contact-force", "density")
    with pytest.raises(ConfigError, match="--mesh must be one of"):
        optimization_case("die-slab", mesh="medium")
    with pytest.raises(ConfigError, match="--design must be one of"):
        optimization_case("die-slab", "levelset")


def _independent_objective(nlp, rec, objective_name):
    """The raw objective from other code paths: the assembler's cell energies, the contact
    system's nodal-area force (numpy) instead of the JAX functionals."""
    disc = nlp.system.disc
    rho = nlp.fields(rec.x).rho
    if "strain_energy" in objective_name:
        return -float(disc.strain_energy(rec.u, rho, per_cell=True)[disc.cell_slice("slab")].sum())
    return -float(nlp.system.contact.total_force(rec.u, rec.pressures).sum())


@pytest.mark.parametrize(
    "name, design",
    [
        ("die-slab", "bspline"),
        ("die-slab", "density"),
        ("die-cantilever", "bspline"),
        ("die-slab-contact-force", "bspline"),
    ],
)
def test_two_mma_iterations(name, design, tmp_path):
    problem = optimization_case(name, design, "coarse")
    res = optimize(
        problem,
        "mma",
        MMAOptions(max_iter=2, kkt_tol=0.0, change_tol=0.0),
        out=tmp_path,
        outputs=OutputOptions(vtu="none", plot=False),
    )
    f = [r["objective"] for r in res.history]
    assert res.iterations == 2 and len(f) == 3
    # grey start: rho(0.4) everywhere, so f/|f^0| = -rho(0.4) up to the die's compliance and the
    # penalty's penetration (both proportional to the force, i.e. smaller on the soft start)
    assert f[0] == pytest.approx(-_rho(VOLUME_FRACTION), rel=1e-2)
    # both steps improve on the grey start; MMA (no conservative inner loop) need not descend at every
    # step: on the cantilever its second step overshoots (-0.62, then -0.43, -0.84 at convergence)
    assert max(f[1], f[2]) < f[0] < 0
    assert res.volume_fractions[0] <= VOLUME_FRACTION + VOLUME_TOL
    assert res.record.objective == pytest.approx(res.normalized_objective * res.scale, rel=1e-12)
    nlp = DesignNLP(problem)
    assert res.record.objective == pytest.approx(
        _independent_objective(nlp, res.record, problem.objective.name), rel=1e-9
    )
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["design"][0]["n_design"] == PAPER_SIZES[design, "coarse"][0]
    assert summary["normalize"] == "full" and summary["objective_scale"] == pytest.approx(res.scale)


def _column_design_objective(problem):
    """f/|f^0| of a hand-made black-and-white design: a straight column through the slab under the
    die, |x - 4.5| < 1.76 (9 of 23 cells across: volume fraction 0.391), solved from zero."""
    from contopt.responses.base import Fields

    nlp = DesignNLP(problem)
    scale = nlp.objective_scale()
    part = nlp.space.parts[0]
    nu = np.where(np.abs(part.centroids[:, 0] - 4.5) < 1.76, 1.0, 0.0)
    assert part.volumes @ nu / part.volumes.sum() <= VOLUME_FRACTION
    rho = np.ones(nlp.space.n_cells)
    rho[part.cells] = problem.design.simp.forward(nu)
    state, _ = nlp.solve_state(rho)
    return problem.objective.value(Fields.from_state(nlp.system, state)) / scale


#: Stopping rule of the slow run. MMA's default kkt_tol (1e-3) stops this problem after 3
#: iterations: where the Heaviside saturates the gradient vanishes and the KKT residual is small
#: while the steps are still at the move limit (see contopt.optimize.mma); the change rule never
#: fires either, because variables whose cells are saturated drift at the move limit (changes of
#: 0.05-0.4 for 80 iterations with f constant to 1e-4). A KKT residual of 5e-5 (rms per variable,
#: f of order 1) is reached once the boundary has settled.
MMA_OPTIONS = MMAOptions(max_iter=40, kkt_tol=5e-5, change_tol=0.0)
#: Greyness: volume share of the slab's cells with 0.1 < nu < 0.9 (driver.grey_fraction). The paper's
#: figure 4b shows a sharp boundary and no grey interior. A column-like design has two side faces of
#: 4 x 3 each; a grey layer one cell (0.39) thick along them is 24 * 0.39 / 108 = 0.087 of the slab.
#: 0.1 accepts at most such a layer and rejects a porous design (the grey start is 1.0).
GREY_MAX = 0.1


@pytest.mark.slow
def test_die_slab_bspline_converges_to_a_black_and_white_design(tmp_path):
    """Paper 7.1, coarse B-spline (table 1: f_a/|f_a^0| = -0.9908 after 19 IPOPT iterations).

    The paper's -0.99 is not a bound for our die (its geometry is fitted to the paper's |f_a^0|,
    not known; see test_full_design_energy_is_the_papers), so the optimum is checked against a
    feasible design built by hand instead: it must do better than a straight solid column under
    the die of the same volume, and no better than the full slab.
    """
    problem = optimization_case("die-slab", "bspline", "coarse")
    res = optimize(problem, "mma", MMA_OPTIONS, out=tmp_path, outputs=OutputOptions(vtu="none", plot=False))
    assert res.status == "converged", res.message
    assert res.volume_fractions[0] <= VOLUME_FRACTION + VOLUME_TOL
    column = _column_design_objective(problem)
    assert -1.0 < res.normalized_objective < column < res.history[0]["objective"]
    nlp = DesignNLP(problem)
    assert GREY_BAND == (0.1, 0.9)
    assert grey_fraction(nlp.space, res.fields) < GREY_MAX


#: paper 7.1: "the nominal, i.e., full volume, strain energy of the slab is |f_a^0| = 5.014e-2"
PAPER_FULL_ENERGY = 5.014e-2


@pytest.mark.slow
def test_full_design_energy_is_the_papers():
    """The bundled die (fitted in benchmarks/die_recovery.py) keeps the coarse die-slab's full-design
    strain energy within the issue's 1 % of the paper's; the fit left it at +0.16 %, and Newton's
    and the multipliers' tolerances move it by less than 1e-6 of that."""
    from contopt.cases.die_slab import die_slab
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(die_slab("coarse"))
    state = solve_static(system, newton=NewtonOptions(n_steps=6))
    disc = system.disc
    energy = float(disc.strain_energy(state.u, per_cell=True)[disc.cell_slice("slab")].sum())
    np.testing.assert_allclose(energy, PAPER_FULL_ENERGY, rtol=0.01)


def test_the_die_starts_where_its_fit_put_it():
    """The files' die starts 0.4045 above the slab's top (docs/die.md); the earlier one rests on it."""
    from contopt.cases.die_slab import die_slab

    def lowest(model):
        die = next(b for b in model.bodies if b.name == "die")
        return float(die.mesh.points[:, 2].min())

    assert lowest(die_slab("coarse")) == pytest.approx(3.4045, abs=1e-12)
    assert lowest(die_slab("coarse", support="right")) == pytest.approx(3.4045, abs=1e-12)
    assert lowest(die_slab("coarse", die="resting")) == pytest.approx(3.0, abs=1e-12)
    with pytest.raises(ConfigError, match="die must be one of"):
        die_slab("coarse", die="flat")
