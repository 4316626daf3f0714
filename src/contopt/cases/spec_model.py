"""The model sections of a problem file: ``[[bodies]]`` (meshes, derived sets, materials),
``[[supports]]``, ``[[soft_supports]]``, ``[[loads]]`` and ``[[contact]]`` (see
:mod:`contopt.cases.spec` for the keys).

The reader checks what only the file knows (key names, types, which body and set a name
means); the ranges of values are the constructed objects' own checks, surfaced by
:meth:`~contopt.cases.toml_reader.Table.guard` with the key they are about.
"""

from __future__ import annotations

import inspect
import math
from pathlib import Path

import numpy as np

from contopt.assembly.model import Acceleration, Body, BodyForce, Dirichlet, LoadPath, Model, SoftSupport, Traction
from contopt.cases.keys import ABSENT, PRESENT
from contopt.cases.keys_model import GENERATORS, LOADS, MATERIALS, MESH_KEYS, MODEL
from contopt.cases.spec_tool import rigid_body, tool_mesh
from contopt.cases.toml_reader import REQUIRED, Reader, Table, describe, read_options, suggest
from contopt.contact.coulomb import Coulomb
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import LAWS, law_named
from contopt.contact.verify import PenetrationCheck
from contopt.material.hyperelastic import MooneyRivlin, neo_hookean
from contopt.mesh import generators
from contopt.mesh.cad import CadOptions, mesh_cad
from contopt.mesh.io import read_mesh
from contopt.mesh.tets import tetrahedralize
from contopt.mesh.voxel import VoxelOptions, read_envelope, voxelize

_AXES = ("x", "y", "z")
#: what a rigid tool's table says of the keys it does not take
_RIGID_HINT = " (a rigid tool takes no mesh, material or fbar: its surface is rigid = {...}, its motion motion = {...})"
#: set selections are inclusive up to this fraction of the mesh size (coordinates from linspace
#: are off by round-off)
_SET_TOL = 1e-9


def read_model(r: Reader, top: Table):
    """The Model of a long-form file, its bodies by name and, per body voxelized from a closed
    surface (``mesh = { envelope = ... }``), that surface by the body's name."""
    made = _bodies(r, top)
    bodies = [b for b, _ in made]
    envelopes = {b.name: e for b, e in made if e is not None}
    by_name = {b.name: b for b in bodies}
    model = top.guard(
        None,
        Model,
        bodies=tuple(bodies),
        dirichlet=read_supports(top, by_name),
        loads=read_loads(top, by_name),
        interfaces=_contact(top, by_name),
        soft_supports=read_soft_supports(top, by_name),
    )
    return model, by_name, envelopes


# --- bodies
def _bodies(r: Reader, top: Table) -> list:
    out = []
    seen: dict[str, int] = {}  # name -> index of its body
    for i, t in enumerate(top.tables("bodies", MODEL["bodies"].names, MODEL["bodies"].required)):
        name = t.str("name")
        if name in seen:
            raise t.error("name", f"duplicate body name {name!r} (also bodies[{seen[name]}].name)")
        seen[name] = i
        rigid = t.has("rigid")  # a rigid tool: its surface and motion instead of a mesh and a material
        if t.has("motion") and not rigid:
            raise t.error(
                "motion",
                "moves a rigid tool: give its surface as rigid = {...} (a deformable body moves by [[supports]])",
            )
        t.only(MODEL["bodies"].allowed(PRESENT if rigid else ABSENT), hint=_RIGID_HINT if rigid else "")
        mesh, envelope = (tool_mesh(r, t.sub("rigid")), None) if rigid else _mesh(r, t.sub("mesh"))
        for s in t.tables("sets", MODEL["bodies.sets"].names, MODEL["bodies.sets"].required):
            mesh = _derived_set(s, mesh)
        if rigid:
            out.append((rigid_body(t, name, mesh), None))
            continue
        material = _material(t.sub("material"))
        fbar = t.bool("fbar", MODEL["bodies"].default("fbar"))
        out.append((t.guard(None, Body, name, mesh, material, fbar=fbar), envelope))
    if not out:
        raise top.error("bodies", "needs at least one [[bodies]] table")
    return out


