"""The design sections of a problem file: ``[design]`` (maps, designed bodies with their
parameterization, symmetry, skins and fixed regions), ``[objective]`` and ``[[constraints]]``
(see :mod:`contopt.cases.spec` for the keys).

As in :mod:`contopt.cases.spec_model`, the ranges of values are the constructed objects'
own checks, named by their key through :meth:`~contopt.cases.toml_reader.Table.guard`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.cases.keys_run import RUN, SENSES
from contopt.cases.spec_model import body_name, input_path
from contopt.cases.toml_reader import Table, describe, read_options, suggest
from contopt.design import (
    BoxRegion,
    BSplineGrid,
    CyclicSymmetry,
    Density,
    Design,
    DesignedBody,
    EtaContinuation,
    Heaviside,
    RadialSkin,
    Robust,
    Simp,
    SurfaceRegion,
)
from contopt.mesh.voxel import read_envelope
from contopt.optimize.load_case import COMBINES
from contopt.responses.catalog import AGGREGATES, ON, READS, RESPONSES


@dataclass(frozen=True)
class BoxUnion:
    """Cells whose centroid lies in any of several regions (:class:`~contopt.design.BoxRegion` boxes,
    :class:`~contopt.design.SurfaceRegion` closed surfaces)."""

    boxes: tuple

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """(k, 3) centroids -> (k,) bool."""
        mask = np.zeros(len(X), bool)
        for box in self.boxes:
            mask |= box(X)
        return mask


# --- design
def read_design(t: Table, by_name: dict, envelopes: dict | None = None):
    """The Design and, per designed body, ``(its table, its DesignedBody)`` (to name errors found later).

    envelopes : body name -> the closed surface its voxels were made from (the design's exported
        surface is cut to it)
    """
    heaviside = t.guard(None, Heaviside, t.number("eta", RUN["design"].default("eta")))
    simp = t.guard(None, Simp, t.number("p", RUN["design"].default("p")), t.number("nu0", RUN["design"].default("nu0")))
    entries = []
    seen: dict[str, str] = {}  # name -> the key path of the table that designs it
    for b in t.tables("bodies", RUN["design.bodies"].names, RUN["design.bodies"].required):
        name = body_name(b, "body", by_name)
        if by_name[name].rigid is not None:
            raise b.error("body", f"body {name!r} is a rigid tool; design a deformable body")
        if name in seen:
            raise b.error("body", f"body {name!r} is designed twice (also {seen[name]})")
        seen[name] = b.path
        entries.append((b, _designed_body(b, name, (envelopes or {}).get(name))))
    if not entries:
        raise t.error("bodies", "needs at least one [[design.bodies]] table")
    robust = None
    if t.has("robust"):
        r = t.sub("robust", RUN["design.robust"].names, RUN["design.robust"].required)
        robust = r.guard(None, Robust, r.number("delta", RUN["design.robust"].default("delta")))
    cont = None
    if t.has("eta_continuation"):
        c, keys = t.sub("eta_continuation", *_names("design.eta_continuation")), RUN["design.eta_continuation"]
        cont = c.guard(
            None,
            EtaContinuation,
            c.number("start", keys.default("start")),
            c.number("factor", keys.default("factor")),
            c.int("every", keys.default("every")),
        )
    bodies = tuple(d for _, d in entries)
    design = t.guard(
        None,
        Design,
        bodies=bodies,
        heaviside=heaviside,
        simp=simp,
        robust=robust,
        eta_continuation=cont,
    )
    return design, entries


def _names(path: str) -> tuple:
    return RUN[path].names, RUN[path].required


def _designed_body(t: Table, name: str, envelope=None):
    if t.has("density") == t.has("bspline"):
        raise t.error(
            None, "needs exactly one parameterization: density = {radius = ...} or bspline = {control_points = [...]}"
        )
    skins = tuple(read_options(t.r, RadialSkin, s.data, s.path) for s in t.tables("skins"))
    vf = t.number("volume_fraction", None)  # its range is DesignedBody's rule
    return t.guard(
        None,
        DesignedBody,
        name,
        _parameterization(t),
        volume_fraction=vf,
        symmetry=_symmetry(t),
        skins=skins,
        solid=_boxes(t, "solid"),
        void=_boxes(t, "void"),
        skin_eps=t.number("skin_eps", RUN["design.bodies"].default("skin_eps")),
        envelope=envelope,
    )


def _parameterization(t: Table):
    if t.has("density"):
        d = t.sub("density", RUN["design.bodies.density"].names, RUN["design.bodies.density"].required)
        return d.guard(None, Density, d.number("radius"))
    return _bspline(t.sub("bspline"))


def _symmetry(t: Table):
    if not t.has("symmetry"):
        return None
    sym = RUN["design.bodies.symmetry"]
    s = t.sub("symmetry", sym.names, sym.required)
    return s.guard(
        None,
        CyclicSymmetry,
        s.int("sectors"),
        s.bool("reflection", sym.default("reflection")),
        s.str("axis", sym.default("axis")),
        s.vector("center", sym.default("center")),
        s.angle("start", sym.default("start")),
    )


def _bspline(t: Table):
    t.only(RUN["design.bodies.bspline"].names)
    if t.has("control_points") == t.has("patches"):
        raise t.error(None, "needs control_points = [nx, ny, nz] or patches = [nx, ny, nz] (one of the two)")
    for a, b in (("lower", "origin"), ("upper", "lengths")):
        if t.has(a) and t.has(b):
            raise t.error(b, f"give {a} or {b}, not both")
    origin = t.vector("lower", None) if t.has("lower") else t.vector("origin", None)
    lengths = t.vector("lengths", None)
    if t.has("upper"):  # the grid's box is origin + lengths: say it of the keys given
        upper = t.vector("upper")
        if origin is None:
            raise t.error("lower", "required with upper (the box is lower..upper)")
        lengths = tuple(u - lo for u, lo in zip(upper, origin))
        if min(lengths) <= 0:
            raise t.error("upper", f"must exceed lower in every direction, got {list(upper)} and {list(origin)}")
    degree = t.int("degree", RUN["design.bodies.bspline"].default("degree"))
    if t.has("control_points"):
        return t.guard(None, BSplineGrid.with_control_points, t.ints("control_points"), degree, origin, lengths)
    return t.guard(None, BSplineGrid, t.ints("patches"), degree, origin, lengths)


def _boxes(t: Table, k: str, table: str | None = None):
    """The region of key ``k``: a box {lower, upper}, a closed surface (a file name or {file, scale}), or a list
    of them (their union); None when absent. ``table``: the key table they follow (default ``design.bodies.<k>``)."""
    if not t.has(k):
        return None
    keys = RUN[table or f"design.bodies.{k}"]
    raw = t.raw(k)
    entries = raw if isinstance(raw, list) else [raw]
    regions = []
    for i, entry in enumerate(entries):
        if isinstance(entry, str):  # a bare file name: {file = NAME}
            entry = {"file": entry}
        where = f"{t.key(k)}[{i}]" if isinstance(raw, list) else t.key(k)
        regions.append(_region(t.r.table(entry, where, keys.names), k))
    if not regions:
        raise t.error(k, "needs {lower = [...], upper = [...]}, a closed surface's file name, or a list of them")
    return regions[0] if len(regions) == 1 else BoxUnion(tuple(regions))


def _region(b: Table, k: str):
    """One box {lower, upper} or one closed surface {file, scale} of a region."""
    if b.has("file"):
        for other in ("lower", "upper"):
            if b.has(other):
                raise b.error(other, "give a box (lower, upper) or a closed surface (file), not both")
        path = input_path(b, "file")
        scale = b.positive("scale", RUN["design.bodies.solid"].default("scale"))
        return SurfaceRegion(b.guard("file", read_envelope, path, scale), str(path.name))
    if b.has("scale"):
        raise b.error("scale", "scales a closed surface's file: give file = NAME with it")
    if not (b.has("lower") and b.has("upper")):
        raise b.error(None, f"{k} needs a box {{lower = [...], upper = [...]}} or a closed surface {{file = NAME}}")
    lower, upper = b.vector("lower", infinite=True), b.vector("upper", infinite=True)
    if any(lo > up for lo, up in zip(lower, upper)):
        raise b.error("upper", f"must be >= lower in every direction, got {list(upper)} and {list(lower)}")
    return BoxRegion(lower, upper)


def check_design(model, design, entries):
    """Build the discretization and each designed body's design matrix; errors name the entry."""
    from contopt.assembly.system import discretize  # JAX: here, not atop, so load_model loads none

    disc = discretize(model)
    for t, body in entries:
        t.guard(None, Design(bodies=(body,), heaviside=design.heaviside, simp=design.simp).build, disc)
    return disc


