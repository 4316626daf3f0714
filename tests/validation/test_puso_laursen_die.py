"""Puso & Laursen's die on the seed paper's slab: docs/validation.md (e), docs/die.md (issue 42 §2).

A port of Puso & Laursen's mortar examples (2003-2004, LLNL report UCRL-JRNL-200667; the primary
source was not reachable) describes their Example 2's die as a cylinder sector of radius 3, 0.2
thick and 5.2 wide (E 1000), its axis 2.5 from the slab's end, on this slab (9 x 4 x 3, E 1,
nu 0.3). Here it rests on the slab and moves -0.6 (the seed paper's text), frictionless, on the
seed's cantilever of 7.2 (the slab held at x = 9): the die is 6.5 from the support, where the slab
bends as a beam. Its full design's slab energy against an Euler-Bernoulli cantilever of the slab's
section (EI = 1 * 4 * 3^3 / 12 = 9) deflected by d = 0.6 at L = 6.5: ``U = 3 EI d^2 / (2 L^3)``
= 0.01770; contopt: 0.01661 (-6.1 %: the slab's local indentation and its shear soften it).

The seed paper's table 3 on this die (coarse, MMA; benchmarks/die_recovery.py --optimize
pl,2.5,right,density) is the slow test: f/|f_a^0| = -0.6898 against the paper's -0.6974.
"""

import pytest

from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import load_spec
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

X_AXIS = 2.5  # the die's axis, from the slab's end x = 0 (the cantilever is held at x = 9)
#: the port's die, resting on the slab's top z = 3 and moved -0.6 on its inner surface
OVERRIDES = {
    "bodies[1].mesh.radius": 3.0,
    "bodies[1].mesh.arc_deg": 100.0,
    "bodies[1].mesh.width": 5.2,
    "bodies[1].mesh.thickness": 0.2,
    "bodies[1].mesh.center": [X_AXIS, 2.0, 6.0],
}


def _problem(**kw):
    path = OPTIMIZATION_CASES["die-cantilever"].path
    return load_spec(path, OVERRIDES, label=path.name, check=False, **kw)


def test_puso_laursen_die_bends_the_cantilever_like_a_beam():
    """The full design's slab energy within 10 % of the Euler-Bernoulli cantilever's 0.01770 (measured
    0.01661, -6.1 %: the indentation under the die and the shear of a slab 3 deep over 6.5 soften it;
    a die that missed the slab, or a support on the wrong end, is off by far more)."""
    spec = _problem()
    system = System.of(spec.problem.model)
    state = solve_static(system, newton=NewtonOptions(n_steps=6))
    disc = system.disc
    energy = float(disc.strain_energy(state.u, None, per_cell=True)[disc.cell_slice("slab")].sum())
    beam = 3.0 * (4.0 * 3.0**3 / 12.0) * 0.6**2 / (2.0 * (9.0 - X_AXIS) ** 3)
    print(f"slab energy {energy:.6g}, beam {beam:.6g} ({energy / beam - 1:+.2%})")
    assert energy == pytest.approx(beam, rel=0.10)


@pytest.mark.slow
def test_puso_laursen_die_gives_table_3():
    """Table 3's density row, coarse, MMA with the case's stopping rules: f/|f_a^0| within 0.02 of the
    paper's -0.6974 (measured -0.6898; the fitted die bundled today: -0.8457, 0.15 away)."""
    from contopt.optimize.driver import optimize

    spec = _problem(design="density")
    res = optimize(spec.problem, spec.optimizer, spec.options)
    print(f"f/|f0| {res.normalized_objective:.4f} after {res.iterations} iterations ({res.status})")
    assert res.normalized_objective == pytest.approx(-0.6974, abs=0.02)