def _mesh(r: Reader, t: Table) -> tuple:
    """The body's mesh and, where it is the voxels of a closed surface, that surface (else None)."""
    mesh = _mesh_of(r, t)
    return mesh if isinstance(mesh, tuple) else (mesh, None)


def _mesh_of(r: Reader, t: Table):
    given = [k for k in ("file", "cad", "envelope") if t.has(k)]
    if len(given) > 1:
        raise t.error(
            given[1],
            f"give one of file (a mesh file), cad (a CAD file Gmsh meshes) or envelope (voxels of a "
            f"closed surface), not {' and '.join(given)}",
        )
    if t.has("file"):
        t.only(MODEL["bodies.mesh"].allowed(PRESENT))
        file = Path(t.str("file"))
        path = file if file.is_absolute() else r.base_dir / file
        if not path.exists():
            raise t.error("file", f"no such file: {path}")
        return t.guard(None, read_mesh, path, body=t.str("body", None))
    if t.has("cad"):
        return _cad_mesh(r, t)
    if t.has("envelope"):
        return _envelope_mesh(r, t)
    if not t.has("generator"):
        raise t.error(
            None,
            f"needs generator (one of {list(GENERATORS)}), file (a mesh file), cad (a CAD file) or envelope "
            "(a closed surface, voxelized)",
        )
    gen = t.str("generator", choices=GENERATORS)
    keys = MESH_KEYS[gen]
    t.only(MODEL["bodies.mesh"].allowed(gen))
    params = inspect.signature(getattr(generators, gen)).parameters
    kw = {}
    for k, kind in keys.items():
        required = params[k].default is inspect.Parameter.empty
        if kind.startswith("angle"):
            v = t.angle(k, REQUIRED if required else None, n=2 if kind == "angles" else 1)
        elif kind == "grading":
            v = _grading(t, k) if t.has(k) else None
        else:
            getter = {"string": "str", "boolean": "bool"}.get(kind, kind)  # the Table getter of the type
            v = getattr(t, getter)(k, REQUIRED if required else None)
        if v is not None:
            kw[k] = v
    section = MODEL["bodies.mesh"]
    element = t.str("element", section.default("element"), choices=("hex8", "tet"))
    order = t.int("order", section.default("order"))
    if order not in (1, 2):
        raise t.error("order", f"must be 1 (hex8 or tet4) or 2 (tet10), got {order!r}")
    if order == 2 and element == "hex8":
        raise t.error("order", 'order = 2 is tet10: set element = "tet" (hex8 is linear)')
    mesh = t.guard(None, getattr(generators, gen), **kw)
    return mesh if element == "hex8" else t.guard(None, tetrahedralize, mesh, order)


def _cad_mesh(r: Reader, t: Table):
    """The hex8 (or tet4 / tet10) mesh Gmsh makes of a CAD file (contopt.mesh.cad)."""
    t.only(MODEL["bodies.mesh"].allowed(PRESENT, "cad"))
    file = Path(t.str("cad"))
    path = file if file.is_absolute() else r.base_dir / file
    if not path.exists():
        raise t.error("cad", f"no such file: {path}")
    section = MODEL["bodies.mesh"]
    options = t.guard(
        None,
        CadOptions,
        size=t.positive("size"),
        order=t.int("order", section.default("order")),
        scale=t.positive("scale", section.default("scale")),
        element=t.str("element", section.default("element"), choices=("hex8", "tet")),
    )
    kw = {"order": options.order, "scale": options.scale, "element": options.element}
    return t.guard(None, mesh_cad, path, options.size, **kw)


def input_path(t: Table, k: str) -> Path:
    """The file named by key ``k``, relative to the problem file's folder; an error naming the key when it does
    not exist."""
    file = Path(t.str(k))
    path = file if file.is_absolute() else t.r.base_dir / file
    if not path.exists():
        raise t.error(k, f"no such file: {path}")
    return path


