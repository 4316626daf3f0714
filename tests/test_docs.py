"""Every code block of the Markdown docs (README.md, CONTRIBUTING.md, docs/*.md) works, by the rule of
CONTRIBUTING.md, "Code blocks in the docs": ```python blocks run (a file's blocks in order, in one
namespace, in an empty folder), ```toml blocks read, and the commands of ```bash / ```console blocks
name what exists (the contopt command line parses them, make knows the target, the script is there)."""

import ast
import contextlib
import importlib
import importlib.util
import io
import re
import shlex
import tomllib
from pathlib import Path

import pytest
from _doc_blocks import DOCS, ROOT, Block, blocks

from contopt.cases.forward import FORWARD_CASES
from contopt.cases.keys_model import COMMON
from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import load_spec
from contopt.cli.parser import build_parser

BLOCKS = [b for path in DOCS for b in blocks(path)]
#: the languages a block may have: a MyST directive (```{toctree}) is no code block
LANGUAGES = {"python", "toml", "bash", "console", "text", ""}
#: the top-level tables and keys of a problem file (contopt.cases.spec)
SECTIONS = {"bodies", "supports", "soft_supports", "loads", "contact", "design", "objective", "constraints"}
SECTIONS |= {"variants", "case", "case_options", *COMMON}
#: a line of a block without a language that is a command, not output: it belongs in a ```bash block
COMMAND = re.compile(r"^(\$ )?(contopt [a-z]|make |python |pip |mpiexec )")


def _name(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _python_files(tag: str | None = None) -> list[Path]:
    return [p for p in DOCS if any(b.language == "python" and (tag is None or b.tag == tag) for b in blocks(p))]


def _run_python(path: Path, slow: bool) -> None:
    """Run the python blocks of ``path`` in order in one namespace (the cwd is the test's folder); a slow
    block only when ``slow``, a no-run block's imports only. The line numbers of a traceback are the file's."""
    namespace: dict = {"__name__": "__docs__"}
    for block in blocks(path):
        if block.language != "python" or (block.tag == "slow" and not slow):
            continue
        tree = ast.parse("\n" * block.line + block.text, str(path))
        if block.tag == "no-run":
            tree.body = [node for node in tree.body if isinstance(node, ast.Import | ast.ImportFrom)]
        exec(compile(tree, str(path), "exec"), namespace)


@pytest.mark.parametrize("path", _python_files(), ids=_name)
def test_python_blocks_run(path, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _run_python(path, slow=False)


@pytest.mark.slow
@pytest.mark.parametrize("path", _python_files("slow"), ids=_name)
def test_python_blocks_run_with_the_slow_ones(path, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _run_python(path, slow=True)


def test_blocks_have_a_known_language_and_tag():
    problems = [
        f"{b.where}: language {b.language!r}" for b in BLOCKS if b.language not in LANGUAGES and b.language[:1] != "{"
    ]
    problems += [
        f"{b.where}: {b.tag!r} tags python blocks only"
        for b in BLOCKS
        if b.tag in ("slow", "no-run") and b.language != "python"
    ]
    problems += [f"{b.where}: no-run needs a reason" for b in BLOCKS if b.tag == "no-run" and not b.arg]
    problems += [
        f"{b.where}: 'part of' tags toml blocks only" for b in BLOCKS if b.tag == "part of" and b.language != "toml"
    ]
    problems += [
        f"{b.where}: a command in a block without a language (make it ```bash): {line!r}"
        for b in BLOCKS
        if b.language == ""
        for line in b.text.splitlines()
        if COMMAND.match(line)
    ]
    assert problems == []


# --- toml ----------------------------------------------------------------------------------------------


def _within(part, whole) -> bool:
    """Whether ``part`` (parsed TOML) is an excerpt of ``whole``: its tables' keys and values are
    ``whole``'s, each table of a list one of ``whole``'s list (in part)."""
    if isinstance(part, dict):
        return isinstance(whole, dict) and all(k in whole and _within(v, whole[k]) for k, v in part.items())
    if isinstance(part, list) and part and all(isinstance(x, dict) for x in part):
        return isinstance(whole, list) and all(any(_within(x, y) for y in whole) for x in part)
    return part == whole


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.language == "toml"], ids=lambda b: b.where)
def test_toml_blocks_read(block, tmp_path, monkeypatch):
    """A whole problem file (its bodies, design and objective, or a case) is read by the problem-file
    reader; an excerpt of a file (``<!-- part of PATH -->``) must be in it; other fragments parse and
    hold sections of a problem file only."""
    data = tomllib.loads(block.text)
    if block.tag == "part of":
        whole = tomllib.loads((ROOT / block.arg).read_text(encoding="utf-8"))
        assert _within(data, whole), f"{block.where}: not an excerpt of {block.arg}"
    elif "case" in data or {"bodies", "design", "objective"} <= data.keys():
        monkeypatch.chdir(tmp_path)
        load_spec(block.text, label=block.where)
    else:
        assert set(data) <= SECTIONS, f"{block.where}: no problem file has {sorted(set(data) - SECTIONS)}"


# --- shell ---------------------------------------------------------------------------------------------


def _commands(block: Block) -> list[tuple[list[str], str]]:
    """The commands of a bash or console block (a console block's are its ``$ `` lines), split into
    words, each with the text of its here-document ('' if none)."""
    lines = block.text.splitlines()
    if block.language == "console":
        lines = [line[2:] for line in lines if line.startswith("$ ")]
    commands, i = [], 0
    while i < len(lines):
        line = lines[i]
        while line.endswith("\\") and i + 1 < len(lines):
            i += 1
            line = line[:-1] + " " + lines[i]
        heredoc, m = "", re.search(r"<<-?\s*(['\"]?)(\w+)\1", line)
        if m:
            end = next(j for j in range(i + 1, len(lines)) if lines[j].strip() == m[2])
            heredoc, line, i = "\n".join(lines[i + 1 : end]) + "\n", line[: m.start()] + line[m.end() :], end
        words = shlex.split(line, comments=True)
        for separator in ("&&", "||", ";", "|"):
            words = [w for w in words if w != separator]  # one command per line in the docs
        if words:
            commands.append((words, heredoc))
        i += 1
    return commands


def _contopt(argv: list[str]) -> list[str]:
    said = io.StringIO()
    try:
        with contextlib.redirect_stderr(said), contextlib.redirect_stdout(io.StringIO()):
            args = build_parser().parse_args(argv)
    except SystemExit as stop:
        return [] if stop.code == 0 else [said.getvalue().strip().splitlines()[-1]]
    case = getattr(args, "case", None)
    known = set(OPTIMIZATION_CASES) | set(FORWARD_CASES)
    if args.command in ("run", "forward", "check-gradient", "export") and not (case.endswith(".toml") or case in known):
        return [f"no case {case!r}"]
    return []


def _python_code(code: str, where: str) -> list[str]:
    """A python here-document or -c: it compiles, and what it imports from contopt is there."""
    tree = ast.parse(code, where)
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "contopt":
            module = importlib.import_module(node.module)
            problems += [f"{node.module} has no {a.name}" for a in node.names if not hasattr(module, a.name)]
        elif isinstance(node, ast.Import):
            problems += [
                f"no module {a.name}"
                for a in node.names
                if a.name.split(".")[0] == "contopt" and importlib.util.find_spec(a.name) is None
            ]
    return problems


def _python(words: list[str], heredoc: str, where: str) -> list[str]:
    if words[:2] == ["-m", "pip"]:
        return _pip(words[2:])
    if words[:1] == ["-m"]:
        return [] if importlib.util.find_spec(words[1]) else [f"no module {words[1]}"]
    if words[:1] == ["-c"]:
        return _python_code(words[1], where)
    if words[:1] == ["-"]:
        return _python_code(heredoc, where)
    return [] if (ROOT / words[0]).is_file() else [f"no script {words[0]}"]


def _pip(words: list[str]) -> list[str]:
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    named = [e for w in words for m in [re.fullmatch(r"\.\[([\w,-]+)\]", w)] if m for e in m[1].split(",")]
    return [f"no extra {e!r} in pyproject.toml" for e in named if e not in extras]


def _make(words: list[str]) -> list[str]:
    targets = set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(encoding="utf-8"), re.M))
    return [f"no make target {t!r}" for t in words if not t.startswith("-") and "=" not in t and t not in targets]


