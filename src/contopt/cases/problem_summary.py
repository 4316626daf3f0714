"""The problem in plain words: what ``report.html`` says of a run's bodies, supports, prescribed
motions, loads, contact interfaces (with the nonmortar side and who chose it), design, objective
and constraints.

:func:`problem_summary` makes it from a :class:`~contopt.optimize.problem.DesignProblem` (a problem
file's, read, or one built in Python) and :func:`model_summary` from a Model alone (a `contopt
forward` run): a tuple of :class:`Sentence`, one per topic. The numbers are the user's own, in the
user's units (no unit is assumed or shown). The report (:mod:`contopt.optimize.report_story`) sits
below this layer and cannot build it, so a run directory keeps it: :func:`record_summary` writes
``checkpoint/problem_summary.json`` when a run starts (:meth:`contopt.cases.spec_run.RunSpec.run`),
and a forward run keeps it in its ``summary.json`` under ``"problem"``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contopt.assembly.model import Acceleration, BodyForce, LoadPath, Model, RigidMotion, Traction
from contopt.contact.laws import AugmentedLagrangian, Penalty
from contopt.design import BSplineGrid, Density
from contopt.io.files import write_atomically
from contopt.material.hyperelastic import MooneyRivlin
from contopt.optimize.report_story import PROBLEM_SUMMARY

_COUNTS = ("no", "One", "Two", "Three", "Four", "Five", "Six", "Seven", "Eight", "Nine", "Ten")
#: the contact laws in words (their names in a problem file: ``law = "alm" | "penalty"``)
_LAWS = {AugmentedLagrangian.name: "augmented Lagrangian", Penalty.name: "penalty"}
#: what ``objective.normalize`` divides by, in words
_NORMALIZE = {"full": "its value at the full design", "initial": "its value at the initial design"}
#: the responses integrated over bodies (the others are over contact interfaces)
_OVER_BODIES = ("strain-energy", "compliance", "volume-fraction", "stress")


@dataclass(frozen=True)
class Sentence:
    """One sentence of the summary: its ``topic`` (bodies, supports, motions, soft_supports, loads,
    contact, design, objective, constraints) and its plain ``text``."""

    topic: str
    text: str


def as_json(sentences) -> list[dict]:
    """The summary as JSON-ready ``[{"topic": ..., "text": ...}, ...]``."""
    return [{"topic": s.topic, "text": s.text} for s in sentences]


def record_summary(out, sentences) -> Path:
    """Write the summary into the run directory ``out`` (``checkpoint/problem_summary.json``); its path."""
    path = Path(out) / PROBLEM_SUMMARY
    text = json.dumps(as_json(sentences), indent=1, ensure_ascii=False)
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path


# --- numbers
def _num(v) -> str:
    """A number as the user would write it (``1``, ``0.3``, ``-0.6``, ``1e-06``)."""
    v = float(v)
    return "0" if v == 0 else f"{v:g}"


def _vec(values) -> str:
    return "(" + ", ".join(_num(v) for v in values) + ")"


def _region_words(region) -> str:
    """``, cells in the box (..) to (..)`` of a stress's region (a box or a union of boxes), "" without one."""
    if region is None:
        return ""
    boxes = getattr(region, "boxes", (region,))
    if not all(hasattr(b, "lower") for b in boxes):
        return ", cells in its region"
    words = " or ".join(f"{_vec(b.lower)} to {_vec(b.upper)}" for b in boxes)
    return f", cells with centre in the box {words}" if len(boxes) == 1 else f", cells with centre in the boxes {words}"


def _by(components: str, values) -> str:
    """A prescribed displacement: ``(0, 0, -0.6)`` for xyz, ``-0.1 in z``, ``(0.1, -0.2) in x, z``."""
    values = np.broadcast_to(np.atleast_1d(np.asarray(values, dtype=float)), (len(components),))
    if components == "xyz":
        return _vec(values)
    if len(components) == 1:
        return f"{_num(values[0])} in {components}"
    return f"{_vec(values)} in {', '.join(components)}"


