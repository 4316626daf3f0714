"""The panels of curves.png (contopt.io.plots.curve_panels): a load-path objective's target points are
drawn with the contact forces, on their abscissa (the motion's displacement at the target's load factors)."""

import numpy as np

from contopt.io.plots import curve_panels, plot_curves
from contopt.optimize.curves import target_curve
from contopt.responses import ContactForce
from contopt.responses.path import ForceTarget

#: one curve set: a motion of travel 0.15 t, a contact interface, at t = 0, 0.5, 1
ENTRY = {
    "label": "first design (iteration 0)",
    "load_factor": [0.0, 0.5, 1.0],
    "motions": [
        {
            "name": "punch/zmax (xyz)",
            "kind": "motion",
            "travel": [0.0, 0.075, 0.15],
            "force_along": [0.0, 0.01, 0.03],
        }
    ],
    "interfaces": [{"name": "punch/zmin -> pad/zmax", "normal_force": [0.0, 0.01, 0.03]}],
}


def test_the_target_is_drawn_on_the_contact_panel_at_the_motions_displacement(tmp_path):
    target = target_curve(-2.0 * ForceTarget([[0.0, 0.0], [0.5, 0.02], [1.0, 0.06]], steps=4))
    assert target == {"name": "force_target", "load_factor": [0.0, 0.5, 1.0], "force": [0.0, 0.02, 0.06]}
    panels = curve_panels({"curves": [ENTRY], "target": target})
    (contact,) = [p for p in panels if p["title"] == "contact interfaces"]
    label, x, y, _ = contact["lines"][-1]
    assert label == "target (force_target)"
    np.testing.assert_allclose(x, [0.0, 0.075, 0.15])
    assert y == [0.0, 0.02, 0.06]
    assert plot_curves({"curves": [ENTRY], "target": target}, tmp_path / "curves.png").stat().st_size > 0


def test_an_objective_without_a_target_draws_none():
    assert target_curve(ContactForce()) is None
    panels = curve_panels({"curves": [ENTRY]})
    (contact,) = [p for p in panels if p["title"] == "contact interfaces"]
    assert [line[0] for line in contact["lines"]] == ["punch/zmin -> pad/zmax normal, first design (iteration 0)"]


def test_a_target_of_one_step_still_reads_the_recorded_path():
    assert ForceTarget([[0.0, 0.0], [1.0, 1.0]], steps=1).stops == (1.0,)
