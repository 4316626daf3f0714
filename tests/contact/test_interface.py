"""Which surface is nonmortar: the mortar rule chooses when the user does not say, says why, and warns
with the measured penetration when the user's choice is the coarse side under a finer, curved mortar;
a failed contact check advises what helps against the failure it saw."""

import logging

import numpy as np
import pytest
from _meshing import roller_on_block  # tests/contact/_meshing.py

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.contact.interface import ContactInterface, choose_sides, surface_measures
from contopt.contact.laws import Penalty
from contopt.contact.verify import STEP_ADVICE, Finding, SideAdvice, advice_for
from contopt.errors import ConfigError, MeshError
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.solve.static import solve_static
from contopt.solve.system import System


def _two_blocks(top_divisions=(4, 4, 1), top_E=1.0, bottom_E=1.0):
    """A block (4 x 4 facets on its top) under a smaller-celled or alike block standing on it."""
    bottom = box((1.0, 1.0, 0.5), (4, 4, 2))
    top = box((1.0, 1.0, 0.5), top_divisions, origin=(0.0, 0.0, 0.5))
    return (
        Body("bottom", bottom, neo_hookean(bottom_E, 0.3)),
        Body("top", top, neo_hookean(top_E, 0.3)),
    )


def _model(bodies, **interface):
    support = (Dirichlet("bottom", "zmin", "xyz"),)
    return Model(bodies=bodies, dirichlet=support, interfaces=(ContactInterface(**interface),))


SURFACES = (("bottom", "zmax"), ("top", "zmin"))


def test_the_finer_surface_is_chosen_nonmortar_whichever_is_named_first():
    for order in (SURFACES, SURFACES[::-1]):
        iface = _model(_two_blocks((8, 8, 1)), surfaces=order).interfaces[0]
        assert iface.nonmortar == ("top", "zmin") and iface.mortar == ("bottom", "zmax")
        assert iface.sides == "chosen" and "the finer surface" in iface.choice and "facets 0.125" in iface.choice


def test_for_facets_of_one_size_the_curved_then_the_softer_surface_is_chosen():
    roller = roller_on_block(Penalty())
    measures = surface_measures(roller, ("roller", "outer"))
    assert measures.curvature == pytest.approx(1 / 0.2, rel=0.05)  # a 16-gon of radius 0.2
    assert surface_measures(roller, ("block", "zmax")).curvature == 0.0
    nonmortar, mortar, rule, why = choose_sides(roller, ("block", "zmax"), ("roller", "outer"))
    assert (nonmortar, rule) == (("roller", "outer"), "curved") and "radius 0.19" in why
    soft = _model(_two_blocks(top_E=0.1), surfaces=SURFACES).interfaces[0]
    assert soft.nonmortar == ("top", "zmin") and "softer" in soft.choice
    alike = _model(_two_blocks(), surfaces=SURFACES[::-1]).interfaces[0]
    assert alike.nonmortar == ("top", "zmin") and "first given" in alike.choice


def test_the_choice_is_said_and_the_users_choice_is_kept(caplog):
    with caplog.at_level(logging.INFO, logger="contopt.contact.interface"):
        _model(_two_blocks((8, 8, 1)), surfaces=SURFACES)
    assert any("nonmortar top/zmin: the finer surface" in r.getMessage() for r in caplog.records)
    given = _model(_two_blocks((8, 8, 1)), nonmortar=SURFACES[0], mortar=SURFACES[1]).interfaces[0]
    assert given.nonmortar == SURFACES[0] and given.sides == "given" and given.choice == ""
    assert "the finer surface" in given.mismatch(_model(_two_blocks((8, 8, 1)), surfaces=SURFACES))


def test_sides_are_given_one_way_or_the_other():
    with pytest.raises(ConfigError, match="not both"):
        ContactInterface(SURFACES[0], SURFACES[1], surfaces=SURFACES)
    with pytest.raises(ConfigError, match="surfaces=\\(a, b\\)"):
        ContactInterface(SURFACES[0])
    with pytest.raises(ConfigError, match="must be two"):
        ContactInterface(surfaces=SURFACES[:1])
    with pytest.raises(MeshError, match="contact interface .*unknown facet set"):  # named with the interface
        _model(_two_blocks(), surfaces=(("bottom", "zmax"), ("top", "nowhere")))


def test_an_interface_is_named_by_its_bodies_unless_given_a_name_and_names_are_unique():
    given = ContactInterface(SURFACES[1], SURFACES[0])
    assert given.name == "top-bottom"
    # with surfaces: the order given, also when the model chooses the other side nonmortar
    chosen = _model(_two_blocks((8, 8, 1)), surfaces=SURFACES).interfaces[0]
    assert chosen.nonmortar == ("top", "zmin") and chosen.name == "bottom-top"
    assert ContactInterface(SURFACES[0], SURFACES[1], name="seat").name == "seat"
    with pytest.raises(ConfigError, match="name must be a non-empty string"):
        ContactInterface(SURFACES[0], SURFACES[1], name="")
    twice = dict(bodies=_two_blocks(), interfaces=(given, ContactInterface(SURFACES[1], SURFACES[0], law="penalty")))
    with pytest.raises(ConfigError, match="duplicate contact interface name 'top-bottom' \\(interfaces 0 and 1\\)"):
        Model(**twice)


def test_a_coarse_nonmortar_under_a_curved_mortar_is_reported_with_its_penetration():
    system = System.of(roller_on_block(Penalty()))
    state = solve_static(system)
    warnings = system.contact.coarse_side_warnings(state.checks)  # what solve_static logs as warnings
    deepest = state.checks[0].depth_mortar.max()
    assert len(warnings) == 1 and f"up to {deepest:.3g}" in warnings[0] and "nonmortar = roller/outer" in warnings[0]
    # with the sides the rule chooses, the roller's nodes carry the pressure and none is reported
    chosen = System.of(roller_on_block(Penalty(), surfaces=True))
    state = solve_static(chosen)
    assert chosen.model.interfaces[0].nonmortar == ("roller", "outer")
    assert not chosen.contact.coarse_side_warnings(state.checks)
    assert state.checks[0].depth_mortar.max() < deepest


def _finding(side, depth):
    origin = (0.0, 0.0, 0.0)
    return Finding(side=side, body="b", node=1, position=origin, depth=depth, relative=depth, held=False, other="c")


def test_the_advice_matches_the_failure():
    coarse = SideAdvice(mismatch="the finer surface (...)", swap="roller/outer", size=0.05)
    swap = advice_for(_finding("mortar", 0.01), reach=0.1, sides=coarse)
    assert "Swap the sides (nonmortar = roller/outer" in swap and "facets of about 0.05" in swap
    assert "newton.n_steps" not in swap  # no number of load steps changes the weighted gaps of a coarse side
    # a node deeper than the search reaches, or a nonmortar node unheld: a surface driven through
    assert advice_for(_finding("mortar", 0.2), reach=0.1, sides=coarse) == STEP_ADVICE
    assert advice_for(_finding("nonmortar", 0.01), reach=0.1, sides=coarse) == STEP_ADVICE
    assert "refine the nonmortar surface" in advice_for(_finding("mortar", 0.01), reach=0.1, sides=SideAdvice())
    assert np.isfinite(coarse.size)