def _envelope_mesh(r: Reader, t: Table):
    """The hex8 voxels of a closed surface (contopt.mesh.voxel), a design domain from its envelope,
    and that surface (its design's exported surface is cut to it)."""
    t.only(MODEL["bodies.mesh"].allowed(PRESENT, "envelope"))
    path = input_path(t, "envelope")
    options = t.guard(
        None,
        VoxelOptions,
        size=t.positive("size"),
        scale=t.positive("scale", MODEL["bodies.mesh"].default("scale")),
    )
    surface = t.guard("envelope", read_envelope, path, options.scale, options.size)
    return t.guard(None, voxelize, surface, options.size, str(path)), surface


def _grading(t: Table, k: str):
    """box grading: a ratio for all axes, or per axis a ratio, "uniform" or a list of coordinates."""
    v = t.raw(k)
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return float(v)
    bad = t.error(
        k,
        'must be a ratio > 0, or a list of 3 entries each a ratio > 0, "uniform" or a list of '
        f"increasing coordinates; got {describe(v)}",
    )
    if not isinstance(v, list) or len(v) != 3:
        raise bad
    out: list[float | np.ndarray | None] = []
    for e in v:
        if e == "uniform":
            out.append(None)
        elif isinstance(e, (int, float)) and not isinstance(e, bool):
            out.append(float(e))
        elif isinstance(e, list) and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in e):
            out.append(np.asarray(e, dtype=np.float64))
        else:
            raise bad
    return out


def _derived_set(t: Table, mesh):
    """A node (and facet) set selected from an existing set by coordinate ranges or a nearest point."""
    name = t.str("name")
    if name in mesh.node_sets or name in mesh.facet_sets:
        raise t.error("name", f"the mesh already has a set {name!r}; choose another name")
    source = t.str("from", MODEL["bodies.sets"].default("from"))
    if source not in mesh.facet_sets and source not in mesh.node_sets:
        names = sorted(set(mesh.facet_sets) | set(mesh.node_sets))
        raise t.error("from", f"the mesh has no set {source!r}; {suggest(source, names)}sets: {names}")
    ranges = {a: t.vector(a, None, n=2, infinite=True) for a in _AXES}
    nearest = _points(t, "nearest")
    if nearest is not None and any(v is not None for v in ranges.values()):
        raise t.error("nearest", "give coordinate ranges (x, y, z) or nearest, not both")
    if nearest is None and all(v is None for v in ranges.values()):
        raise t.error(None, "needs coordinate ranges (x = [min, max], ...) or nearest = [x, y, z]")
    for a, rng in ranges.items():
        if rng is not None and rng[0] > rng[1]:
            raise t.error(a, f"must be [min, max] with min <= max, got {describe(t.raw(a))}")
    if nearest is not None:
        return _nearest_set(t, mesh, name, source, nearest)
    return _range_set(t, mesh, name, source, ranges)


def _points(t: Table, k: str):
    """One point [x, y, z] or a list of points, as a (k, 3) array; None when absent."""
    v = t.raw(k, None)
    if v is None:
        return None
    points = v if isinstance(v, list) and v and all(isinstance(p, list) for p in v) else [v]
    for p in points:
        if not (
            isinstance(p, list)
            and len(p) == 3
            and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in p)
        ):
            raise t.error(k, f"must be a point [x, y, z] or a list of points, got {describe(v)}")
    return np.asarray(points, dtype=np.float64)


def _nearest_set(t: Table, mesh, name: str, source: str, points: np.ndarray):
    """The nodes of ``source`` nearest to the points, in their order."""
    nodes = mesh.node_set(source)
    picked = [int(nodes[np.argmin(np.linalg.norm(mesh.points[nodes] - p, axis=1))]) for p in points]
    if len(set(picked)) < len(picked):
        raise t.error("nearest", "two of the points pick the same node; give points near distinct nodes")
    return mesh.with_sets(node_sets={name: np.array(picked, dtype=np.int64)})