# --- responses
def response_options() -> dict[str, tuple]:
    """What each built-in response takes besides its name (:data:`contopt.responses.catalog.RESPONSES`)."""
    return {name: kind.options for name, kind in RESPONSES.items()}


def read_response(t: Table, by_name: dict, interfaces: tuple, extra: tuple = ()):
    """A built-in response from a table ``response = NAME`` with its options (and the ``extra`` keys
    the table holds for its user); ``interfaces``: the names of the model's contact interfaces."""
    from contopt.responses.functionals import builtin  # JAX (see check_design)

    options = response_options()
    name = t.str("response", choices=options)
    own = options[name]
    for k in t.data:
        if k not in own and any(k in keys for keys in options.values()):
            raise t.error(k, f"not an option of response {name!r}; its options: {sorted(own + ('name',))}")
    t.only(("response", "name", *own, *extra))
    t.require(RESPONSES[name].required)
    if name == "stress":
        _check_aggregate(t)
    if "on" in own:
        _check_on(t)
    kw = {k: _option(t, k, by_name, interfaces) for k in ("name", *own) if t.has(k)}
    if isinstance(kw.get("set"), str) and isinstance(kw.get("bodies"), str):  # a set of that body's mesh
        t.guard("set", by_name[kw["bodies"]].mesh.node_set, kw["set"])
    reads_contact = "on" not in own or t.str("on", "contact", ON) == "contact"  # on = "reaction" ... reads none
    if not t.has("interfaces") and "interfaces" in own and not interfaces and reads_contact:
        raise t.error("response", f"{name!r} needs a [[contact]] interface; the model has none")
    return t.guard(None, builtin, name, **kw)