def check_command(words: list[str], heredoc: str = "", where: str = "") -> list[str]:
    """What is wrong with one command line (split into words); [] when nothing is."""
    while words and re.match(r"^\w+=", words[0]):  # VAR=value before the command
        words = words[1:]
    program = words[0].removeprefix(".venv/bin/")
    if program == "mpiexec":
        rest = words[1:]
        while rest and rest[0].startswith("-"):
            rest = rest[2:] if rest[0] in ("-n", "-np") else rest[1:]
        return check_command(rest, heredoc, where)
    rules = {
        "contopt": lambda: _contopt(words[1:]),
        "make": lambda: _make(words[1:]),
        "python": lambda: _python(words[1:], heredoc, where),
        "python3": lambda: _python(words[1:], heredoc, where),
        "pip": lambda: _pip(words[1:]),
        # the user's own tools on a file an earlier line wrote: only that they get one
        "$EDITOR": lambda: [] if len(words) == 2 else ["$EDITOR takes the one file to edit"],
        "xdg-open": lambda: [] if len(words) == 2 else ["xdg-open takes the one file to open"],
    }
    if program not in rules:
        return [f"no rule for {program!r}: teach tests/test_docs.py to check it"]
    return [f"{' '.join(words)}: {p}" for p in rules[program]()]


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.language in ("bash", "console")], ids=lambda b: b.where)
def test_shell_blocks_name_what_exists(block):
    problems = [p for words, heredoc in _commands(block) for p in check_command(words, heredoc, block.where)]
    assert problems == [], block.where


def test_the_gallery_commands_parse():
    pytest.importorskip("sphinx", reason="sphinx is in the dev extra that make test installs")
    spec = importlib.util.spec_from_file_location("contopt_gallery", ROOT / "docs" / "_ext" / "contopt_gallery.py")
    gallery = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gallery)
    lines = [line for case in OPTIMIZATION_CASES.values() for line in gallery.commands(case)]
    assert len(lines) >= 2 * len(OPTIMIZATION_CASES)
    assert [p for line in lines for p in check_command(shlex.split(line))] == []


def test_the_checks_of_commands_fail():
    """The command rules find what is wrong (each of these lines is)."""
    wrong = [
        "contopt run die-slab --mesh",  # a flag without its value
        "contopt run no-such-case",
        "contopt frobnicate",
        "make no-such-target",
        "python benchmarks/no_such_script.py --out x.json",
        'pip install -e ".[no-such-extra]"',
        "cmake ..",
    ]
    assert all(check_command(shlex.split(line)) for line in wrong)
    assert _python_code("from contopt.solve.static import no_such_name\n", "<test>")
    assert not _within({"design": {"eta": 6.0}}, {"design": {"eta": 10.0}})
