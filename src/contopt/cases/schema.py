"""The problem file described: a JSON Schema (draft 2020-12) for editors (``contopt schema``) and one
key explained (``contopt explain KEY``), both from the declarations of :mod:`contopt.cases.keys_model`
and :mod:`contopt.cases.keys_run`, which the reader takes its keys and defaults from. Loads no JAX.
"""

from __future__ import annotations

import math
import textwrap
from typing import Any

from contopt.cases.keys import ABSENT, NO_DEFAULT, PRESENT, Key, Kind, Section, degrees, lookup
from contopt.cases.keys_model import MODEL_SECTIONS
from contopt.cases.keys_run import RUN_SECTIONS
from contopt.cases.toml_reader import suggest
from contopt.errors import ConfigError

#: the tables of a problem file by path (list indices dropped: ``contact.check``)
SECTIONS: dict[str, Section] = {s.path: s for s in (*MODEL_SECTIONS, *RUN_SECTIONS)}

_NUMBER: dict = {"type": "number"}
_VECTOR: dict = {"type": "array", "items": _NUMBER}
_NAMES: dict = {"anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}, "minItems": 1}]}
#: each Key.type as JSON Schema (table-valued types are made by _value)
TYPES: dict[str, dict] = {
    "string": {"type": "string"},
    "integer": {"type": "integer"},
    "number": _NUMBER,
    "boolean": {"type": "boolean"},
    "names": _NAMES,
    "angle": _NUMBER,
    "points": {"anyOf": [_VECTOR, {"type": "array", "items": _VECTOR}]},
    "value": {"anyOf": [_NUMBER, _VECTOR]},
    "rows": {"type": "array", "items": _VECTOR},
    "steps": {"anyOf": [{"type": "integer", "minimum": 1}, {"type": "array", "items": _NUMBER, "minItems": 1}]},
    "angle_path": {"anyOf": [_NUMBER, {"type": "array", "items": {**_VECTOR, "minItems": 2, "maxItems": 2}}]},
    "axis": {"anyOf": [{"type": "string", "enum": ["x", "y", "z"]}, {**_VECTOR, "minItems": 3, "maxItems": 3}]},
    "normalize": {"anyOf": [{"type": "string", "enum": ["full", "initial", "none"]}, _NUMBER]},
    "direction": {"anyOf": [{"type": "string", "enum": ["norm"]}, {**_VECTOR, "minItems": 3, "maxItems": 3}]},
    "grading": {
        "anyOf": [
            _NUMBER,
            {
                "type": "array",
                "minItems": 3,
                "maxItems": 3,
                "items": {"anyOf": [_NUMBER, {"const": "uniform"}, _VECTOR]},
            },
        ]
    },
    "any": {},
}


def _ref(path: str) -> dict:
    return {"$ref": f"#/$defs/{path or 'problem'}"}


def _value(key: Key) -> dict:
    """The JSON Schema of a key's value."""
    if key.type in ("vector", "ints", "range", "angles"):
        items = {"type": "integer", "minimum": 1} if key.type == "ints" else _NUMBER
        n = 2 if key.type in ("range", "angles") else key.n
        return {"type": "array", "items": items, "minItems": n, "maxItems": n}
    if key.type == "table":
        return _ref(key.table)
    if key.type == "tables":
        return {"anyOf": [{"type": "array", "items": _ref(key.table)}, _ref(key.table)]}
    if key.type == "regions":  # boxes or closed surfaces (a file name, or a table)
        one = {"anyOf": [_ref(key.table), {"type": "string"}]}
        return {"anyOf": [*one["anyOf"], {"type": "array", "items": one, "minItems": 1}]}
    if key.type == "friction":
        return {"anyOf": [_NUMBER, _ref(key.table)]}
    if key.type == "options":  # raw options: a table name = value, or [[name, value], ...]
        return {"anyOf": [{"type": "object"}, {"type": "array"}]}
    out = dict(TYPES[key.type])
    if key.choices:
        out["enum"] = list(key.choices)
    return out


def summary(key: Key) -> str:
    """The key's description in one line: what it means, its unit, its default."""
    text = key.doc.rstrip(".")
    if key.unit:
        text += f" [{key.unit}]"
    return text


def _json(value):
    if isinstance(value, tuple):
        return [_json(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _property(key: Key) -> dict:
    out = {"description": summary(key), **_value(key)}
    if key.default is not NO_DEFAULT and key.default is not None and _json(key.default) is not None:
        out["default"] = _json(key.default)
    if key.unit:
        out["x-unit"] = key.unit
    return out


def _condition(kind: Kind) -> dict:
    if kind.value is PRESENT:
        return {"required": [kind.key]}
    if kind.value is ABSENT:
        return {"not": {"required": [kind.key]}}
    return {"properties": {kind.key: {"const": kind.value}}, "required": [kind.key]}


def table_schema(section: Section) -> dict:
    """One table: its keys, the required ones, and per form the keys it allows."""
    properties: dict[str, Any] = {}
    for key in section.all_keys():
        properties.setdefault(key.name, _property(key))
    out: dict[str, Any] = {"type": "object", "description": section.doc}
    if section.free:
        return out
    out["properties"] = properties
    out["additionalProperties"] = False
    if section.required:
        out["required"] = list(section.required)
    forms = []
    for kind in section.kinds:
        then: dict[str, Any] = {"propertyNames": {"enum": list(section.allowed(kind.value, kind.key))}}
        keys = degrees(list(kind.keys))
        own = [k for k in keys if k.required and k.name != kind.key]
        if own:
            then["required"] = [k.name for k in own]
        then["properties"] = {k.name: _property(k) for k in keys}
        forms.append({"if": _condition(kind), "then": then})
    if forms:
        out["allOf"] = forms
    return out


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a problem file."""
    defs = {path or "problem": table_schema(s) for path, s in SECTIONS.items()}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "contopt problem file",
        "description": "A contopt problem file (TOML). Units are the user's consistent set: contopt assumes none.",
        **defs.pop("problem"),
        "$defs": defs,
    }


def every_key() -> list[str]:
    """Every key's path, ``contact.law`` (a table's keys under its path)."""
    return [f"{s.path}.{n}" if s.path else n for s in SECTIONS.values() for n in s.names]


def explain(dotted: str) -> str:
    """What ``contopt explain KEY`` prints: the key's description, type, unit, default and allowed
    values (per form where its table has several). ConfigError with a did-you-mean for an unknown key."""
    try:
        section, key = lookup(SECTIONS, dotted)
    except KeyError:
        known = every_key()
        hint = suggest(dotted, known) or suggest(dotted.rpartition(".")[2], known)
        raise ConfigError(f"unknown key {dotted!r}; {hint}`contopt schema` lists every key") from None
    path = f"{section.path}.{key.name}" if section.path else key.name
    lines = [f"{path}: {summary(key)}", f"  in: [{section.path or 'the top table'}] {section.doc}"]
    forms: list[tuple[Kind | None, Key]] = [
        (kind, k) for kind in section.kinds for k in degrees(list(kind.keys)) if k.name == key.name
    ]
    for kind, k in forms or [(None, key)]:
        where = "" if kind is None else f"  ({kind.key} = {kind.value!r})" if isinstance(kind.value, str) else ""
        lines.append(f"  type: {_type_words(k)}{where}")
        if k.required:
            lines.append("  required")
        elif k.default is not NO_DEFAULT:
            lines.append(f"  default: {_toml(k.default)}")
        if k.choices:
            lines.append(f"  allowed: {', '.join(map(str, k.choices))}")
        if k.doc != key.doc:
            lines.append(f"  {k.doc}")
    inner = SECTIONS.get(key.table) if key.table else None
    if inner is not None and not inner.free:
        lines.append(f"  its keys: {', '.join(inner.names)} (contopt explain {key.table}.KEY)")
    if len(key.doc) > 100:
        lines += textwrap.wrap(key.doc, 100, initial_indent="  ", subsequent_indent="  ")
    return "\n".join(lines)


def _type_words(key: Key) -> str:
    words = {
        "vector": f"a list of {key.n} numbers",
        "ints": f"a list of {key.n} integers >= 1",
        "range": "[min, max] (inf allowed)",
        "angles": "[start, end]",
        "angle": "a number (or NAME_deg in degrees)",
        "table": f"a table [{key.table}]",
        "tables": f"a list of tables [[{key.table}]]",
        "regions": "a table {lower, upper}, a file name or a table {file, scale}, or a list of them",
        "friction": f"a number (mu) or a table [{key.table}]",
        "names": "a name or a list of names",
        "value": "a number or one per component",
        "rows": "a list of rows [t, value per component]",
        "steps": "an integer >= 1 or a list of load factors in (0, 1]",
        "angle_path": "a number or rows [t, angle] (or NAME_deg in degrees)",
        "axis": '"x", "y", "z" or a vector [x, y, z]',
        "points": "a point [x, y, z] or a list of points",
        "normalize": '"full", "initial", "none" or a number',
        "direction": '[x, y, z] (contact-force: or "norm")',
        "options": "a table name = value",
        "grading": 'a ratio, or per axis a ratio, "uniform" or a list of coordinates',
    }
    return words.get(key.type, key.type)


def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)