def _count(n: int, one: str, many: str) -> str:
    return f"{_COUNTS[n] if n < len(_COUNTS) else n} {one if n == 1 else many}"


def _listed(items: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


# --- the model
def _material(m) -> str:
    if isinstance(m, MooneyRivlin):
        name = "neo-Hookean" if m.B == 0 else "Mooney-Rivlin"
        extra = "" if m.B == 0 else f", b_fraction = {_num(m.B / (m.A + m.B))}"
    else:
        name, extra = type(m).__name__, ""
    text = f"{name}, E = {_num(m.youngs_modulus)}, nu = {_num(m.poisson_ratio)}{extra}"
    density = float(getattr(m, "mass_density", 0.0))
    return text + (f", mass_density = {_num(density)}" if density > 0 else "")


def _body(b) -> str:
    if b.rigid is not None:  # its one layer of cells is its surface: a cell a facet, no material
        return f"{b.name} (a rigid tool, {len(b.mesh.cells):,} facets)"
    n, element = len(b.mesh.cells), b.mesh.element
    fbar = ", F-bar" if b.fbar and element == "hex8" else ""  # tets take none (Body)
    return f"{b.name} ({element}, {n:,} cell{'s' * (n != 1)}, {_material(b.material)}{fbar})"


def _bodies(model: Model) -> Sentence:
    parts = [_body(b) for b in model.bodies]
    return Sentence("bodies", f"{_count(len(parts), 'body', 'bodies')}: {_listed(parts)}.")


def _motion(bc) -> str | None:
    """How a prescribed displacement moves its nodes, or None for a support (zero throughout)."""
    value = bc.value
    if isinstance(value, RigidMotion):
        return _rigid(value)
    if isinstance(value, LoadPath):
        stops = [f"{_by(bc.components, row[1:])} at load factor {_num(row[0])}" for row in value.points]
        return f"moved along a path through {_listed(stops)}"
    if callable(value):
        return "moved as a function of position and load factor"
    if not np.any(np.atleast_1d(np.asarray(value, dtype=float))):
        return None
    return f"moved by {_by(bc.components, value)}"


def _rigid(m: RigidMotion) -> str | None:
    """How a rigid tool moves: its translation and its turn, or None when it stays where it is."""
    parts = []
    if isinstance(m.translation, LoadPath):
        stops = [f"{_vec(row[1:])} at load factor {_num(row[0])}" for row in m.translation.points]
        parts.append(f"translated along a path through {_listed(stops)}")
    elif np.any(m.translation):
        parts.append(f"translated by {_vec(m.translation)}")
    if isinstance(m.angle, LoadPath) or m.angle:
        parts.append(f"turned about {_vec(m.axis)} through {_vec(m.point)}")
    return f"moved rigidly: {' and '.join(parts)}" if parts else None


def _conditions(model: Model, n_steps: int | None) -> list[Sentence]:
    """Supports, prescribed motions, soft supports and loads."""
    supports, motions = [], []
    for bc in model.dirichlet:
        moved = _motion(bc)
        where = f"{bc.body}/{bc.node_set}"
        if moved is None:
            supports.append(f"{where} fixed in {', '.join(bc.components)}")
        else:
            motions.append(f"{where} {moved}")
    steps = f" over {n_steps} load step{'s' * (n_steps != 1)}" if n_steps else ""
    out = []
    if supports:
        out.append(Sentence("supports", f"Supports: {'; '.join(supports)}."))
    if motions:
        out.append(Sentence("motions", f"Prescribed motions{steps}: {'; '.join(motions)}."))
    if model.soft_supports:
        springs = "; ".join(f"{s.body}, stiffness {_num(s.stiffness)}" for s in model.soft_supports)
        out.append(Sentence("soft_supports", f"Soft supports (springs to ground fading as 1 - t): {springs}."))
    if model.loads:
        loads = "; ".join(_load(load) for load in model.loads)
        out.append(Sentence("loads", f"Loads{'' if motions else steps}: {loads}."))
    return out


def _load(load) -> str:
    if isinstance(load, Traction):
        return f"traction {_vec(load.traction)} on {load.body}/{load.facet_set}"
    if isinstance(load, BodyForce):
        return f"body-force {_vec(load.force)} on {load.body}"
    if isinstance(load, Acceleration):
        return f"acceleration {_vec(load.acceleration)} on {load.body}"
    return f"{type(load).__name__} on {getattr(load, 'body', '?')}"


def _interface(iface) -> str:
    nonmortar, mortar = "/".join(iface.nonmortar), "/".join(iface.mortar)
    law = getattr(iface.law, "name", "")
    friction = iface.friction
    rubs = "frictionless" if friction is None else f"Coulomb friction mu = {_num(friction.mu)}"
    if iface.sides == "chosen":
        why = iface.choice.split(": ", 1)[1] if iface.choice.startswith("nonmortar ") else iface.choice
        who = f"chosen: {why}"
    else:
        who = "given by the user"
    law = _LAWS.get(law, law or type(iface.law).__name__)
    return f"interface {iface.name}: nonmortar side {nonmortar} ({who}), mortar side {mortar}, {law}, {rubs}"


def _contact(model: Model) -> list[Sentence]:
    if not model.interfaces:
        return []
    parts = [_interface(i) for i in model.interfaces]
    head = "Contact" if len(parts) == 1 else f"Contact, {_count(len(parts), 'interface', 'interfaces').lower()}"
    return [Sentence("contact", f"{head}: {'; '.join(parts)}.")]


def model_summary(model: Model, n_steps: int | None = None) -> tuple[Sentence, ...]:
    """The bodies, supports, prescribed motions (applied over ``n_steps`` load steps), soft
    supports, loads and contact interfaces of ``model``, in words."""
    return (_bodies(model), *_conditions(model, n_steps), *_contact(model))


# --- the design and the responses
def _designed(d) -> str:
    p = d.parameterization
    if isinstance(p, Density):
        how = f"density method, cone filter radius {_num(p.radius)}"
    elif isinstance(p, BSplineGrid):
        how = f"B-spline level set, {' x '.join(str(n) for n in p.shape)} control points of degree {p.degree}"
    else:
        how = type(p).__name__
    parts = [how]
    if d.symmetry is not None:
        s = d.symmetry
        parts.append(f"{s.n_sectors} sectors about {s.axis}{' with reflection' if s.reflection else ''}")
    if d.skins:
        parts.append(_count(len(d.skins), "skin", "skins").lower())
    parts += [f"fixed {k} cells" for k in ("solid", "void") if getattr(d, k) is not None]
    vf = d.volume_fraction
    parts.append(f"volume fraction \u2264 {_num(vf)}" if vf is not None else "no volume constraint")
    return f"{d.body} ({'; '.join(parts)})"


def _design(design) -> Sentence:
    bodies = _listed([_designed(d) for d in design.bodies])
    maps = (
        f"SIMP p = {_num(design.simp.p)}, nu0 = {_num(design.simp.nu0)}, Heaviside eta = {_num(design.heaviside.eta)}"
    )
    return Sentence("design", f"Design: {bodies}; {maps}.")


#: the load-path responses in words (contopt.responses.path)
_ALONG_PATH = {
    "force-target": "the force target (the mean squared miss of the {force} from its target curve at {n} load steps)",
    "force-max": "the force max (the largest {force} over {n} load steps, smoothly)",
    "force-min": "the force min (the smallest {force} over {n} load steps, smoothly)",
}


def _steps_words(response) -> str:
    """``6`` (a count, at k / 6) or ``3 (t = 0.5, 0.75, 1)`` (the load factors listed)."""
    if isinstance(response.steps, int):
        return str(response.steps)
    return f"{len(response.stops)} (t = {', '.join(f'{t:g}' for t in response.stops)})"


def _quantity_words(quantity) -> str:
    """What a load-path response reads at each step, in words (contopt.responses.quantities)."""
    body, node_set = getattr(quantity, "body", None), getattr(quantity, "set", None)
    if body is None:  # the contact force or the strain energy: built-in responses
        return response_words(quantity)[1]
    on = f" on {node_set}" if node_set else ""
    direction = getattr(quantity, "direction", None)
    along = f" along {_vec(direction)}" if direction is not None else ""
    if type(quantity).__name__ == "Reaction":
        return f"the reaction of {body}'s support{on}{along or ' along its motion'}"
    return f"the mean displacement of {body}{on}{along}"


def _kind(response) -> str | None:
    """The built-in response's name in a problem file (``strain-energy``), or None."""
    from contopt.responses.functionals import BUILTIN  # JAX: a response was built, so it is loaded

    return next((name for name, cls in BUILTIN.items() if type(response) is cls), None)


def response_words(response) -> tuple[str, str]:
    """``(sense, words)`` of a response: ``("maximize", "the strain energy of slab")`` for
    ``-StrainEnergy("slab")``; the sense is "minimize" unless the response is a negated one."""
    from contopt.responses.base import Combination  # JAX (see _kind)

    sense = "minimize"
    name = str(getattr(response, "name", ""))
    if isinstance(response, Combination) and name.startswith("-") and len(response.parts) == 1:
        sense, response = "maximize", response.parts[0]
    kind = _kind(response)
    if kind is None:
        return sense, f"the response {getattr(response, 'name', type(response).__name__)}"
    if kind in _ALONG_PATH:  # a load-path response: the quantity it reads, at its load steps
        force = _quantity_words(response.quantity).removeprefix("the ")
        return sense, _ALONG_PATH[kind].format(force=force, n=_steps_words(response))
    words = kind.replace("-", " ")
    if kind == "pressure-variance" and "relative" in str(response.name):
        words = "relative pressure variance"
    if kind == "stress":  # contopt.responses.stress: its aggregation and relaxation
        ks = response.aggregate == "ks"
        how = f"KS function, sharpness {response.sharpness:g}," if ks else f"{response.p:g}-norm"
        words = f"stress (the {how} of the von Mises stress relaxed as rho^{response.q:g})"
    if kind in _OVER_BODIES:
        bodies = response.bodies
        where = f"of {_listed(list(bodies))}" if bodies else "of all bodies"
        where += _region_words(getattr(response, "region", None))
    else:
        parts = getattr(response, "parts", None) or (response,)  # pressure-variance: its parts name them
        interfaces = getattr(response, "interfaces", None) or getattr(parts[0], "interfaces", None)
        where = f"at interface {_listed(list(interfaces))}" if interfaces else "at every interface"
    direction = getattr(response, "direction", None)
    if isinstance(direction, str):
        where += " (the size of the resultant)"
    elif direction is not None:
        where += f" along {_vec(direction)}"
    return sense, f"the {words} {where}"


def _objective(objective, normalize) -> Sentence:
    sense, words = response_words(objective)
    if isinstance(normalize, str):
        scale = _NORMALIZE.get(normalize)
    else:
        scale = _num(normalize)
    return Sentence("objective", f"Objective: {sense} {words}{f', divided by {scale}' if scale else ''}.")


def _constraints(constraints) -> list[Sentence]:
    parts = []
    for c in constraints:
        words = response_words(c.response)[1].removeprefix("the ")
        if c.lower is not None and c.upper is not None:
            parts.append(f"{_num(c.lower)} \u2264 {words} \u2264 {_num(c.upper)}")
        elif c.upper is not None:
            parts.append(f"{words} \u2264 {_num(c.upper)}")
        elif c.lower is not None:
            parts.append(f"{words} \u2265 {_num(c.lower)}")
    return [Sentence("constraints", f"Constraints: {'; '.join(parts)}.")] if parts else []


def _model_of(model) -> Model:
    """The Model of a Model, a Discretization or a System."""
    model = getattr(model, "disc", model)
    return getattr(model, "model", model)


def problem_summary(problem) -> tuple[Sentence, ...]:
    """The summary of a design problem (see the module docstring): the model's, the design, the
    objective and the constraints."""
    return (
        *model_summary(_model_of(problem.model), problem.newton.n_steps),
        _design(problem.design),
        _objective(problem.objective, problem.normalize),
        *_constraints(problem.constraints),
    )
