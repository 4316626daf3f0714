"""The fenced code blocks of the Markdown docs (README.md, docs/*.md), for tests/test_docs.py.

A block is a fenced block (three or more backticks or tildes, at any indentation); its language is the
first word after the fence. An HTML comment on the line right before the fence tags it:

- ``<!-- slow -->``: a long computation, run only by the slow-marked test;
- ``<!-- no-run: REASON -->``: a python block that needs what a test does not have (a run directory,
  say): it is compiled and its imports are run, the rest is not;
- ``<!-- part of PATH -->``: a toml block that is an excerpt of the problem file PATH (from the
  repository root): its tables and values must be that file's;

(any other comment on that line tags nothing). CONTRIBUTING.md, "Code blocks in the docs", has the rule.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: the Markdown files whose blocks are checked: the front page, the contributing guide and the site's pages
DOCS = (ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md")))

FENCE = re.compile(r"^(?P<indent> *)(?P<fence>`{3,}|~{3,})(?P<info>[^`]*)$")
TAG = re.compile(r"^\s*<!--\s*(?P<tag>slow|no-run|part of)\b:?\s*(?P<arg>.*?)\s*-->\s*$")


@dataclass(frozen=True)
class Block:
    """One fenced block: its file, the line of its opening fence (from 1), language, text, tag and the
    tag's argument (no-run's reason, part of's path)."""

    path: Path
    line: int
    language: str
    text: str
    tag: str | None = None
    arg: str = ""

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """The fenced blocks of the Markdown file ``path``, in order; an unclosed fence is an error."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence = len(m["indent"]), m["fence"]
        closing = re.compile(rf"^ *{re.escape(fence[0])}{{{len(fence)},}}\s*$")
        end = next((j for j in range(i + 1, len(lines)) if closing.match(lines[j])), None)
        if end is None:
            raise ValueError(f"{path.relative_to(ROOT)}:{i + 1}: a fence that is never closed")
        body = "\n".join(_dedent(line, indent) for line in lines[i + 1 : end])
        tag = TAG.match(lines[i - 1]) if i > 0 else None
        found.append(
            Block(
                path,
                i + 1,
                (m["info"].split() or [""])[0].lower(),
                body + "\n",
                tag["tag"] if tag else None,
                tag["arg"] if tag else "",
            )
        )
        i = end + 1
    return found


def _dedent(line: str, indent: int) -> str:
    """``line`` without the fence's indentation (as CommonMark: at most that many spaces go)."""
    return line[min(indent, len(line) - len(line.lstrip(" "))) :]