def _range_set(t: Table, mesh, name: str, source: str, ranges: dict):
    """The facets (by their centres) or nodes of ``source`` within the coordinate ranges."""
    tol = _SET_TOL * float(np.ptp(mesh.points, axis=0).max())

    def inside(X):
        keep = np.ones(len(X), bool)
        for d, a in enumerate(_AXES):
            if ranges[a] is not None:
                keep &= (X[:, d] >= ranges[a][0] - tol) & (X[:, d] <= ranges[a][1] + tol)
        return keep

    if source in mesh.facet_sets:
        facets = mesh.facet_set(source)
        facets = facets[inside(mesh.points[mesh.facet_nodes(facets)].mean(axis=1))]
        if not len(facets):
            raise t.error(None, f"selects no facet of {source!r}")
        nodes = np.unique(mesh.facet_nodes(facets))
        return mesh.with_sets(node_sets={name: nodes}, facet_sets={name: facets})
    nodes = mesh.node_set(source)
    nodes = nodes[inside(mesh.points[nodes])]
    if not len(nodes):
        raise t.error(None, f"selects no node of {source!r}")
    return mesh.with_sets(node_sets={name: nodes})


def _material(t: Table):
    model = t.str("model", choices=MATERIALS)
    if model == "neo-hookean":
        t.only(MODEL["bodies.material"].allowed(model))
        return t.guard(None, neo_hookean, t.number("E"), t.number("nu"), t.number("mass_density", 0.0))
    if t.has("kappa") or t.has("A") or t.has("B"):
        t.only(("model", "kappa", "A", "B", "mass_density"), hint=" (give kappa, A, B or E, nu, b_fraction, not both)")
        return t.guard(
            None,
            MooneyRivlin,
            kappa=t.number("kappa"),
            A=t.number("A", 0.0),
            B=t.number("B", 0.0),
            mass_density=t.number("mass_density", 0.0),
        )
    t.only(("model", "E", "nu", "b_fraction", "mass_density"), hint=" (or kappa, A, B instead of E, nu, b_fraction)")
    return t.guard(
        None,
        MooneyRivlin.from_E_nu,
        t.number("E"),
        t.number("nu"),
        t.number("b_fraction", 0.0),
        t.number("mass_density", 0.0),
    )


# --- names
def body_name(t: Table, k: str, by_name: dict) -> str:
    """A body's name, one of ``by_name``."""
    name = t.str(k)
    if name not in by_name:
        raise t.error(k, f"unknown body {name!r}; {suggest(name, by_name)}bodies: {list(by_name)}")
    return name


def _set_name(t: Table, k: str, body, kind: str) -> str:
    """A set of ``body``: a facet set, or for ``kind="node"`` a node set or a facet set (its nodes)."""
    name = t.str(k)
    sets = body.mesh.facet_sets
    if kind == "node":
        sets = {**body.mesh.node_sets, **sets}
    if name not in sets:
        raise t.error(
            k, f"body {body.name!r} has no {kind} set {name!r}; {suggest(name, sets)}its {kind} sets: {sorted(sets)}"
        )
    return name


# --- conditions
def read_supports(top: Table, by_name: dict) -> tuple:
    out = []
    for t in top.tables("supports", MODEL["supports"].names, MODEL["supports"].required):
        body = body_name(t, "body", by_name)
        node_set = _set_name(t, "set", by_name[body], "node")
        comps = t.str("components", MODEL["supports"].default("components"))
        if "path" in t.data:  # rows [t, value per component]: piecewise linear in the load factor
            if "value" in t.data:
                raise t.error("path", "give either value (proportional to the load) or path, not both")
            value = t.guard("path", LoadPath, t.raw("path"))
        elif isinstance(t.raw("value", 0.0), list):
            value = t.vector("value", n=len(comps))
        else:
            value = t.number("value", 0.0)
        bc = t.guard(None, Dirichlet, body, node_set, comps, value)
        t.guard(None, Model, bodies=(by_name[body],), dirichlet=(bc,))
        out.append(bc)
    return tuple(out)