def _check_aggregate(t: Table) -> None:
    """The stress's aggregate and the one parameter it takes (p for the p-norm, sharpness for KS)."""
    if t.str("aggregate", "pnorm", AGGREGATES) == "ks":
        if t.has("p"):
            raise t.error("p", 'is the p-norm\'s exponent; with aggregate = "ks" give sharpness (1/stress) instead')
        if not t.has("sharpness"):
            raise t.error("sharpness", 'is needed with aggregate = "ks": a number > 0 in 1/stress, e.g. 20 / the limit')
    elif t.has("sharpness"):
        raise t.error("sharpness", 'is the KS function\'s; set aggregate = "ks" or give p (the p-norm) instead')


def _check_on(t: Table) -> None:
    """A load-path response's ``on`` and the options it reads (:data:`contopt.responses.catalog.READS`)."""
    on = t.str("on", "contact", ON)
    for k in sorted({k for reads in READS.values() for k in reads}):
        if t.has(k) and k not in READS[on]:
            takes = [o for o, reads in READS.items() if k in reads]
            raise t.error(k, f'is not read with on = "{on}" (it is with on = {takes}); leave it out')
    if on in ("reaction", "displacement") and len(t.names("bodies", ())) != 1:
        raise t.error("bodies", f'must name one body with on = "{on}" (whose support or node set it reads)')
    for k in ("set", "direction") if on == "displacement" else ():
        if not t.has(k):
            raise t.error(k, 'is needed with on = "displacement" (the node set and the direction it reads)')


