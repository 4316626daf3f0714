"""The contact matrix's fast cells (a punch and a partly covered face, E ratio 1 and 1e4, both laws)
converge, transmit the held body's reaction and, with the augmented Lagrangian, hold the surfaces
apart; a slow test runs the hardest corner of the grid within its time budget."""

import functools

import pytest

from contopt.cases.contact_matrix import TIGHT_RTOL, Cell, fast_subset, grid, run_cell, run_cells

FAST = fast_subset()
ALM = [c for c in FAST if c.law == "alm"]
#: the force the interfaces transmit and the held body's reaction differ by the free residual,
#: which Newton brings below TIGHT_RTOL (1e-12) of the reference force, about the force itself here
FORCE_RTOL = 1e-8
assert FORCE_RTOL >= 1e3 * TIGHT_RTOL


@functools.cache
def _measured(cell: Cell) -> dict:
    return run_cell(cell, rtol=TIGHT_RTOL)


@pytest.mark.parametrize("cell", FAST, ids=Cell.key)
def test_cell_converges_and_transmits_the_reaction(cell):
    r = _measured(cell)
    assert r["converged"], r["error"]
    # never cut back forever: the stiff punch with ALM cuts its closing step back once (measured), none more
    assert r["cutbacks"] <= 2 and r["load_steps"] >= (4 if cell.geometry == "flat-punch" else 1)
    assert r["reaction"] > 0 and r["active_nodes"] > 0
    assert r["force_vs_reaction"] < FORCE_RTOL
    if cell.law == "penalty":
        assert r["alm_updates"] == 0
    else:
        assert r["alm_updates"] >= 1


_CORNERS = pytest.mark.xfail(
    strict=True,
    reason="measured 0.014 h (E ratio 1) and 0.042 h (1e4), at a punch (mortar) node between the block's "
    "nodes: the mortar gaps are averages weighted over the block's facets, they hold the non-matching "
    "surfaces apart on average, not at every node of the mortar side",
)


@pytest.mark.parametrize(
    "cell", [pytest.param(c, marks=_CORNERS) if c.geometry == "flat-punch" else c for c in ALM], ids=Cell.key
)
def test_augmented_lagrangian_leaves_no_pointwise_penetration(cell):
    r = _measured(cell)
    assert r["converged"], r["error"]
    assert r["penetration_over_h"] < 0.01


def test_pressure_is_integrated_exactly_on_the_flat_partly_covered_face():
    # the large face stays flat (held rigidly): the pressure integral over the mortar overlap is the
    # reaction to round-off; under the punch the block's top bends and the integral is only close
    for cell in FAST:
        r = _measured(cell)
        bound = 1e-12 if cell.geometry == "partly-covered" else 0.02
        assert r["integral_vs_reaction"] < bound, cell.key()


@pytest.mark.slow
def test_the_hardest_corner_of_the_grid_converges_or_fails_with_one_line():
    # E ratio 1e5, nearly incompressible soft bodies, every geometry, law and side
    cells = grid(ratios=(1e5,), nus=(0.49,))
    # at Newton's default rtol 1e-9, as users solve: the force bound then allows r_ref up to 10x the force
    for r in run_cells(cells, budget=300.0):
        assert not r.get("timed_out"), r["cell"]
        if r["converged"]:
            assert r["force_vs_reaction"] < FORCE_RTOL, r["cell"]
        else:
            assert r["error"] and r.get("error_lines") == 1, (r["cell"], r["error"])


@pytest.mark.slow
def test_the_seam_with_the_roller_nonmortar_and_alm_converges_on_a_nearly_incompressible_block():
    # measured 2026-11-29: the updates stalled to an error after 116 Newton iterations (the penalty cell
    # beside it converges in 45): the block without contact made every solve run to the Newton tolerances
    r = run_cell(Cell("seam", 1.0, 0.49, "alm", "tool"))
    assert r["converged"], r["error"]
    assert r["newton_iterations"] <= 90 and r["force_vs_reaction"] < FORCE_RTOL


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [1e2, 1e4, 1e5])
def test_the_seam_with_a_stiff_roller_and_alm_converges_on_a_nearly_incompressible_block(ratio):
    # measured 2026-11-30 at b1d5f21: Newton failed after the fourth update (E ratio 1e2), the updates' stall
    # error after 102 and 72 Newton iterations (1e4, 1e5): the solves after the updates crept on slivers at
    # the roller's edge over the blocks' edge line y = 0.2, outside the on-line band of 1e-9. With 1e-8: 34,
    # against the penalty cells' 40 beside them; twice the penalty cells' 33 at 088724a is the bound
    r = run_cell(Cell("seam", ratio, 0.49, "alm", "tool"))
    assert r["converged"], r["error"]
    assert r["newton_iterations"] <= 66 and r["force_vs_reaction"] < FORCE_RTOL
