"""``contopt schema`` and ``contopt explain KEY``: the problem file described (no JAX loaded)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from contopt.cli.exits import DONE
from contopt.io.files import write_atomically


def cmd_schema(args) -> int:
    """Write the JSON Schema of a problem file to ``--out`` (default: standard output)."""
    from contopt.cases.schema import json_schema

    text = json.dumps(json_schema(), indent=1, ensure_ascii=False) + "\n"
    if args.out in (None, "-"):
        sys.stdout.write(text)
        return DONE
    path = Path(args.out)
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))  # OutputError: one line
    print(f'wrote {path}; put "#:schema ./{path.name}" atop a problem file for completion and checks (docs/schema.md)')
    return DONE


def cmd_explain(args) -> int:
    """Print what a key of the problem file means, its type, default and allowed values."""
    from contopt.cases.schema import explain

    print(explain(args.key))
    return DONE
