"""Reading TOML tables with errors that name the key: the machinery under the problem files.

:class:`Reader` knows where the values come from (the file's name, its folder, the command-line
flags that replaced values); :class:`Table` reads one table with typed getters whose errors are
one line ``file: key.path: reason``, with a did-you-mean suggestion for unknown keys and names.
:meth:`Table.guard` turns the error of a constructor (a dataclass checking its own fields) into
the same kind of line, naming the key the message is about. :func:`read_options` reads an
options dataclass from a table by its own fields. :func:`set_key` replaces a value by its key
path (``design.bodies[0].volume_fraction``), as ``--set`` does.

Nothing here knows the problem files' sections: those are :mod:`contopt.cases.spec_model`,
:mod:`~contopt.cases.spec_design` and :mod:`~contopt.cases.spec_run`.
"""

from __future__ import annotations

import builtins
import dataclasses
import difflib
import math
import re
import tomllib
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from contopt.errors import ConfigError, ContoptError

#: the default of a getter whose key must be given
REQUIRED = object()


class SpecError(ConfigError):
    """One bad entry of a problem file, as one line: ``file: key.path: reason``.

    Attributes: ``source`` (the file, or a label for text), ``key`` (the full key
    path, "" for the file as a whole), ``reason`` and ``origin`` (where an overriding
    value came from: a command-line flag such as ``"--eta"``, ``"override"``, or None for
    the file). A flag's error names the flag as typed: ``file: --eta must be ... (design.eta)``.
    """

    def __init__(self, source: str, key: str, reason: str, origin: str | None = None):
        self.source, self.key, self.origin = source, key, origin
        self.reason = " ".join(str(reason).split())  # one line, whatever the cause said
        if not key:
            text = f"{source}: {self.reason}"
        elif origin is None:
            text = f"{source}: {key}: {self.reason}"
        elif origin.startswith("--"):  # a flag: say it as the user typed it, then the key it sets
            flag = f"--set {key}" if origin == "--set" else origin
            tail = "" if origin == "--set" else f" ({key})"
            sep = " " if self.reason.startswith("must") else ": "
            text = f"{source}: {flag}{sep}{self.reason}{tail}"
        else:
            text = f"{source}: {key} ({origin}): {self.reason}"
        super().__init__(text)


def describe(value) -> str:
    """How a TOML value reads in a message: its type and value."""
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return f"a list {value!r}" if len(repr(value)) < 60 else f"a list of {len(value)} entries"
    return repr(value)


def suggest(word: str, choices: Iterable[str]) -> str:
    """``"did you mean 'x'? "`` for the closest of ``choices``, or ``""``."""
    match = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f"did you mean {match[0]!r}? " if match else ""


def strip_subject(message: str, key: str) -> str:
    """``"newton.max_iter must be ..."`` -> ``"must be ..."`` (the key path already says which)."""
    return re.sub(rf"^[\w.]*\b{re.escape(key)}\b\s*[:=]?\s*", "", message) or message