def _option(t: Table, k: str, by_name: dict, interfaces: tuple):
    """A response option's value: body names, [[contact]] names, or what the response checks itself."""
    if k == "bodies":
        bodies = t.names("bodies")
        for b in bodies:
            if b not in by_name:
                raise t.error("bodies", f"unknown body {b!r}; {suggest(b, by_name)}bodies: {list(by_name)}")
        return bodies if len(bodies) > 1 else bodies[0]
    if k == "interfaces":
        if not interfaces:
            raise t.error("interfaces", "the model has no [[contact]] interfaces")
        v = t.raw("interfaces")
        if isinstance(v, list) and v and all(isinstance(i, int) and not isinstance(i, bool) for i in v):
            raise t.error("interfaces", f"give the interfaces' names, not their numbers: {list(interfaces)}")
        names = t.names("interfaces")
        for name in names:
            if name not in interfaces:
                raise t.error(
                    "interfaces",
                    f"unknown contact interface {name!r}; {suggest(name, interfaces)}interfaces: {list(interfaces)}",
                )
        return names
    if k == "direction":
        return t.vector("direction")
    if k == "steps":  # a count, or the load factors read: the response checks a list (one-line error naming it)
        v = t.raw("steps")
        if not isinstance(v, list) and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
            raise t.error("steps", f"must be an integer >= 1 or a list of load factors in (0, 1], got {describe(v)}")
        return v
    if k == "sharpness":
        return t.positive("sharpness")
    if k == "aggregate":
        return t.str("aggregate", choices=AGGREGATES)
    if k == "on":
        return t.str("on", choices=ON)
    if k == "target":
        return t.raw("target")  # the response checks the points (one-line error naming the key)
    if isinstance(t.raw(k), bool):
        return t.bool(k)
    if k == "region":  # the stress's cells: boxes as the design's solid and void take them
        return _boxes(t, k, "design.bodies.solid")
    if k in ("p", "q"):  # the stress's exponents: numbers here, their ranges checked by Stress itself
        return t.number(k)
    return t.str(k)


def read_objective(t: Table, by_name: dict, interfaces: tuple, cases: tuple = ()):
    """``(objective, normalize, combine)`` of the ``[objective]`` table (normalize is checked by
    DesignProblem); ``cases``: the names of the file's load cases."""
    objective = read_response(t, by_name, interfaces, extra=("sense", "normalize", "combine"))
    combine = t.str("combine", RUN["objective"].default("combine"), COMBINES)
    if t.has("combine") and not cases:
        raise t.error("combine", "combines the objectives of [[load_cases]]; the file has none")
    if t.str("sense", RUN["objective"].default("sense"), SENSES) == "maximize":
        objective = -objective
    normalize = t.raw("normalize", RUN["objective"].default("normalize"))
    if isinstance(normalize, bool) or not isinstance(normalize, (str, int, float)):
        raise t.error("normalize", f"must be a name or a number, got {describe(normalize)}")
    return objective, normalize, combine


def read_constraints(top: Table, by_name: dict, interfaces: tuple, cases: tuple = ()) -> tuple:
    """The ``[[constraints]]``; ``cases``: the names of the file's load cases (a constraint's ``case``)."""
    from contopt.optimize.problem import Constraint  # JAX (see check_design)

    out = []
    for t in top.tables("constraints", None, ("response",)):
        response = read_response(t, by_name, interfaces, extra=("upper", "lower", "scale", "case"))
        case = t.str("case", None)
        if case is not None and not cases:
            raise t.error("case", "names a load case; the file has no [[load_cases]]")
        if case is not None and case not in cases:
            raise t.error("case", f"unknown load case {case!r}; {suggest(case, cases)}cases: {list(cases)}")
        upper, lower = t.number("upper", None), t.number("lower", None)
        if upper is not None and lower is not None and lower > upper:
            raise t.error("lower", f"must not exceed upper ({lower} > {upper})")
        out.append(
            t.guard(None, Constraint, response, upper=upper, lower=lower, scale=t.number("scale", None), case=case)
        )
    return tuple(out)
