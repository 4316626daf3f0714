"""A rigid tool in a problem file: ``[[bodies]]`` with ``rigid = {...}`` (its surface: a shape or a
file) and ``motion = {...}`` (its rigid motion) instead of ``mesh`` and ``material``
(:mod:`contopt.mesh.tool`, :class:`contopt.assembly.model.RigidMotion`)."""

from __future__ import annotations

import inspect
import math
from pathlib import Path

import numpy as np

from contopt.assembly.model import Body, LoadPath, RigidMotion
from contopt.cases.keys import PRESENT
from contopt.cases.keys_model import MODEL, SHAPE_KEYS, SHAPES
from contopt.cases.toml_reader import REQUIRED, Reader, Table, describe
from contopt.mesh import tool


def tool_mesh(r: Reader, t: Table):
    """The hex8 layer of the surface ``t`` (``[bodies.rigid]``) describes."""
    section = MODEL["bodies.rigid"]
    if t.has("file"):
        t.only(section.allowed(PRESENT))
        file = Path(t.str("file"))
        path = file if file.is_absolute() else r.base_dir / file
        if not path.exists():
            raise t.error("file", f"no such file: {path}")
        scale = t.positive("scale", section.default("scale"))
        surface = t.guard("file", tool.read_surface, path, scale)
    else:
        if not t.has("shape"):
            raise t.error(None, f"needs shape (one of {list(SHAPES)}) or file (a surface file such as an STL)")
        shape = t.str("shape", choices=SHAPES)
        t.only(section.allowed(shape))
        fn = getattr(tool, SHAPES[shape])
        params = inspect.signature(fn).parameters
        kw = {}
        for k, (kind, _) in SHAPE_KEYS[shape].items():
            default = REQUIRED if params[k].default is inspect.Parameter.empty else None
            v = _shape_value(t, k, kind, default)
            if v is not None:
                kw[k] = v
        surface = t.guard(None, fn, **kw)
    if t.bool("flip", section.default("flip")):
        surface = surface.flipped()
    return t.guard("thickness", tool.tool_layer, surface, t.positive("thickness", section.default("thickness")))


def _shape_value(t: Table, k: str, kind: str, default):
    """One argument of a shape: read as its kind says."""
    if kind == "angle":
        return t.angle(k, default)
    if kind == "axis":
        return axis(t, k, default)
    if kind == "value":  # one length, or one per side
        return t.vector(k, n=2) if isinstance(t.raw(k, None), list) else t.positive(k, default)
    if kind == "ints":
        return t.ints(k, default, n=2)
    return {"vector": t.vector, "number": t.positive, "integer": t.int}[kind](k, default)


def axis(t: Table, k: str, default=REQUIRED):
    """An axis: "x", "y", "z" or a vector [x, y, z] (a tuple of 3 floats)."""
    if not t.has(k):
        return t.raw(k, default)
    if isinstance(t.raw(k), str):
        return t.str(k, choices=("x", "y", "z"))
    return t.vector(k)


def motion(t: Table | None) -> RigidMotion:
    """The RigidMotion ``t`` (``[bodies.motion]``) describes; standing still when absent."""
    if t is None:
        return RigidMotion()
    t.only(MODEL["bodies.motion"].names)
    if t.has("path") and t.has("value"):
        raise t.error("path", "give either value (proportional to the load) or path, not both")
    kw: dict = {}
    if t.has("path"):
        kw["translation"] = t.guard("path", LoadPath, t.raw("path"))
    elif t.has("value"):
        kw["translation"] = t.vector("value")
    if t.has("rotation"):
        section = MODEL["bodies.motion.rotation"]
        rot = t.sub("rotation", section.names, ("axis",))
        kw["axis"] = _direction(rot, axis(rot, "axis"))
        kw["point"] = rot.vector("point", section.default("point"))
        kw["angle"] = _angle(rot)
    return t.guard(None, RigidMotion, **kw)


def _direction(t: Table, v) -> tuple:
    """A letter axis as its unit vector."""
    if isinstance(v, str):
        return tuple(float(a) for a in np.eye(3)["xyz".index(v)])
    return v


def _angle(t: Table):
    """``angle`` (radians) or ``angle_deg`` (degrees): a number, or rows [t, angle] as a LoadPath of radians."""
    given = [k for k in ("angle", "angle_deg") if t.has(k)]
    if len(given) != 1:
        why = "give angle (radians) or angle_deg (degrees), one of the two"
        raise t.error("angle_deg", why if given else "required key is missing (or angle in radians)")
    k = given[0]
    v = t.raw(k)
    to_radians = math.radians if k == "angle_deg" else float
    if isinstance(v, list):
        ok = all(isinstance(row, list) and len(row) == 2 for row in v)
        if not ok:
            raise t.error(k, f"must be a number or rows [t, angle], got {describe(v)}")
        path = t.guard(k, LoadPath, v)
        return LoadPath(tuple((row[0], to_radians(row[1])) for row in path.points))
    return to_radians(t.number(k))


def rigid_body(t: Table, name: str, mesh) -> Body:
    """The rigid Body of a ``[[bodies]]`` table with ``rigid`` (its layer ``mesh`` read already)."""
    return t.guard(None, Body, name, mesh, rigid=motion(t.sub("motion", default=None)))
