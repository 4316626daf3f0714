"""The die-slab model (paper 7.1) with its die cut into tets: the problem file's element / order keys on a
generated mesh, and the full design's forward solve against the hex8 die's.

The die's hexes are cut into six tets each (straight-sided, so its surface is the hex die's: the
outer quads of the sector are planar rectangles, each now two triangles), and at E = 1000 the die is
effectively rigid, so the slab's strain energy and the contact force must be the hex die's; issue 39
asks for 1 % (measured: tet10 7e-7, tet4 4e-5; docs/cad.md, "Tetrahedra").
"""

import numpy as np
import pytest

from contopt.cases.die_slab import die_slab
from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import SpecError, load_model
from contopt.errors import ConfigError

#: issue 39: the tet die's slab energy within 1 % of the hex die's
ENERGY_RTOL = 0.01


@pytest.mark.parametrize("element, cell, facet", [("tet4", 4, 3), ("tet10", 10, 6)])
def test_the_die_cut_into_tets_keeps_its_sets(element, cell, facet):
    hexes = die_slab(die_element="hex8").bodies[1].mesh
    die = die_slab(die_element=element).bodies[1].mesh
    assert die.element == element and die.cells.shape == (6 * hexes.n_cells, cell)
    assert set(die.facet_sets) == set(hexes.facet_sets)
    for name, facets in hexes.facet_sets.items():
        assert die.facet_nodes(name).shape == (2 * len(facets), facet)
    np.testing.assert_array_equal(die.points[: hexes.n_nodes], hexes.points)  # the same corners


@pytest.mark.parametrize(
    "overrides, match",
    [
        ({"bodies[1].mesh.order": 2}, r'bodies\[1\]\.mesh\.order.*set element = "tet"'),
        ({"bodies[1].mesh.element": "tets"}, r"bodies\[1\]\.mesh\.element.*did you mean 'tet'"),
        ({"bodies[1].mesh.element": "tet", "bodies[1].mesh.order": 3}, r"mesh\.order.*must be 1.*or 2"),
    ],
)
def test_bad_element_keys_are_one_line_errors(overrides, match):
    path = OPTIMIZATION_CASES["die-slab"].path
    with pytest.raises(SpecError, match=match) as err:
        load_model(path, overrides, label=path.name)
    assert "\n" not in str(err.value)


def test_die_element_is_checked():
    with pytest.raises(ConfigError, match="die_element must be one of"):
        die_slab(die_element="hex20")


def _solve(element: str) -> tuple[float, float]:
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(die_slab("coarse", die_element=element))
    state = solve_static(system, newton=NewtonOptions(n_steps=6))
    assert state.logs[-1].converged and state.t == pytest.approx(1.0)
    lam = tuple(r.lam for r in state.contact)
    energy = float(system.disc.strain_energy(state.u, per_cell=True)[system.disc.cell_slice("slab")].sum())
    return energy, float(system.contact.total_force(state.u, lam).sum())


@pytest.fixture(scope="module")
def hex_die():
    return _solve("hex8")


@pytest.mark.slow
@pytest.mark.parametrize("element", ["tet10", "tet4"])
def test_a_tet_die_gives_the_hex_dies_slab_energy(hex_die, element):
    """The full design on the coarse mesh (6 load steps, ALM): about 1.7 min for the three solves."""
    energy, force = _solve(element)
    assert energy == pytest.approx(hex_die[0], rel=ENERGY_RTOL)
    assert force == pytest.approx(hex_die[1], rel=ENERGY_RTOL)