def parse_toml(text: str, label: str) -> dict:
    """The parsed text; a syntax error is a SpecError ``label:line:column: TOML syntax error: ...``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        msg = str(err)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        where = f"{label}:{m.group(1)}:{m.group(2)}" if m else label
        raise SpecError(where, "", f"TOML syntax error: {re.sub(r' ?[(]at [^)]*[)]', '', msg)}") from None


def toml_value(text: str):
    """A command-line value as TOML reads it (``0.3``, ``true``, ``[1, 2]``, ``"x"``); else the plain string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def set_key(data: dict, dotted: str, value, error: Callable[[str, str], SpecError]) -> None:
    """Set ``a.b[0].c = value`` in parsed TOML (tables on the way are made; list entries must exist).

    A path may end at a list entry (``design.bodies[0]``): the entry is replaced.
    ``error(key, reason)`` makes the error of a path that cannot be set.
    """
    tokens = []
    for part in dotted.split("."):
        m = re.fullmatch(r"([A-Za-z0-9_-]+)((?:\[\d+\])*)", part)
        if not m:
            raise error(dotted, "not a key path (write e.g. design.bodies[0].volume_fraction)")
        tokens.append(m.group(1))
        tokens += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    node: Any = data  # a table or a list, as the path walks down
    walked = ""
    for tok, nxt in zip(tokens[:-1], tokens[1:]):
        walked = f"{walked}[{tok}]" if isinstance(tok, int) else (f"{walked}.{tok}" if walked else tok)
        if isinstance(tok, int):
            if not isinstance(node, list) or tok >= len(node):
                raise error(walked, "no such entry in the file to set a value in")
            node = node[tok]
        else:
            if not isinstance(node, dict):
                raise error(walked, "is not a table")
            node = node.setdefault(tok, [] if isinstance(nxt, int) else {})
    last = tokens[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise error(dotted, "no such entry in the file to replace")
    elif not isinstance(node, dict):
        raise error(dotted, "can only set a key of a table")
    node[last] = value


class Reader:
    """Where values come from: the file's name for messages, its folder, and ``origins``
    (``{key path: "--flag"}``: the values a flag, ``--set`` or a variant replaced)."""

    def __init__(self, source: str, base_dir: Path, origins: Mapping[str, str]):
        self.source, self.base_dir, self.origins = source, base_dir, dict(origins)

    def origin(self, key: str) -> str | None:
        return next((o for k, o in self.origins.items() if key == k or key.startswith((k + ".", k + "["))), None)

    def error(self, key: str, reason: str) -> SpecError:
        return SpecError(self.source, key, reason, self.origin(key) if key else None)

    def table(self, data, key: str, allowed: Iterable[str] | None = None, required: Iterable[str] = ()) -> Table:
        if not isinstance(data, dict):
            raise self.error(key, f"must be a table, got {describe(data)}")
        t = Table(self, data, key)
        if allowed is not None:
            t.only(allowed)
        t.require(required)
        return t

    def set(self, data: dict, dotted: str, value) -> None:
        """:func:`set_key`, its errors named as the override that failed."""
        set_key(data, dotted, value, lambda key, reason: SpecError(self.source, key, reason, self.origins.get(dotted)))


class Table:
    """One TOML table being read: typed getters whose errors name the full key path.

    Each getter returns ``default`` when the key is absent; absent without a default is an error.
    """

    def __init__(self, reader: Reader, data: dict, path: str):
        self.r, self.data, self.path = reader, data, path

    def key(self, k: str) -> str:
        return f"{self.path}.{k}" if self.path else k

    def error(self, k: str | None, reason: str) -> SpecError:
        return self.r.error(self.key(k) if k else self.path, reason)

    def only(self, allowed: Iterable[str], hint: str = "") -> Table:
        allowed = sorted(set(allowed))
        for k in self.data:
            if k not in allowed:
                raise self.error(k, f"unknown key; {suggest(k, allowed)}allowed keys here: {allowed}{hint}")
        return self

    def require(self, keys: Iterable[str]) -> None:
        for k in keys:
            if k not in self.data:
                raise self.error(k, "required key is missing")

    def has(self, k: str) -> bool:
        return k in self.data

    def raw(self, k: str, default=REQUIRED):
        if k in self.data:
            return self.data[k]
        if default is REQUIRED:
            raise self.error(k, "required key is missing")
        return default

    # --- scalars (the getters are named after the types they read: the annotations below them
    # say builtins.str, builtins.int and builtins.bool)
    def str(self, k: str, default=REQUIRED, choices: Iterable[str] | None = None) -> str:
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        if choices is not None:
            choices = sorted(choices)
            if v not in choices:
                hint = suggest(v, choices) if isinstance(v, str) else ""
                raise self.error(k, f"must be one of {choices}, got {describe(v)}" + (f"; {hint}" if hint else ""))
        elif not isinstance(v, str) or not v:
            raise self.error(k, f"must be a non-empty string, got {describe(v)}")
        return v

    def bool(self, k: builtins.str, default=REQUIRED) -> builtins.bool:
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        if not isinstance(v, bool):
            raise self.error(k, f"must be true or false, got {describe(v)}")
        return v

    def int(self, k: builtins.str, default=REQUIRED, minimum: builtins.int | None = None) -> builtins.int:
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        if isinstance(v, bool) or not isinstance(v, int) or (minimum is not None and v < minimum):
            what = "an integer" + (f" >= {minimum}" if minimum is not None else "")
            raise self.error(k, f"must be {what}, got {describe(v)}")
        return v

    def number(
        self,
        k: builtins.str,
        default=REQUIRED,
        check: tuple[builtins.str, Callable[[float], builtins.bool]] | None = None,
    ):
        """A finite float; ``check = (description, predicate)``, e.g. ``("> 0", lambda v: v > 0)``."""
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        what = "a number" + (f" {check[0]}" if check else "")
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float))
            or not math.isfinite(v)
            or (check is not None and not check[1](float(v)))
        ):
            raise self.error(k, f"must be {what}, got {describe(v)}")
        return float(v)

    def positive(self, k: builtins.str, default=REQUIRED):
        return self.number(k, default, ("> 0", lambda v: v > 0))

    # --- lists
    def vector(self, k: builtins.str, default=REQUIRED, n: builtins.int = 3, infinite: builtins.bool = False):
        """A tuple of ``n`` floats (``infinite``: inf and -inf allowed, e.g. an open range)."""
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        ok = (
            isinstance(v, list)
            and len(v) == n
            and all(
                isinstance(c, (int, float))
                and not isinstance(c, bool)
                and not math.isnan(c)
                and (infinite or math.isfinite(c))
                for c in v
            )
        )
        if not ok:
            raise self.error(
                k, f"must be a list of {n} {'numbers' if infinite else 'finite numbers'}, got {describe(v)}"
            )
        return tuple(float(c) for c in v)

    def ints(self, k: builtins.str, default=REQUIRED, n: builtins.int = 3, minimum: builtins.int = 1):
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        ok = (
            isinstance(v, list)
            and len(v) == n
            and all(isinstance(c, int) and not isinstance(c, bool) and c >= minimum for c in v)
        )
        if not ok:
            raise self.error(k, f"must be a list of {n} integers >= {minimum}, got {describe(v)}")
        return tuple(v)

    def names(self, k: builtins.str, default=REQUIRED):
        """A string or a list of strings, as a tuple."""
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        v = [v] if isinstance(v, str) else v
        if not isinstance(v, list) or not v or not all(isinstance(s, str) and s for s in v):
            raise self.error(k, f"must be a name or a list of names, got {describe(self.data[k])}")
        return tuple(v)

    # --- nested
    def sub(
        self,
        k: builtins.str,
        allowed: Iterable[builtins.str] | None = None,
        required: Iterable[builtins.str] = (),
        default=REQUIRED,
    ):
        if k not in self.data:
            return self.raw(k, default)
        return self.r.table(self.data[k], self.key(k), allowed, required)

    def tables(
        self, k: builtins.str, allowed: Iterable[builtins.str] | None = None, required: Iterable[builtins.str] = ()
    ) -> list[Table]:
        """An array of tables (``[[k]]`` or ``k = [{...}, ...]``); a single table counts as one."""
        v = self.raw(k, [])
        if isinstance(v, dict):
            v = [v]
        if not isinstance(v, list):
            raise self.error(k, f"must be an array of tables ([[{self.key(k)}]]), got {describe(v)}")
        return [self.r.table(item, f"{self.key(k)}[{i}]", allowed, required) for i, item in enumerate(v)]

    def angle(self, k: builtins.str, default=REQUIRED, n: builtins.int = 1):
        """Radians under ``k`` or degrees under ``k_deg`` (one of the two): a float, or ``n`` floats."""
        kd = f"{k}_deg"
        if self.has(k) and self.has(kd):
            raise self.error(kd, f"give {k} (radians) or {kd} (degrees), not both")
        if not self.has(k) and not self.has(kd):
            if default is REQUIRED:
                raise self.error(kd, f"required key is missing (or {k} in radians)")
            return default
        use = kd if self.has(kd) else k
        v = self.number(use) if n == 1 else self.vector(use, n=n)
        if use == k:
            return v
        return float(np.deg2rad(v)) if n == 1 else tuple(float(a) for a in np.deg2rad(v))

    # --- what a constructor says
    def guard(self, k: builtins.str | None, fn: Callable, *args, **kwargs):
        """``fn(*args, **kwargs)``; a contopt error it raises is re-raised naming key ``k``, else
        the key of this table the message is about (:meth:`subject`), else the table."""
        try:
            return fn(*args, **kwargs)
        except ContoptError as err:
            if isinstance(err, SpecError):
                raise
            msg = str(err)
            if k is None:
                k, msg = self.subject(msg)
            raise self.error(k, msg) from None

    def subject(self, message: builtins.str) -> tuple[builtins.str | None, builtins.str]:
        """The key of this table a constructor's message is about, and the message as said of it.

        The message starts with the key (``"thickness 3.5 must be ..."``, kept whole), or names
        it just before ``must`` after the owner's words (``"heaviside.eta must be > 0"``,
        ``"Young's modulus E must be > 0"``: said as ``"must be > 0"``). (None, message) otherwise.
        """
        first = next((key for key in self.data if re.match(rf"{re.escape(key)}\b", message)), None)
        last = next((key for key in self.data if said_of(message, key)), None)
        said = said_of(message, last) if last else None  # a str whenever last is one
        return (last, said) if said else (first, message)