def read_soft_supports(top: Table, by_name: dict) -> tuple:
    """Springs to ground fading as ``1 - t`` (for a body held only by contact until it touches)."""
    out = []
    for t in top.tables("soft_supports", MODEL["soft_supports"].names, MODEL["soft_supports"].required):
        out.append(t.guard(None, SoftSupport, body_name(t, "body", by_name), t.number("stiffness")))
    return tuple(out)


def read_loads(top: Table, by_name: dict) -> tuple:
    out = []
    for t in top.tables("loads", None, ("type",)):
        kind = t.str("type", choices=LOADS)
        t.only(MODEL["loads"].allowed(kind))
        body = body_name(t, "body", by_name)
        load: Traction | BodyForce | Acceleration
        if kind == "traction":
            load = Traction(body, _set_name(t, "set", by_name[body], "facet"), t.vector("traction"))
        else:
            load = (BodyForce if kind == "body-force" else Acceleration)(body, t.vector(LOADS[kind]))
        t.guard("set" if kind == "traction" else "body", Model, bodies=(by_name[body],), loads=(load,))
        out.append(load)
    return tuple(out)


def _contact_sides(t: Table, by_name: dict) -> dict:
    """``nonmortar`` and ``mortar``, or ``surfaces`` (two, the nonmortar side chosen by the model),
    as ContactInterface's keywords."""

    def surface(s: Table) -> tuple:
        body = body_name(s, "body", by_name)
        return (body, _set_name(s, "set", by_name[body], "facet"))

    given = [k for k in ("nonmortar", "mortar") if t.has(k)]
    if t.has("surfaces"):
        if given:
            raise t.error(
                given[0], "give nonmortar and mortar, or surfaces (the nonmortar side chosen for you), not both"
            )
        tables = t.tables("surfaces", MODEL["contact.surfaces"].names, MODEL["contact.surfaces"].required)
        if len(tables) != 2:
            raise t.error("surfaces", f"must be two surfaces, [{{body, set}}, {{body, set}}], got {len(tables)}")
        return {"surfaces": tuple(surface(s) for s in tables)}
    if len(given) < 2:
        missing = next(k for k in ("nonmortar", "mortar") if k not in given)
        raise t.error(missing, "required key is missing (or give surfaces = [{body, set}, {body, set}] instead)")
    return {
        k: surface(t.sub(k, MODEL[f"contact.{k}"].names, MODEL[f"contact.{k}"].required))
        for k in ("nonmortar", "mortar")
    }


def _contact(top: Table, by_name: dict) -> tuple:
    out: list = []
    seen: dict[str, int] = {}  # name -> index of its interface
    for i, t in enumerate(top.tables("contact")):
        if t.has("enforcement"):  # its name until 0.1
            raise t.error("enforcement", f'the key is now called law: write law = "{t.raw("enforcement")}"')
        t.only(MODEL["contact"].names)
        sides = _contact_sides(t, by_name)
        law = t.guard(None, law_named, t.str("law", MODEL["contact"].default("law"), LAWS), eps=t.number("eps", None))
        check = read_options(t.r, PenetrationCheck, t.raw("check", {}), t.key("check"))
        # friction = 0.3 (the coefficient) or friction = {mu = 0.3, eps = ...}
        raw = t.raw("friction", None)
        friction = (
            None
            if raw is None
            else read_options(t.r, Coulomb, raw, t.key("friction"))
            if isinstance(raw, dict)
            else t.guard("friction", Coulomb, t.number("friction"))
        )
        iface = t.guard(
            None,
            ContactInterface,
            **sides,
            law=law,
            check=check,
            skin=t.number("skin", None),
            max_angle_deg=t.number("max_angle_deg", MODEL["contact"].default("max_angle_deg")),
            friction=friction,
            name=t.str("name", None),
        )
        if iface.name in seen:
            hint = "" if t.has("name") else " (the default name); give one of them a name"
            raise t.error(
                "name", f"duplicate contact interface name {iface.name!r} (also contact[{seen[iface.name]}]){hint}"
            )
        seen[iface.name] = i
        t.guard(None, Model, bodies=tuple(by_name.values()), interfaces=(iface,))
        out.append(iface)
    return tuple(out)
