"""``contopt run --design-from SOURCE`` (``[run] design_from``): start from another design.

SOURCE is a run directory (the ``--out`` of ``contopt run``): the design of its last recorded
iteration, as ``export-design`` takes it (the last readable record when that one is damaged),
with the run's design space rebuilt from the directory; or a VTU file a run wrote
(``OUT/vtu/BODY_NNNN.vtu``: its body's volume fraction ``nu``, cell or point data; a file whose
name names no designed body is taken for the problem's one designed body); or a run's
``design.pvd`` (the VTU files of its last entry, one per body). The design is carried to the
new problem's mesh and design space by :mod:`contopt.design.transfer`: copied when both have the
same design variables, else interpolated or fitted, so a coarse optimization seeds a fine one.
Everything is read and carried before the run directory is touched; what cannot be used is a
one-line ConfigError that begins with the option and its value.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from contopt.cases.export import design_variables, last_design, recorded_eta, run_design_space
from contopt.design.transfer import BodyField, body_fields, start_design, volume_fraction_field
from contopt.errors import ConfigError
from contopt.io.vtk import read_pvd, read_vtu
from contopt.optimize.history import Checkpoint

log = logging.getLogger(__name__)
#: the run's progress lines (``contopt run`` prints them)
progress_log = logging.getLogger("contopt.progress")

#: the volume fraction a run writes to its VTU files (cell data of each designed body)
NU = "nu"
#: a run's VTU file name: BODY_NNNN.vtu
VTU_NAME = re.compile(r"^(?P<body>.+)_(?P<index>\d+)$")
#: what to give instead, in the errors
GIVE = "give the --out directory of a `contopt run`, or a VTU or PVD file it wrote"


@dataclass(frozen=True, eq=False)
class DesignSource:
    """A start design, read: each designed body's level set (by name, :class:`BodyField`) and what
    it is, in words; ``label`` (the option and its value) begins its errors. ``loose``: one field
    whose body was named after its file (a VTU): a target that designs one body of another name
    takes it for that body."""

    fields: dict
    description: str
    label: str = "--design-from"
    loose: bool = False

    def __call__(self, space) -> np.ndarray:
        """(n,) the start design of ``space`` (a ``start`` of :func:`contopt.optimize.driver.optimize`);
        ConfigError, one line, when its bodies do not match or lie elsewhere."""
        fields = self.fields
        (name, field), *others = fields.items()
        if self.loose and not others and len(space.parts) == 1 and space.names != [name]:
            fields = {space.names[0]: replace(field, body=space.names[0])}
        try:
            x, how = start_design(space, fields)
        except ConfigError as err:
            raise ConfigError(f"{self.label}: {err}") from None
        ways = ", ".join(f"body {body!r} {way}" for body, way in how.items())
        progress_log.info("starting from %s: %s", self.description, ways)
        return x


def design_from(source: str | os.PathLike, what: str = "--design-from") -> DesignSource:
    """The start design in ``source`` (a run directory, a VTU or a PVD file); ``what`` names the
    option in errors. ConfigError, one line, when it cannot be used."""
    path = Path(source)
    label = f"{what} {source}"
    try:
        return replace(_read(path), label=label)
    except ConfigError as err:
        raise ConfigError(f"{label}: {err}") from None


def _read(path: Path) -> DesignSource:
    """The start design in ``path``; ConfigError (without the option's name) when it cannot be used."""
    if path.is_dir():
        return _from_run(path)
    if not path.exists():
        raise ConfigError(f"there is no such directory or file; {GIVE}")
    if path.suffix.lower() == ".pvd":
        return _from_pvd(path)
    if path.suffix.lower() == ".vtu":
        field = _vtu_field(path)
        if field is None:
            raise ConfigError(
                f"{path.name} has no volume fraction field {NU!r} (cell or point data): give the "
                "VTU file of a designed body that `contopt run` wrote (OUT/vtu/BODY_NNNN.vtu)"
            )
        return DesignSource({field.body: field}, f"the volume fraction of {path}", loose=True)
    raise ConfigError(f"a {path.suffix or 'file without an extension'} file holds no design; {GIVE}")


def _from_run(path: Path) -> DesignSource:
    """The design of the last recorded iteration of the run in ``path`` (the last readable record)."""
    if not Checkpoint(path).restore_meta():  # a deleted meta.json comes back from the records' copies
        raise ConfigError(f"the directory is not a run directory (it has no checkpoint/meta.json); {GIVE}")
    fix = f"start from its VTU files (--design-from {path / 'design.pvd'}) or from another run"
    x, iteration, evaluation, note = last_design(path, "is the start", fix)
    if note is not None:
        log.warning("%s", note)
    space, disc = run_design_space(path)
    x = design_variables(space, x, recorded_eta(path, evaluation))
    if x.shape != (space.n,):
        raise ConfigError(
            f"analysis {evaluation} has {x.size} design variables, the run's problem {space.n}; "
            "the checkpoint belongs to another problem"
        )
    fields = body_fields(space, x)
    for name, field in fields.items():
        points = disc.model.bodies[disc.model.body_index(name)].mesh.points
        fields[name] = replace(field, extent=(points.min(axis=0), points.max(axis=0)))
    where = f"iteration {iteration}" if iteration is not None else f"analysis {evaluation}"
    return DesignSource(fields, f"the design of {path}, {where}")


def _vtu_field(path: Path) -> BodyField | None:
    """The volume fraction of the body in a VTU file as a level set (sharpness 1: start_design scales
    it); None when the file has none (a body that is not designed)."""
    match = VTU_NAME.match(path.stem)
    body = match["body"] if match else path.stem
    points, cells, point_data, cell_data = read_vtu(path)
    used = points[np.unique(cells)]
    extent = (used.min(axis=0), used.max(axis=0))
    if NU in cell_data:
        return volume_fraction_field(body, points[cells].mean(axis=1), cell_data[NU].ravel(), 1.0, extent)
    if NU in point_data:
        return volume_fraction_field(body, points, point_data[NU].ravel(), 1.0, extent)
    return None


def _from_pvd(path: Path) -> DesignSource:
    entries = read_pvd(path)
    if not entries:
        raise ConfigError("the series lists no VTU file")
    last = max(t for t, _, _ in entries)
    fields = {}
    for _, _, file in (e for e in entries if e[0] == last):
        field = _vtu_field(file)
        if field is not None:  # None: a body that was not designed
            fields[field.body] = field
    if not fields:
        raise ConfigError(f"no VTU file of its last entry (time {last:g}) has a volume fraction field {NU!r}")
    return DesignSource(fields, f"the volume fraction of {path} (time {last:g})")
