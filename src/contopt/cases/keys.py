"""The problem file's keys as declarations: a :class:`Key` (type, unit, default, allowed values, what
it means) in a :class:`Section` (a table, with its forms: :class:`Kind`).

The sections themselves are :mod:`contopt.cases.keys_model` and :mod:`contopt.cases.keys_run`; the
reader (:mod:`contopt.cases.spec_model`, :mod:`~contopt.cases.spec_design`,
:mod:`~contopt.cases.spec_run`) takes the keys a table allows and their defaults from them, and
``contopt schema`` / ``contopt explain`` (:mod:`contopt.cases.schema`) describe them. What an owner
already declares is read from it, not written again: an options class's keys are its dataclass
fields (their defaults, and their meaning from its docstring's ``name : text`` lines), a
constructor's defaults come from its signature (:func:`arg`), and the lists of allowed values are
the owners' (``contact.laws.LAWS``, ``optimize.base.OPTIMIZERS``, ``responses.catalog.RESPONSES``,
``solve.linear.options.BACKEND_CHOICES``, ...). Nothing here loads JAX.

Units are the user's consistent set (contopt assumes none): "length" is whatever length unit the
meshes use, "pressure (force/area)" the stress unit that goes with it, and so on.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
from dataclasses import dataclass
from typing import Any


class _Marker:
    def __init__(self, name: str):
        self.name = name

    def __repr__(self) -> str:
        return self.name


#: a key without a default: absent, its owner decides (what it does is in the key's description)
NO_DEFAULT: Any = _Marker("NO_DEFAULT")
#: a form of a table chosen by whether a key is there (Kind.value)
PRESENT: Any = _Marker("PRESENT")
ABSENT: Any = _Marker("ABSENT")

LENGTH = "length"
PRESSURE = "pressure (force/area)"
ANGLE = "radians (NAME_deg: degrees)"


@dataclass(frozen=True)
class Key:
    """One key of a table.

    type : what its value is (:data:`contopt.cases.schema.TYPES` says how each reads in JSON Schema)
    doc : what it means; unit : its unit ("" when it has none); default : its value when absent
    choices : the allowed values of a string; table : the section of a table or list of tables
    n : the length of a vector or list of integers
    """

    name: str
    type: str
    doc: str
    unit: str = ""
    default: Any = NO_DEFAULT
    choices: tuple = ()
    required: bool = False
    table: str = ""
    n: int = 3


@dataclass(frozen=True)
class Kind:
    """One form of a table: the keys it takes when ``key`` has ``value`` (or is PRESENT / ABSENT)."""

    key: str
    value: Any
    keys: tuple[Key, ...]


@dataclass(frozen=True)
class Section:
    """A table of the problem file: ``path`` without list indices (``contact.check``), its keys
    (every form takes them) and its forms (``kinds``); ``free``: any further key (raw options)."""

    path: str
    doc: str
    keys: tuple[Key, ...] = ()
    kinds: tuple[Kind, ...] = ()
    free: bool = False

    @property
    def names(self) -> tuple[str, ...]:
        """Every key the table may have, in any of its forms."""
        return tuple(dict.fromkeys(k.name for k in self.all_keys()))

    @property
    def required(self) -> tuple[str, ...]:
        return tuple(k.name for k in self.keys if k.required)

    def all_keys(self) -> list[Key]:
        """Every key, of every form (an angle's ``NAME_deg`` after it)."""
        return degrees([*self.keys, *(k for kind in self.kinds for k in kind.keys)])

    def kind(self, value, key: str | None = None) -> Kind:
        """The form ``value`` (of key ``key``, where two forms are chosen by different keys being PRESENT)."""
        return next(kind for kind in self.kinds if kind.value == value and key in (None, kind.key))

    def allowed(self, value, key: str | None = None) -> tuple[str, ...]:
        """The keys of the form ``value`` of ``key`` (the common ones and its own)."""
        return tuple(dict.fromkeys(k.name for k in degrees([*self.keys, *self.kind(value, key).keys])))

    def key(self, name: str) -> Key:
        return next(k for k in self.all_keys() if k.name == name)

    def default(self, name: str):
        """The default of a key (None where it has none)."""
        value = self.key(name).default
        return None if value is NO_DEFAULT else value


def degrees(keys: list[Key]) -> list[Key]:
    """``keys`` with each angle followed by its ``NAME_deg`` (the same angle in degrees; one of the two
    is given, so neither is required)."""
    out = []
    for k in keys:
        if k.type not in ("angle", "angles", "angle_path"):
            out.append(k)
            continue
        default = k.default
        if default is not NO_DEFAULT:
            default = tuple(math.degrees(a) for a in default) if isinstance(default, tuple) else math.degrees(default)
        out.append(dataclasses.replace(k, required=False))
        out.append(dataclasses.replace(k, name=f"{k.name}_deg", unit="degrees", default=default, required=False))
    return out


# --- what owners declare
def doc_of(owner, name: str) -> str:
    """The text its docstring gives ``name`` (a ``name : text`` or ``a, name : text`` line, or a
    ``; name : text`` part of one, and the lines indented under it), as one line; "" when it gives
    none or says only "see above"."""
    lines = (inspect.getdoc(owner) or "").splitlines()
    for i, line in enumerate(lines):
        indent = len(line) - len(line.lstrip())
        parts = re.split(r";\s*(?=[\w, ]+ : )", line.strip())
        for n, part in enumerate(parts):
            m = re.match(r"^([\w, ]+?) : (.*)$", part)
            if not m or name not in [w.strip() for w in m.group(1).split(",")]:
                continue
            text = [m.group(2)]
            if n == len(parts) - 1:
                for more in lines[i + 1 :]:
                    if not more.strip() or len(more) - len(more.lstrip()) <= indent:
                        break
                    text.append(more.strip())
            said = " ".join(text).strip()
            return "" if said.lower().startswith("see above") else said
    return ""


def default_of(owner, name: str):
    """The default of argument or field ``name`` of ``owner`` (NO_DEFAULT when it has none)."""
    if dataclasses.is_dataclass(owner):
        for f in dataclasses.fields(owner):
            if f.name == name:
                if f.default is not dataclasses.MISSING:
                    return f.default
                if f.default_factory is not dataclasses.MISSING:
                    return f.default_factory()
    parameter = inspect.signature(owner).parameters.get(name)
    if parameter is None or parameter.default is inspect.Parameter.empty:
        return NO_DEFAULT
    return parameter.default


def arg(owner, name: str, type: str, unit: str = "", doc: str = "", key: str = "", **kw) -> Key:
    """The key ``key`` (default ``name``) for argument ``name`` of ``owner``: its meaning from the
    owner's docstring unless ``doc`` says it, its default from the owner's signature."""
    kw.setdefault("default", default_of(owner, name))
    if kw["default"] is None:  # absent: the owner decides (the description says how)
        kw["default"] = NO_DEFAULT
    return Key(key or name, type, doc or doc_of(owner, name), unit, **kw)


def _field_type(f: dataclasses.Field) -> str:
    ann = str(f.type)
    for kind, word in (("bool", "boolean"), ("int", "integer"), ("float", "number"), ("str", "string")):
        if ann.startswith(kind) or (kind == "float" and "float" in ann):
            return word
    return "options" if ann.startswith("tuple") else "any"


def fields_section(path: str, cls, doc: str, exclude=(), units=None, choices=None, tables=None, types=None) -> Section:
    """A table read by :func:`contopt.cases.toml_reader.read_options`: the fields of ``cls``
    (``types``: a field's type where its annotation does not say it, e.g. a vector)."""
    units, choices, tables, types = units or {}, choices or {}, tables or {}, types or {}
    keys = []
    for f in dataclasses.fields(cls):
        if f.name in exclude or not f.init:
            continue
        kind = "table" if f.name in tables else types.get(f.name) or _field_type(f)
        keys.append(
            arg(
                cls,
                f.name,
                kind,
                units.get(f.name, ""),
                choices=tuple(choices.get(f.name, ())),
                table=tables.get(f.name, ""),
            )
        )
    return Section(path, doc, tuple(keys))


def lookup(sections: dict, dotted: str) -> tuple[Section, Key]:
    """The section and key of ``contact.law`` (list indices dropped). KeyError when there is none."""
    dotted = re.sub(r"\[\d+\]", "", dotted.strip())
    where, _, name = dotted.rpartition(".")
    section = sections.get(where)
    if section is None or name not in section.names:
        raise KeyError(dotted)
    return section, section.key(name)
