"""The house style of contopt's docstrings, for autodoc: ``name : what it is`` entries.

The docstrings describe parameters, attributes and options as ``name : text`` lines (text continued on
lines indented below), under a numpy-style ``Parameters`` / ``Attributes`` / ``Returns`` heading or
without one (the fields of an options class). Numpy style would read the text as the entry's *type*,
and reStructuredText reads entries of one and of several lines as broken definition lists. Before
napoleon sees a docstring, this extension writes the headed sections as field lists (``:param name:``,
``:ivar name:``, ``:returns:``, ``:raises:``) and the entries without a heading as a definition list.
"""

from __future__ import annotations

import re

from sphinx.application import Sphinx

ENTRY = re.compile(r"^(?P<names>\**[A-Za-z_][\w.]*(?:, \**[A-Za-z_][\w.]*)*) : (?P<text>.*)$")
#: numpy-style headings and the field each of their entries becomes (None: the entry's own text)
SECTIONS = {"Parameters": "param", "Other Parameters": "param", "Attributes": "ivar", "Returns": None, "Raises": None}


def _heading(lines: list[str], i: int) -> str | None:
    """The section ``lines[i]`` heads (its next line underlines it with dashes), or None."""
    if i + 1 >= len(lines) or not re.fullmatch(r"-{3,}", lines[i + 1].strip()):
        return None
    title = lines[i].strip()
    return next((s for s in SECTIONS if title == s or title.startswith(s + " (")), None)


def _entry(lines: list[str], i: int) -> tuple[re.Match | None, list[str], int]:
    """The entry at ``lines[i]`` (None if it is none), its continuation lines and the index after them."""
    m = ENTRY.match(lines[i])
    j = i + 1
    while m and j < len(lines) and lines[j][:1].isspace() and lines[j].strip():
        j += 1
    return m, [line.strip() for line in lines[i + 1 : j]], j


def _entries(lines: list[str], i: int) -> tuple[list[tuple[re.Match, list[str]]], int]:
    """The entries from ``lines[i]`` on (blank lines between them allowed) and the index after them."""
    found = []
    while i < len(lines):
        k = i
        while k < len(lines) and not lines[k].strip():
            k += 1
        m, more, j = _entry(lines, k) if k < len(lines) else (None, [], k)
        if m is None:
            return found, i
        found.append((m, more))
        i = j
    return found, i


def _section(lines: list[str], i: int, title: str) -> tuple[list[str], int]:
    """The field list of the section whose first line is ``lines[i]``, and the index after it: its
    entries, or (Returns, Raises) its first paragraph."""
    kind = title.split(" (")[0]
    entries, j = _entries(lines, i)
    if SECTIONS[kind]:
        return [
            f":{SECTIONS[kind]} {m['names']}: {m['text']}" + "".join(f" {t}" for t in more) for m, more in entries
        ], j
    field = "raises" if kind == "Raises" else "returns"
    if entries:
        items = [f"   - ``{m['names']}``: {m['text']}" + "".join(f" {t}" for t in more) for m, more in entries]
        return [f":{field}:", "", *items], j
    j = i
    while j < len(lines) and lines[j].strip():
        j += 1
    return [f":{field}: " + " ".join(line.strip() for line in lines[i:j])], j


def house_style(lines: list[str]) -> list[str]:
    """The docstring ``lines`` with its entries written as field lists and definition lists."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        title = _heading(lines, i)
        if title:
            k = i + 2
            while k < len(lines) and not lines[k].strip():
                k += 1
            fields, i = _section(lines, k, title)
            out += ["", *fields, ""]
            continue
        m, more, j = _entry(lines, i)
        if m:
            out += ["", f"``{m['names']}``", f"   {m['text']}", *(f"   {t}" for t in more), ""]
            i = j
            continue
        out.append(lines[i])
        i += 1
    return out


def _process(app: Sphinx, what: str, name: str, obj, options, lines: list[str]) -> None:
    lines[:] = house_style(lines)


def setup(app: Sphinx) -> dict:
    app.setup_extension("sphinx.ext.autodoc")
    app.connect("autodoc-process-docstring", _process, priority=400)  # before napoleon's (500)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