def said_of(message: str, key: str) -> str | None:
    """``"must ..."`` when ``message`` names ``key`` (alone) just before its first ``must``
    (``"heaviside.eta must be > 0"``, ``"Young's modulus E must be > 0"``); else None."""
    head, verb, rest = message.partition(" must ")
    if verb and " and " not in head and re.split(r"[\s.]", head)[-1] == key:
        return f"must {rest}"
    return None


def _kind(f: dataclasses.Field) -> str:
    ann = str(f.type)
    for kind in ("bool", "int", "float", "str", "tuple"):
        if ann.startswith(kind) or (kind == "float" and "float" in ann):
            return kind
    return "any"


def read_options(r: Reader, cls, data, path: str, base=None, exclude: Mapping[str, str] | None = None):
    """A dataclass from a TOML table by its own fields: unknown keys, types and the class's own checks
    named by their key. ``exclude``: field -> why it is not set here; ``base``: the values of the
    fields not given (default ``cls()``; a class with required fields needs them in the table)."""
    exclude = exclude or {}
    fields = {f.name: f for f in dataclasses.fields(cls)}
    t = r.table(data, path)
    for k in t.data:
        if k in exclude:
            raise t.error(k, exclude[k])
    t.only(set(fields) - set(exclude))
    kw = {k: _field_value(t, k, _kind(fields[k])) for k in t.data}
    required = [k for k, f in fields.items() if f.default is f.default_factory is dataclasses.MISSING]
    if base is None and required:  # no defaults to try a key against: the message says which key
        t.require(required)
        return t.guard(None, cls, **kw)
    base = base if base is not None else cls()
    try:
        return dataclasses.replace(base, **kw)
    except (ConfigError, TypeError) as err:
        for k in kw:  # which key: the first that fails on its own
            try:
                dataclasses.replace(base, **{k: kw[k]})
            except (ConfigError, TypeError) as one:
                raise t.error(k, said_of(str(one), k) or strip_subject(str(one), k)) from None
        raise t.error(None, str(err)) from None


def _field_value(t: Table, k: str, kind: str) -> Any:
    v = t.data[k]
    if kind in ("bool", "int", "str"):
        return getattr(t, kind)(k)
    if kind == "float":
        return t.number(k)
    if kind == "tuple" and isinstance(v, dict):  # IpoptOptions.options as a table: name = value
        return tuple(v.items())
    if kind == "tuple" and isinstance(v, list):  # or as a list of [name, value] pairs
        return tuple(tuple(x) if isinstance(x, list) else x for x in v)
    return v
