"""``[[load_cases]]`` of a problem file: each case's own supports, motions and loads over the file's
bodies, contact and design (:class:`contopt.optimize.load_case.LoadCase`; keys in
:mod:`contopt.cases.keys_model`). The file's own ``[[supports]]``, ``[[soft_supports]]`` and
``[[loads]]`` hold in every case; a case adds its own and may move a rigid tool otherwise."""

from __future__ import annotations

import dataclasses

from contopt.assembly.model import Model
from contopt.cases.keys_model import MODEL
from contopt.cases.spec_model import body_name, read_loads, read_soft_supports, read_supports
from contopt.cases.spec_tool import motion
from contopt.cases.toml_reader import Table, suggest
from contopt.optimize.load_case import LoadCase

#: what a case's table says of the keys it does not take
_HINT = (
    " (a load case takes its own supports, soft_supports, loads and motions; the bodies, contact and "
    "design are the file's, shared by every case)"
)


def read_load_cases(top: Table, model: Model, by_name: dict) -> tuple:
    """The LoadCases of ``top``'s ``[[load_cases]]`` (``()`` when it has none)."""
    section = MODEL["load_cases"]
    out: list[LoadCase] = []
    seen: dict[str, int] = {}
    for i, t in enumerate(top.tables("load_cases", None, section.required)):
        t.only(section.names, hint=_HINT)
        name = t.str("name")
        if name in seen:
            raise t.error("name", f"duplicate load case name {name!r} (also load_cases[{seen[name]}].name)")
        seen[name] = i
        weight = t.number("weight", section.default("weight"))
        if weight <= 0:
            raise t.error("weight", f"must be > 0 (the case's share of the combined objective), got {weight!r}")
        bodies = _moved(t, model, by_name)
        rigid = {b.name for b in model.bodies if b.rigid is not None}
        held = tuple(bc for bc in model.dirichlet if bc.body not in rigid)  # Model adds the tools' motions again
        case_model = t.guard(
            None,
            dataclasses.replace,
            model,
            bodies=bodies,
            dirichlet=held + read_supports(t, by_name),
            loads=model.loads + read_loads(t, by_name),
            soft_supports=model.soft_supports + read_soft_supports(t, by_name),
        )
        out.append(t.guard(None, LoadCase, name, case_model, weight))
    return tuple(out)


def _moved(t: Table, model: Model, by_name: dict) -> tuple:
    """The model's bodies with the rigid tools this case moves otherwise (``motions``)."""
    section = MODEL["load_cases.motions"]
    bodies = {b.name: b for b in model.bodies}
    done: set[str] = set()
    for m in t.tables("motions", section.names, section.required):
        name = body_name(m, "body", by_name)
        if bodies[name].rigid is None:
            rigid = [b.name for b in model.bodies if b.rigid is not None]
            raise m.error(
                "body",
                f"{name!r} is a deformable body, which a case moves by its supports; "
                f"{suggest(name, rigid) if rigid else ''}rigid tools: {rigid}",
            )
        if name in done:
            raise m.error("body", f"{name!r} is moved twice in this case")
        done.add(name)
        own = Table(m.r, {k: v for k, v in m.data.items() if k != "body"}, m.path)
        bodies[name] = m.guard(None, dataclasses.replace, bodies[name], rigid=motion(own))
    return tuple(bodies.values())
