"""The gallery of the bundled cases: Sphinx writes one section per case into docs/gallery.md when it
reads that page, from the case files themselves (src/contopt/cases/files/*.toml), so the gallery
cannot drift from them: the case's description, its picture (``gallery_pictures`` in conf.py, when
docs/figures has one), the commands that run it and its variants, and the problem file, included
literally.

The page marks where the cases go with the line :data:`MARKER`; a page without it, a picture of a
case that is not bundled, or one that is not there fail the build.
"""

from __future__ import annotations

import os
from pathlib import Path

from sphinx.application import Sphinx
from sphinx.errors import ExtensionError

from contopt.cases.optimization import OPTIMIZATION_CASES, OptimizationCase

MARKER = "<!-- the cases: written here by docs/_ext/contopt_gallery.py when Sphinx reads this page -->"
PAGE = "gallery"


def commands(case: OptimizationCase) -> list[str]:
    """The command lines of a case: its run as written, one run per other variant, and its export."""
    lines = [f"contopt run {case.name} --out results/{case.name}"]
    for axis, names in (("mesh", case.meshes), ("design", case.designs)):
        lines += [f"contopt run {case.name} --{axis} {name} --out results/{case.name}-{name}" for name in names[1:]]
    return [*lines, f"contopt export {case.name} --out my-{case.name}.toml"]


def case_section(case: OptimizationCase, docs: Path, picture: tuple[str, str] | None) -> str:
    """The Markdown of one case's section; ``docs`` is the folder of the page (links are relative to it)."""
    variants = [
        f"{axis} {', '.join(names)}" for axis, names in (("mesh", case.meshes), ("design", case.designs)) if names
    ]
    parts = [f"## {case.name}", "", f"{case.description[:1].upper()}{case.description[1:]}."]
    if picture:
        parts += ["", f"![{case.name}]({picture[0]})", "", f"*{picture[1]}*"]
    parts += [
        "",
        f"Optimizer: {case.optimizer}"
        + (f"; variants (the first of each is the file as written): {'; '.join(variants)}" if variants else "")
        + ".",
        "",
        "```bash",
        *commands(case),
        "```",
        "",
        f"The problem file, `{case.path.name}`:",
        "",
        f"```{{literalinclude}} {Path(os.path.relpath(case.path, docs)).as_posix()}",
        ":language: toml",
        "```",
        "",
    ]
    return "\n".join(parts)


def gallery(docs: Path, pictures: dict[str, tuple[str, str]]) -> str:
    """The Markdown of every bundled case, in the order of their names; ``pictures``: case -> (path
    relative to ``docs``, caption)."""
    unknown = sorted(set(pictures) - set(OPTIMIZATION_CASES))
    if unknown:
        raise ExtensionError(f"gallery_pictures names cases that are not bundled: {unknown}")
    missing = sorted(path for path, _ in pictures.values() if not (docs / path).is_file())
    if missing:
        raise ExtensionError(f"gallery_pictures: no such pictures under {docs}: {missing}")
    return "\n".join(case_section(case, docs, pictures.get(name)) for name, case in sorted(OPTIMIZATION_CASES.items()))


def _fill(app: Sphinx, docname: str, source: list[str]) -> None:
    if docname != PAGE:
        return
    if MARKER not in source[0]:
        raise ExtensionError(f"{PAGE}.md has no line {MARKER!r} to write the cases at")
    source[0] = source[0].replace(MARKER, gallery(Path(app.srcdir), app.config.gallery_pictures))


def _always_read(app: Sphinx, env, added, changed, removed) -> list[str]:
    """The page is read again in every build: its sources are the case files, which Sphinx does not watch."""
    return [PAGE]


def setup(app: Sphinx) -> dict:
    app.add_config_value("gallery_pictures", {}, "env")
    app.connect("source-read", _fill)
    app.connect("env-get-outdated", _always_read)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
