"""The named optimization cases: the bundled problem files (``contopt list``, ``contopt run NAME``).

Each case is one file in ``contopt/cases/files`` (package data), read by the same reader as a
user's file (:func:`contopt.cases.spec.load_spec`); its ``[variants]`` are the case's
``--mesh`` and ``--design`` choices. :func:`optimization_case` builds a case's DesignProblem for
the benchmarks, the gradient check and the tests.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from contopt.errors import ConfigError


def cases_dir() -> Path:
    """The folder of the bundled problem files (package data ``contopt/cases/files``)."""
    return Path(str(resources.files("contopt.cases").joinpath("files")))


def bundled_cases() -> dict[str, Path]:
    """Bundled problem files by name (file name without ``.toml``)."""
    folder = cases_dir()
    return {p.stem: p for p in sorted(folder.glob("*.toml"))} if folder.is_dir() else {}


@dataclass(frozen=True)
class OptimizationCase:
    """A bundled problem file, as ``contopt list`` shows it.

    designs, meshes : the file's ``[variants]`` choices (the first: the file as written); () when
        it declares none
    optimizer : the optimizer its ``[optimizer]`` names (a run uses it unless told otherwise)
    """

    name: str
    path: Path
    description: str
    designs: tuple = ()
    meshes: tuple = ()
    optimizer: str = "mma"

    @property
    def default_design(self) -> str | None:
        return self.designs[0] if self.designs else None

    @classmethod
    def read(cls, path: Path) -> OptimizationCase:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        variants = data.get("variants", {})
        return cls(
            path.stem,
            path,
            data.get("description", ""),
            tuple(variants.get("design", ())),
            tuple(variants.get("mesh", ())),
            data.get("optimizer", {}).get("name", "mma"),
        )


OPTIMIZATION_CASES = {name: OptimizationCase.read(path) for name, path in bundled_cases().items()}


def optimization_case(
    name: str, design: str | None = None, mesh: str | None = None, eta: float | None = None, law: str | None = None
):
    """The DesignProblem of case ``name`` with the design and mesh variants chosen (None: the
    file's own), the Heaviside sharpness ``eta`` and every contact interface's ``law`` (a name of
    :data:`contopt.contact.laws.LAWS`, with its default options); errors name the option and its choices."""
    from contopt.cases.spec import load_spec  # spec imports this module

    if name not in OPTIMIZATION_CASES:
        raise ConfigError(f"unknown optimization case {name!r}; choose one of {sorted(OPTIMIZATION_CASES)}")
    path = OPTIMIZATION_CASES[name].path
    problem = load_spec(path, mesh=mesh, design=design, eta=eta, label=path.name, check=False).problem
    if law is None:
        return problem
    overrides = {f"contact[{i}].law": law for i in range(len(problem.model.interfaces))}
    origins = dict.fromkeys(overrides, "--law")
    return load_spec(
        path, overrides, mesh=mesh, design=design, eta=eta, label=path.name, check=False, origins=origins
    ).problem
