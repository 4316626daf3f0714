"""The die-slab model of the paper's sections 7.1-7.2 (the forward cases and the tests use it).

The model is the one of the bundled problem files ``die-slab.toml`` (slab fixed at its bottom)
and ``die-cantilever.toml`` (fixed at x = 9), which describe its geometry and why; the design
problems are those files (:func:`contopt.cases.optimization.optimization_case`).
"""

from __future__ import annotations

from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import load_model
from contopt.errors import ConfigError

#: the problem file of each support
FILES = {"bottom": "die-slab", "right": "die-cantilever"}
#: where the die's axis starts: the files' die, fitted to the paper's |f_a^0| (0.4045 above the slab,
#: docs/die.md), or the die of earlier releases that rests on the slab and indents it by 0.6
DIES = {"fitted": None, "resting": [4.5, 2.0, 6.0]}
#: the die's elements: the file's hex8, or each hex cut into six tets (the mesh's element / order keys)
DIE_ELEMENTS = {"hex8": None, "tet4": {"element": "tet", "order": 1}, "tet10": {"element": "tet", "order": 2}}


def die_slab(
    mesh: str | None = None,
    support: str = "bottom",
    law: str | None = None,
    eps: float | None = None,
    slab_divisions=None,
    body_force=None,
    die: str = "fitted",
    die_element: str = "hex8",
):
    """The Model of the die pressed into the slab.

    mesh : the files' mesh variant (``"coarse"``, the default, or ``"fine"``); slab_divisions
        (nx, ny, nz) replaces it
    support : ``"bottom"`` (paper 7.1) or ``"right"`` (the cantilever of 7.2, fixed at x = 9)
    law, eps : the contact law's name and its penalty (default: the file's)
    body_force : a constant force per volume on the slab (not in the paper; makes the compliance
        of eq. 42 non-zero, e.g. for gradient checks)
    die : ``"fitted"`` (the files' die) or ``"resting"`` (the earlier die, see :data:`DIES`)
    die_element : ``"hex8"`` (the files'), ``"tet4"`` or ``"tet10"``: the die's hexes cut into six tets each
        (straight-sided, so the same surface; docs/cad.md, "Tetrahedra")
    """
    if support not in FILES:
        raise ConfigError(f"support must be one of {sorted(FILES)}, got {support!r}")
    if die not in DIES:
        raise ConfigError(f"die must be one of {sorted(DIES)}, got {die!r}")
    if die_element not in DIE_ELEMENTS:
        raise ConfigError(f"die_element must be one of {sorted(DIE_ELEMENTS)}, got {die_element!r}")
    cut = DIE_ELEMENTS[die_element] or {}
    replace = {
        "bodies[0].mesh.divisions": None if slab_divisions is None else list(slab_divisions),
        "contact[0].law": law,
        "contact[0].eps": eps,
        "bodies[1].mesh.center": DIES[die],
        "bodies[1].mesh.element": cut.get("element"),
        "bodies[1].mesh.order": cut.get("order"),
        "loads": None if body_force is None else [{"type": "body-force", "body": "slab", "force": list(body_force)}],
    }
    path = OPTIMIZATION_CASES[FILES[support]].path
    overrides = {key: value for key, value in replace.items() if value is not None}
    return load_model(path, overrides, mesh=mesh, label=path.name)
