"""Regenerate the sample output in docs/tutorial.md from a real run (so it cannot go stale).

    .venv/bin/python scripts/tutorial_output.py            # rewrite the block in docs/tutorial.md
    .venv/bin/python scripts/tutorial_output.py --check    # exit 1 when the block differs (tests use it)

Runs `contopt run examples/tutorial.toml --max-iter 2` into a temporary directory and puts its
output between the markers `<!-- tutorial output -->` and `<!-- end tutorial output -->`. Times
differ from run to run; :func:`normalized` masks them for the comparison.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "tutorial.md"
BEGIN, END = "<!-- tutorial output -->", "<!-- end tutorial output -->"
ITERATIONS = 2


def run_output() -> str:
    """The stdout of a short tutorial run, with the temporary directory written as results/tutorial."""
    from contopt.cli import main

    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(ROOT):
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = main(["run", "examples/tutorial.toml", "--max-iter", str(ITERATIONS), "--out", tmp, "--overwrite"])
        if code != 0:
            raise SystemExit(f"the tutorial run failed (exit {code})")
        return out.getvalue().replace(tmp, "results/tutorial")


def normalized(text: str) -> list[str]:
    """Lines with the times masked: stamps, seconds per iteration, ETA, durations."""
    masks = [
        (r"\[\s*[\d.]+ s\]", "[T]"),
        (r"[\d.]+ s/it", "S s/it"),
        (r"ETA <= \S+", "ETA"),
        (r"\d+m\d+s", "D"),
        (r"in [\d.]+ s", "in S s"),
        (r"\([\d.]+ s so far\)", "(S)"),
        (r"\d+ new entries in the compilation cache", "N new entries"),
        (r"compiled; N new entries in the compilation cache|loaded from the compilation cache", "CACHE"),
    ]
    lines = []
    for line in text.strip().splitlines():
        for pattern, repl in masks:
            line = re.sub(pattern, repl, line)
        lines.append(line.rstrip())
    return lines


def documented() -> str:
    text = DOC.read_text(encoding="utf-8")
    start, stop = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[start:stop].strip().removeprefix("```").removesuffix("```").strip()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true")
    args = p.parse_args(argv)
    from contopt.config import setup_jax

    setup_jax()
    fresh = run_output()
    if args.check:
        same = normalized(fresh) == normalized(documented())
        print("docs/tutorial.md's sample output is " + ("current" if same else "stale"))
        return 0 if same else 1
    text = DOC.read_text(encoding="utf-8")
    start, stop = text.index(BEGIN) + len(BEGIN), text.index(END)
    DOC.write_text(text[:start] + "\n```\n" + fresh.strip() + "\n```\n" + text[stop:], encoding="utf-8")
    print(f"wrote the output of a {ITERATIONS}-iteration run into {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
