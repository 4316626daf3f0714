"""Reading the problem a command names: a case, a bundled problem file or FILE.toml, with ``--set``.

One path for `contopt run` and `contopt check-gradient`: :func:`read_problem` resolves the name the
user typed and applies the flags' and ``--set``'s replacements through the problem-file reader
(:func:`contopt.cases.spec.load_spec`), so both commands read a file alike and say the same errors.
"""

from __future__ import annotations

from pathlib import Path


def is_problem_file(source: str) -> bool:
    """Whether ``source`` names a problem file (a path ending in ``.toml``, or a file that exists)."""
    return source.endswith(".toml") or Path(source).is_file()


def replacements(sets, flagged=()) -> tuple[dict, dict]:
    """``(overrides, origins)`` of the flags ``flagged`` (``(key, "--flag", value)``, None: not given)
    and then of ``--set KEY=VALUE`` items ``sets`` (which replace a flag's key); ConfigError naming a bad item."""
    from contopt.cases.toml_reader import toml_value
    from contopt.errors import ConfigError

    overrides, origins = {}, {}
    for key, flag, value in flagged:
        if value is not None:
            overrides[key], origins[key] = value, flag
    for item in sets or ():
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set needs KEY=VALUE (e.g. --set design.bodies[0].volume_fraction=0.3), got {item!r}")
        overrides[key.strip()], origins[key.strip()] = toml_value(text.strip()), "--set"
    return overrides, origins


def read_problem(
    source: str,
    sets=(),
    flagged=(),
    *,
    mesh: str | None = None,
    design: str | None = None,
    eta: float | None = None,
    kind: str = "optimization case",
    also: str = "",
    purpose: str = "optimize it",
):
    """The RunSpec of ``source``: a problem file (FILE.toml), an optimization case or a bundled
    problem file, with the variants, ``flagged`` and ``--set`` replacements applied (:func:`replacements`).
    ``kind``, ``also``: what the command calls a name, and what else it takes, for the error on an unknown name;
    ``purpose``: what the command does with the problem, for the error on a file that is no optimization problem."""
    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.cases.spec import bundled_cases, load_spec
    from contopt.errors import ConfigError

    overrides, origins = replacements(sets, flagged)

    def read(source, label=None):
        return load_spec(source, overrides, mesh=mesh, design=design, eta=eta, label=label, origins=origins)

    if is_problem_file(source):
        if not Path(source).is_file():
            raise ConfigError(f"no such problem file: {source} (give the path of a .toml file, or a case name)")
        _check_optimization_problem(source, overrides, purpose)
        return read(Path(source))
    if source in OPTIMIZATION_CASES:  # a file that names the case: what a run directory keeps of it
        return read(f'case = "{source}"', label=source)
    bundled = bundled_cases()
    if source in bundled:
        return read(bundled[source], label=f"{source}.toml")
    raise ConfigError(
        f"unknown {kind} {source!r}; give a case {sorted(OPTIMIZATION_CASES)}, a bundled "
        f"problem file {sorted(bundled)}{also} or the path of a .toml file"
    )


def _check_optimization_problem(source: str, overrides: dict, purpose: str) -> None:
    """ConfigError where the file ``source`` describes a model only: no ``case``, ``[design]`` or
    ``[objective]``, in the file or the overrides (what else is wrong the reader says, naming the key)."""
    import tomllib

    from contopt.errors import ConfigError

    try:
        data = tomllib.loads(Path(source).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return  # the reader says what is wrong with it, where
    given = set(data) | {key.split(".")[0].split("[")[0] for key in overrides}
    if not given & {"case", "design", "objective"}:
        raise ConfigError(
            f"{source} is no optimization problem: it has no [design] and no [objective] (a model only); "
            f"add them to {purpose}, as in `contopt export cantilever` (docs/optimization.md)"
        )
