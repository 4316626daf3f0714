"""Design problems described in TOML files: ``load_spec(path_or_text) -> RunSpec``.

A problem file either describes everything (the long form) or names a
registered case (the short form). Lists of tables (``[[bodies]]``) are
numbered from 0 in messages: ``bodies[1]`` is the second body. Lengths,
moduli and loads are in whatever consistent units the model uses; angles
are in radians under their plain name (``arc``) or in degrees with the
suffix ``_deg`` (``arc_deg``).

Long form
---------
::

    name, description                 optional strings (shown by `contopt run`)

    [[bodies]]                        one table per deformable body
      name                            unique body name
      mesh = {generator = "box", lengths, divisions, origin, grading}
           | {generator = "cylinder_shell_sector", radius, arc|arc_deg, width, thickness,
              divisions, center, axis, mid_angle|mid_angle_deg, outward}
           | {generator = "annulus", r_inner, r_outer, length, divisions, theta|theta_deg, center}
           | {generator = "cylinder", radius, length, divisions, center, core_size, core_roundness}
           | {file = "part.msh", body = "..."}     (relative to the TOML file; .msh .vtu .e .exo)
      material = {model = "neo-hookean", E, nu, mass_density}
               | {model = "mooney-rivlin", E, nu, b_fraction, mass_density}
               | {model = "mooney-rivlin", kappa, A, B, mass_density}
      fbar = true                     mean-dilatation F-bar
      [[bodies.sets]]                 extra named sets made from the mesh's own
        name                          the new set's name
        from = "all"                  a facet set (gives a facet set and a node set) or a node set
        x, y, z = [min, max]          keep what lies in these ranges (facets by their centre)
        nearest = [x, y, z]           or: the node of `from` nearest to this point (or a list of
                                      points: one node each, in that order)

    [[supports]]                      prescribed displacements (supports and prescribed motions)
      body, set                       a node set (every facet set is also a node set)
      components = "xyz"              which components, e.g. "z" for a roller
      value = 0.0                     one number, or one per component; scaled by the load factor

    [[soft_supports]]                 springs to ground fading as (1 - t), for a body held only by contact
      body, stiffness                 force per length per unit reference volume (see SoftSupport)

    [[loads]]
      type = "traction"      body, set (a facet set), traction = [tx, ty, tz]  (per reference area)
      type = "body-force"    body, force = [bx, by, bz]                       (per reference volume)
      type = "acceleration"  body, acceleration = [ax, ay, az]  (inertia -rho a; needs mass_density)

    [[contact]]                       frictionless mortar contact
      nonmortar = {body, set}         carries the pressure: the finer or softer surface
      mortar = {body, set}
      enforcement = "alm" | "penalty" the contact law (contopt.contact.laws)
      eps, skin, max_angle_deg        optional (see ContactInterface)
      check = {tolerance, enabled}    the check of every converged state (PenetrationCheck)

    [design]
      eta = 10.0, p = 3.0, nu0 = 0.01  Heaviside sharpness, SIMP power, SIMP floor
      [[design.bodies]]
        body
        volume_fraction               nu_max of the body's volume constraint (omit: none)
        density = {radius}            cone filter of this radius
        bspline = {control_points = [nx, ny, nz] | patches = [...], degree = 3,
                   lower, upper | origin, lengths}   (box: default the body's bounding box)
        symmetry = {sectors, reflection = true, axis = "z", center, start|start_deg}
        skins = [{radius, side = "inside"|"outside", slope = 5.0, axis = "z", center}, ...]
        solid, void = {lower, upper} or a list of them   cells fixed solid / void
        skin_eps = 1e-4

    [objective]
      response                        strain-energy | compliance | contact-force | pressure-variance
                                      | volume-fraction
      sense = "minimize" | "maximize"
      bodies = "slab" or [...]        strain-energy, compliance, volume-fraction (default all)
      interfaces = [0]                contact-force, pressure-variance: indices into [[contact]]
      normalized = false              pressure-variance: divide by the squared mean pressure
      quadrature = "overlap"          contact-force: the pressure over the overlap (the force the
                                      bodies exchange) or "gauss" (the paper's appendix A reading)
      normalize = "full"              divide by |f| at the full design; "initial", "none" or a number

    [[constraints]]                   response, its keys as above, upper and/or lower, scale

    [optimizer]
      name = "mma" | "ipopt"
      [optimizer.mma]                 MMAOptions: move, kkt_tol, change_tol, asyinit, ...
      [optimizer.ipopt]               IpoptOptions: tol, hessian, print_level, ...
        [optimizer.ipopt.options]     raw IPOPT options, name = value

    [newton]  [augmentation]  [linear]  [adjoint]    NewtonOptions, AugmentationOptions,
                                      LinearSolverOptions, AdjointOptions (their field names)

    [run]
      max_iter = 100, out = "results", vtu = "every" | "final" | "none", plot = true,
      warm_start = true, view_up = "x" | "y" | "z" (the pictures' up axis; default: the push)

Short form
----------
::

    case = "die-slab"                 a registered case (`contopt list`)
    [case_options]  mesh, design, eta
    [optimizer]  [run]  [newton]  [augmentation]  [linear]  [adjoint]   as above (the newton,
                                      augmentation, linear and adjoint keys given replace the case's)

Errors are :class:`SpecError` (a :class:`~contopt.errors.ConfigError`): one
line ``file: key.path: reason`` naming the allowed values, with a
did-you-mean suggestion for unknown keys and names.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from contopt.errors import ConfigError, ContoptError

GENERATORS = ("annulus", "box", "cylinder", "cylinder_shell_sector")
MATERIALS = ("mooney-rivlin", "neo-hookean")
LOAD_TYPES = ("acceleration", "body-force", "traction")
SENSES = ("maximize", "minimize")
NORMALIZATIONS = ("full", "initial", "none")
OPTIMIZERS = ("ipopt", "mma")
VTU_MODES = ("every", "final", "none")
VIEW_AXES = ("x", "y", "z")
AXES = ("x", "y", "z")
SIDES = ("inside", "outside")

#: what a response table may hold besides its own options
_RESPONSE_OPTIONS = {
    "strain-energy": ("bodies",),
    "compliance": ("bodies",),
    "contact-force": ("interfaces", "quadrature"),
    "pressure-variance": ("interfaces", "normalized"),
    "volume-fraction": ("bodies",),
}

#: set selections are inclusive up to this fraction of the mesh size (coordinates from linspace
#: are off by round-off)
_SET_TOL = 1e-9

_REQUIRED = object()
_FILE_OUT = object()  # RunSpec.run's default: the run directory the file names


# ----------------------------------------------------------------------------------------- errors
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


def _describe(value) -> str:
    """How a TOML value reads in a message: its type and value."""
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return f"a list {value!r}" if len(repr(value)) < 60 else f"a list of {len(value)} entries"
    return repr(value)


def _suggest(word: str, choices: Iterable[str]) -> str:
    match = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f"did you mean {match[0]!r}? " if match else ""


def _strip_subject(message: str, key: str) -> str:
    """``"newton.max_iter must be ..."`` -> ``"must be ..."`` (the key path already says which)."""
    return re.sub(rf"^[\w.]*\b{re.escape(key)}\b\s*[:=]?\s*", "", message) or message


# ----------------------------------------------------------------------------------------- reading
class _Reader:
    """Where values come from: the file's name for messages, its folder, command-line overrides."""

    def __init__(self, source: str, base_dir: Path, origins: Mapping[str, str]):
        self.source, self.base_dir, self.origins = source, base_dir, dict(origins)

    def error(self, key: str, reason: str) -> SpecError:
        origin = next((o for k, o in self.origins.items() if key == k or key.startswith((k + ".", k + "["))), None)
        return SpecError(self.source, key, reason, origin if key else None)

    def table(self, data, key: str, allowed: Iterable[str] | None = None, required: Iterable[str] = ()) -> "_Table":
        if not isinstance(data, dict):
            raise self.error(key, f"must be a table, got {_describe(data)}")
        t = _Table(self, data, key)
        if allowed is not None:
            t.only(allowed)
        t.require(required)
        return t


class _Table:
    """One TOML table being read: typed getters whose errors name the full key path."""

    def __init__(self, reader: _Reader, data: dict, path: str):
        self.r, self.data, self.path = reader, data, path

    def key(self, k: str) -> str:
        return f"{self.path}.{k}" if self.path else k

    def error(self, k: str | None, reason: str) -> SpecError:
        return self.r.error(self.key(k) if k else self.path, reason)

    def only(self, allowed: Iterable[str], hint: str = "") -> "_Table":
        allowed = sorted(set(allowed))
        for k in self.data:
            if k not in allowed:
                raise self.error(k, f"unknown key; {_suggest(k, allowed)}allowed keys here: {allowed}{hint}")
        return self

    def require(self, keys: Iterable[str]) -> None:
        for k in keys:
            if k not in self.data:
                raise self.error(k, "required key is missing")

    def has(self, k: str) -> bool:
        return k in self.data

    def raw(self, k: str, default=_REQUIRED):
        if k in self.data:
            return self.data[k]
        if default is _REQUIRED:
            raise self.error(k, "required key is missing")
        return default

    # --- scalars (each returns ``default`` when the key is absent; absent without a default is an error)
    def str(self, k: str, default=_REQUIRED, choices: Iterable[str] | None = None) -> str:
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        if choices is not None:
            choices = sorted(choices)
            if v not in choices:
                hint = _suggest(v, choices) if isinstance(v, str) else ""
                raise self.error(k, f"must be one of {choices}, got {_describe(v)}" + (f"; {hint}" if hint else ""))
        elif not isinstance(v, str) or not v:
            raise self.error(k, f"must be a non-empty string, got {_describe(v)}")
        return v

    def bool(self, k: str, default=_REQUIRED) -> bool:
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        if not isinstance(v, bool):
            raise self.error(k, f"must be true or false, got {_describe(v)}")
        return v

    def int(self, k: str, default=_REQUIRED, minimum: int | None = None) -> int:
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        if isinstance(v, bool) or not isinstance(v, int) or (minimum is not None and v < minimum):
            what = "an integer" + (f" >= {minimum}" if minimum is not None else "")
            raise self.error(k, f"must be {what}, got {_describe(v)}")
        return v

    def number(self, k: str, default=_REQUIRED, check: tuple[str, Callable[[float], bool]] | None = None):
        """A finite float; ``check = (description, predicate)``, e.g. ``("> 0", lambda v: v > 0)``."""
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        what = "a number" + (f" {check[0]}" if check else "")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or (
                check is not None and not check[1](float(v))):
            raise self.error(k, f"must be {what}, got {_describe(v)}")
        return float(v)

    def positive(self, k: str, default=_REQUIRED):
        return self.number(k, default, ("> 0", lambda v: v > 0))

    # --- lists
    def vector(self, k: str, default=_REQUIRED, n: int = 3, infinite: bool = False):
        """A tuple of ``n`` floats (``infinite``: inf and -inf allowed, e.g. an open range)."""
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        ok = isinstance(v, list) and len(v) == n and all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and not math.isnan(c)
            and (infinite or math.isfinite(c)) for c in v)
        if not ok:
            raise self.error(k, f"must be a list of {n} {'numbers' if infinite else 'finite numbers'}, "
                                f"got {_describe(v)}")
        return tuple(float(c) for c in v)

    def ints(self, k: str, default=_REQUIRED, n: int = 3, minimum: int = 1):
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        ok = isinstance(v, list) and len(v) == n and all(
            isinstance(c, int) and not isinstance(c, bool) and c >= minimum for c in v)
        if not ok:
            raise self.error(k, f"must be a list of {n} integers >= {minimum}, got {_describe(v)}")
        return tuple(v)

    def names(self, k: str, default=_REQUIRED):
        """A string or a list of strings, as a tuple."""
        if k not in self.data:
            return self.raw(k, default)
        v = self.data[k]
        v = [v] if isinstance(v, str) else v
        if not isinstance(v, list) or not v or not all(isinstance(s, str) and s for s in v):
            raise self.error(k, f"must be a name or a list of names, got {_describe(self.data[k])}")
        return tuple(v)

    # --- nested
    def sub(self, k: str, allowed: Iterable[str] | None = None, required: Iterable[str] = (),
            default=_REQUIRED):
        if k not in self.data:
            return self.raw(k, default)
        return self.r.table(self.data[k], self.key(k), allowed, required)

    def tables(self, k: str, allowed: Iterable[str] | None = None, required: Iterable[str] = ()) -> list["_Table"]:
        """An array of tables (``[[k]]`` or ``k = [{...}, ...]``); a single table counts as one."""
        v = self.raw(k, [])
        if isinstance(v, dict):
            v = [v]
        if not isinstance(v, list):
            raise self.error(k, f"must be an array of tables ([[{self.key(k)}]]), got {_describe(v)}")
        return [self.r.table(item, f"{self.key(k)}[{i}]", allowed, required) for i, item in enumerate(v)]

    def angle(self, k: str, default=_REQUIRED, n: int = 1):
        """Radians under ``k`` or degrees under ``k_deg`` (one of the two): a float, or ``n`` floats."""
        kd = f"{k}_deg"
        if self.has(k) and self.has(kd):
            raise self.error(kd, f"give {k} (radians) or {kd} (degrees), not both")
        if not self.has(k) and not self.has(kd):
            if default is _REQUIRED:
                raise self.error(kd, f"required key is missing (or {k} in radians)")
            return default
        use = kd if self.has(kd) else k
        v = self.number(use) if n == 1 else self.vector(use, n=n)
        if use == k:
            return v
        return float(np.deg2rad(v)) if n == 1 else tuple(float(a) for a in np.deg2rad(v))

    def guard(self, k: str | None, fn: Callable, *args, **kwargs):
        """``fn(*args, **kwargs)``; a contopt error it raises is re-raised naming key ``k``, else the key
        of this table its message starts with (``"thickness 3.5 must be ..."``), else the table."""
        try:
            return fn(*args, **kwargs)
        except ContoptError as err:
            if isinstance(err, SpecError):
                raise
            msg = str(err)
            if k is None:
                k = next((key for key in self.data if re.match(rf"{re.escape(key)}\b", msg)), None)
            raise self.error(k, msg) from None


# ----------------------------------------------------------------------------------------- regions
@dataclass(frozen=True)
class BoxUnion:
    """Cells whose centroid lies in any of several :class:`~contopt.design.BoxRegion` boxes."""

    boxes: tuple

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """(k, 3) centroids -> (k,) bool."""
        mask = np.zeros(len(X), bool)
        for box in self.boxes:
            mask |= box(X)
        return mask


# ----------------------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class RunSpec:
    """A problem file, read: the design problem and how to run it.

    problem : the :class:`~contopt.optimize.problem.DesignProblem` (its ``model`` a Model)
    optimizer : "mma" or "ipopt"; options : its MMAOptions / IpoptOptions (``max_iter`` included)
    out : run directory; vtu, plot : what the run writes (see OutputOptions)
    name, description : from the file (the case name for the short form)
    case : the registered case of a short-form file, else None
    source : the file (or the label of a text); text : the TOML text as read
    discretization : the model's Discretization built while checking the design (reused by :meth:`run`)
    recipe : the arguments of :func:`load_spec` that made this spec (JSON-ready); :meth:`run` stores
        them in the run directory (``checkpoint/problem.json``) so the run's problem can be rebuilt
        from the directory alone (:func:`load_run_spec`)
    """

    problem: Any
    optimizer: str
    options: Any
    out: str = "results"
    vtu: str = "every"
    plot: bool = True
    view_up: str | None = None
    name: str = ""
    description: str = ""
    case: str | None = None
    source: str = ""
    text: str = ""
    discretization: Any = None
    recipe: Any = None

    @property
    def max_iter(self) -> int:
        return self.options.max_iter

    @property
    def eta(self) -> float:
        return self.problem.design.heaviside.eta

    @property
    def model(self):
        return self.problem.model

    def run(self, out=_FILE_OUT, *, resume: bool = False, overwrite: bool = False, outputs=None, progress=None,
            started=None):
        """Optimize (see :func:`contopt.optimize.driver.optimize`) into the run directory ``out``: by
        default the file's ``run.out``; ``None`` keeps everything in memory."""
        from contopt.optimize.driver import OutputOptions, optimize

        problem = self.problem
        if self.discretization is not None:
            problem = dataclasses.replace(problem, model=self.discretization)
        out = self.out if out is _FILE_OUT else out
        if out is not None and self.recipe is not None:
            progress = _recording(Path(out), self.recipe, progress)
        return optimize(problem, self.optimizer, self.options, out=out, resume=resume,
                        overwrite=overwrite,
                        outputs=outputs or OutputOptions(vtu=self.vtu, plot=self.plot, view_up=self.view_up),
                        progress=progress, started=started)


#: where a run directory keeps the recipe of its problem (see RunSpec.recipe)
RECIPE_FILE = Path("checkpoint") / "problem.json"


def _recording(out: Path, recipe: dict, progress):
    """``progress`` that first stores the recipe in ``out`` (once the run has accepted the directory)."""
    import json

    from contopt.optimize.history import atomic_write_text

    done = []

    def wrapped(row, eta):
        if not done:
            done.append(True)
            try:
                atomic_write_text(out / RECIPE_FILE, json.dumps(recipe, indent=1))
            except (OSError, TypeError, ValueError) as err:  # the run goes on; only its rebuild needs this
                import logging

                logging.getLogger(__name__).warning("could not store the problem's recipe in %s: %s", out, err)
        if progress is not None:
            progress(row, eta)

    return wrapped


def load_run_spec(run_dir) -> RunSpec:
    """The RunSpec of the run in ``run_dir``, rebuilt from its stored recipe (``checkpoint/problem.json``).

    A run made before recipes were stored is rebuilt from its ``problem.toml`` and the `contopt run`
    command line in its first comment (the flags --mesh, --design, --eta and --set). ConfigError when
    the directory has neither.
    """
    import json

    run_dir = Path(run_dir)
    path = run_dir / RECIPE_FILE
    if path.exists():
        try:
            recipe = json.loads(path.read_text())
        except (OSError, ValueError) as err:
            raise ConfigError(f"cannot read {path}: {err}") from None
        return load_spec(recipe["text"], recipe.get("overrides"), mesh=recipe.get("mesh"),
                         design=recipe.get("design"), eta=recipe.get("eta"), label=recipe.get("label"),
                         base_dir=recipe.get("base_dir"), origins=recipe.get("origins"))
    copy = run_dir / "problem.toml"
    if not copy.exists():
        raise ConfigError(f"{run_dir} does not say which problem ran (no {RECIPE_FILE} or problem.toml, which "
                          "`contopt run` writes): it was run from Python with optimize(); rebuild its design "
                          "space there")
    return load_spec(copy, **_header_flags(copy))


def _header_flags(copy: Path) -> dict:
    """load_spec arguments from the ``# contopt run ...`` line `contopt run` put atop problem.toml."""
    import shlex

    first = copy.read_text(encoding="utf-8").splitlines()[:1]
    words = shlex.split(first[0].lstrip("# ")) if first and first[0].startswith("# contopt run") else []
    flags: dict = {"overrides": {}, "origins": {}}
    for flag, value in zip(words, words[1:]):
        if flag in ("--mesh", "--design"):
            flags[flag[2:]] = value
        elif flag == "--eta":
            flags["eta"] = float(value)
        elif flag == "--set" and "=" in value:
            key, _, text = value.partition("=")
            try:
                flags["overrides"][key.strip()] = tomllib.loads(f"v = {text.strip()}")["v"]
            except tomllib.TOMLDecodeError:
                flags["overrides"][key.strip()] = text.strip()
            flags["origins"][key.strip()] = "--set"
    return flags


# ----------------------------------------------------------------------------------------- bundled files
def cases_dir() -> Path:
    """The folder of the bundled problem files (package data ``contopt/problems/cases``)."""
    return Path(str(resources.files("contopt.problems").joinpath("cases")))


def bundled_cases() -> dict[str, Path]:
    """Bundled problem files by name (file name without ``.toml``)."""
    folder = cases_dir()
    return {p.stem: p for p in sorted(folder.glob("*.toml"))} if folder.is_dir() else {}


def _commented(line: str, comment: str) -> str:
    return f"{line:<28}# {comment}\n"


def case_file_text(name: str) -> str:
    """A short-form problem file naming the registered case ``name``, its options spelled out."""
    from contopt.problems.optimization import OPTIMIZATION_CASES

    if name not in OPTIMIZATION_CASES:
        raise ConfigError(f"unknown case {name!r}; choose one of {sorted(OPTIMIZATION_CASES)}")
    case = OPTIMIZATION_CASES[name]
    return (f"# The registered case {name!r}: {case.description}\n"
            "# A file that names a case takes [case_options] and the [optimizer], [run], [newton], [augmentation],\n"
            "# [linear] and [adjoint] sections; `contopt run THIS.toml` runs it.\n\n"
            f'case = "{name}"\n\n'
            "[case_options]\n"
            + _commented(f'mesh = "{case.meshes[0]}"', f"one of {list(case.meshes)}")
            + _commented(f'design = "{case.default_design}"', f"one of {list(case.designs)}")
            + _commented("# eta = 10.0", "Heaviside sharpness") + "\n"
            "[optimizer]\n"
            + _commented('name = "mma"', 'or "ipopt"') + "\n"
            "[run]\n"
            "max_iter = 100\n"
            f'out = "results/{name}"\n')


# ----------------------------------------------------------------------------------------- entry point
def load_spec(source, overrides: Mapping[str, Any] | None = None, *, mesh: str | None = None,
              design: str | None = None, eta: float | None = None, label: str | None = None,
              base_dir=None, check: bool = True, origins: Mapping[str, str] | None = None) -> RunSpec:
    """Read a problem file (or TOML text) into a :class:`RunSpec`.

    Parameters
    ----------
    source : a path (``Path``, or a ``str`` without ``=`` or a newline) or the TOML text itself
    overrides : ``{"run.max_iter": 2, "design.bodies[0].volume_fraction": 0.3, ...}`` replacing (or
        adding) values before the file is checked, so their errors name the key like the file's own
    mesh, design : the short form's ``case_options`` (a long-form file describes its own meshes)
    eta : the Heaviside sharpness: ``design.eta`` or, in the short form, ``case_options.eta``
    label : the name errors give a text source (default ``"<toml>"``)
    base_dir : folder relative mesh files are read from (default: the file's folder, or the cwd for text)
    check : build the model's discretization and every designed body's design matrix now, so that
        what only those reveal (a B-spline box missing cells, a filter radius below the cell size)
        names its ``design.bodies[i]`` entry; the discretization is kept for :meth:`RunSpec.run`
    origins : ``{key path: "--flag"}`` where an override came from, for messages (default "override")
    """
    path = None
    if isinstance(source, Path) or (isinstance(source, str) and "=" not in source and "\n" not in source):
        path = Path(source)
        label = label or str(source)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise SpecError(label, "", f"cannot read the problem file: {err}") from None
    else:
        text, label = str(source), label or "<toml>"
    base = Path(base_dir) if base_dir is not None else (path.parent if path is not None else Path.cwd())
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        msg = str(err)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        where = f"{label}:{m.group(1)}:{m.group(2)}" if m else label
        raise SpecError(where, "", f"TOML syntax error: {re.sub(r' ?[(]at [^)]*[)]', '', msg)}") from None
    recipe = {"text": text, "label": label, "base_dir": str(base.resolve()), "overrides": dict(overrides or {}),
              "origins": dict(origins or {}), "mesh": mesh, "design": design, "eta": eta}
    origins = dict(origins or {})
    overrides = dict(overrides or {})
    short = "case" in data
    for flag, value, key in (("mesh", mesh, "case_options.mesh"), ("design", design, "case_options.design"),
                             ("eta", eta, "case_options.eta" if short else "design.eta")):
        if value is None:
            continue
        if not short and flag != "eta":
            raise SpecError(label, "", f"--{flag} applies to a file that names a registered case (case = ...); "
                                       f"this file describes its bodies: edit "
                                       f"{'bodies[i].mesh' if flag == 'mesh' else 'design.bodies[i]'} instead")
        overrides[key] = value
        origins.setdefault(key, f"--{flag}")
    for key in overrides:
        origins.setdefault(key, "override")
    r = _Reader(label, base, origins)
    for key, value in overrides.items():
        _apply_override(r, data, key, value)
    top = r.table(data, "")
    spec = _short_form(r, top, text) if short else _long_form(r, top, text, check)
    return dataclasses.replace(spec, recipe=recipe)


def _apply_override(r: _Reader, data: dict, dotted: str, value) -> None:
    """Set ``a.b[0].c = value`` in the parsed TOML."""
    def error(key: str, reason: str) -> SpecError:  # named as the override that failed
        return SpecError(r.source, key, reason, r.origins.get(dotted))

    tokens = []
    for part in dotted.split("."):
        m = re.fullmatch(r"([A-Za-z0-9_-]+)((?:\[\d+\])*)", part)
        if not m:
            raise error(dotted, "not a key path (write e.g. design.bodies[0].volume_fraction)")
        tokens.append(m.group(1))
        tokens += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    node, walked = data, ""
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
    if isinstance(last, int) or not isinstance(node, dict):
        raise error(dotted, "can only set a key of a table")
    node[last] = value


# ----------------------------------------------------------------------------------------- common sections
_COMMON = ("name", "description", "optimizer", "run", "newton", "augmentation", "linear", "adjoint")


def _solver_options(r: _Reader, top: _Table, base=None) -> dict:
    """``{"newton": ..., "augmentation": ..., "linear": ..., "adjoint": ...}`` for the tables present."""
    from contopt.adjoint.sensitivity import AdjointOptions
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import AugmentationOptions

    out = {}
    for key, cls in (("newton", NewtonOptions), ("augmentation", AugmentationOptions),
                     ("linear", LinearSolverOptions), ("adjoint", AdjointOptions)):
        if top.has(key):
            out[key] = _options(r, cls, top.raw(key), key, base=getattr(base, key, None) if base else None)
    return out


def _kind(f: dataclasses.Field) -> str:
    ann = str(f.type)
    for kind in ("bool", "int", "float", "str", "tuple"):
        if ann.startswith(kind) or (kind == "float" and "float" in ann):
            return kind
    return "any"


def _options(r: _Reader, cls, data, path: str, base=None, exclude: Mapping[str, str] | None = None):
    """An options dataclass from a TOML table, with unknown keys, types and the class's own checks
    named by their key. ``exclude``: field -> why it is not set here; ``base``: values not given."""
    exclude = exclude or {}
    fields = {f.name: f for f in dataclasses.fields(cls)}
    t = r.table(data, path)
    for k in t.data:
        if k in exclude:
            raise t.error(k, exclude[k])
    t.only(set(fields) - set(exclude))
    kw = {}
    for k, v in t.data.items():
        kind = _kind(fields[k])
        if kind == "bool":
            kw[k] = t.bool(k)
        elif kind == "int":
            kw[k] = t.int(k)
        elif kind == "float":
            kw[k] = t.number(k)
        elif kind == "str":
            kw[k] = t.str(k)
        elif kind == "tuple" and isinstance(v, dict):  # IpoptOptions.options as a table: name = value
            kw[k] = tuple(v.items())
        elif kind == "tuple" and isinstance(v, list):  # or as a list of [name, value] pairs
            kw[k] = tuple(tuple(x) if isinstance(x, list) else x for x in v)
        else:
            kw[k] = v
    base = base if base is not None else cls()
    try:
        return dataclasses.replace(base, **kw)
    except (ConfigError, TypeError) as err:
        for k in kw:  # which key: the first that fails on its own
            try:
                dataclasses.replace(base, **{k: kw[k]})
            except (ConfigError, TypeError) as one:
                raise t.error(k, _strip_subject(str(one), k)) from None
        raise t.error(None, str(err)) from None


def _optimizer(r: _Reader, top: _Table, case=None):
    """``(name, options, run settings)``; a named ``case`` supplies the optimizer and the options
    that suit it where the file gives none."""
    from contopt.optimize.ipopt import IpoptOptions
    from contopt.optimize.mma import MMAOptions

    opt = top.sub("optimizer", ("name", "mma", "ipopt"), default=None)
    run = top.sub("run", ("max_iter", "out", "vtu", "plot", "warm_start", "view_up"), default=None)
    default = case.optimizer if case is not None else "mma"
    name = opt.str("name", default, OPTIMIZERS) if opt is not None else default
    why = "the iteration limit is run.max_iter (one for both optimizers)"
    tables = {}
    for key, cls in (("mma", MMAOptions), ("ipopt", IpoptOptions)):
        if opt is not None and opt.has(key):  # both are checked, the one named is used
            tables[key] = _options(r, cls, opt.raw(key), opt.key(key), exclude={"max_iter": why})
        else:
            tables[key] = cls(**(case.optimizer_options.get(key, {}) if case is not None else {}))
    options = tables[name]
    runs = {"out": "results", "vtu": "every", "plot": True, "warm_start": None, "view_up": None}  # None: not given
    if run is not None:
        if run.has("max_iter"):
            options = dataclasses.replace(options, max_iter=run.int("max_iter", minimum=0))
        runs.update(out=run.str("out", "results"), vtu=run.str("vtu", "every", VTU_MODES),
                    plot=run.bool("plot", True), warm_start=run.bool("warm_start", None),
                    view_up=run.str("view_up", None, VIEW_AXES))
    return name, options, runs


def _texts(top: _Table) -> tuple[str, str]:
    name = top.str("name", "")
    desc = top.raw("description", "")
    if not isinstance(desc, str):
        raise top.error("description", f"must be a string, got {_describe(desc)}")
    return name, desc


# ----------------------------------------------------------------------------------------- short form
def _short_form(r: _Reader, top: _Table, text: str) -> RunSpec:
    from contopt.problems.optimization import OPTIMIZATION_CASES, optimization_case

    top.only(("case", "case_options", *_COMMON), hint=" (a file that names a case takes only these; "
             "describe bodies, supports, design ... in a file without `case`)")
    name = top.str("case", choices=OPTIMIZATION_CASES)
    case = OPTIMIZATION_CASES[name]
    opts = top.sub("case_options", ("mesh", "design", "eta"), default=None)
    kw = {}
    if opts is not None:
        if opts.has("mesh"):
            kw["mesh"] = opts.str("mesh", choices=case.meshes)
        if opts.has("design"):
            kw["design"] = opts.str("design", choices=case.designs)
        if opts.has("eta"):
            kw["eta"] = opts.positive("eta")
    problem = top.guard("case", optimization_case, name, **kw)
    optimizer, options, runs = _optimizer(r, top, case)
    solver = _solver_options(r, top, base=problem)
    warm = runs.pop("warm_start")
    problem = dataclasses.replace(problem, **solver, **({} if warm is None else {"warm_start": warm}))
    title, desc = _texts(top)
    return RunSpec(problem=problem, optimizer=optimizer, options=options, name=title or name,
                   description=desc or case.description, case=name, source=r.source, text=text, **runs)


# ----------------------------------------------------------------------------------------- long form
def _long_form(r: _Reader, top: _Table, text: str, check: bool) -> RunSpec:
    from contopt.assembly.model import Model
    from contopt.optimize.problem import DesignProblem

    top.only(("bodies", "supports", "soft_supports", "loads", "contact", "design", "objective", "constraints",
              *_COMMON))
    top.require(("bodies", "design", "objective"))
    bodies = _bodies(r, top)
    by_name = {b.name: b for b in bodies}
    dirichlet = _supports(top, by_name)
    loads = _loads(top, by_name)
    interfaces = _contact(top, by_name, bodies)
    springs = _soft_supports(top, by_name)
    model = top.guard(None, Model, bodies=tuple(bodies), dirichlet=dirichlet, loads=loads, interfaces=interfaces,
                      soft_supports=springs)
    design_table = top.sub("design", ("eta", "p", "nu0", "bodies"), ("bodies",))
    design, entries = _design(design_table, by_name)
    objective_table = top.sub("objective")
    objective = _response(objective_table, by_name, len(interfaces), extra=("sense", "normalize"))
    if objective_table.str("sense", "minimize", SENSES) == "maximize":
        objective = -objective
    normalize = objective_table.raw("normalize", "full")
    if isinstance(normalize, str):
        normalize = objective_table.str("normalize", "full", NORMALIZATIONS)
    elif isinstance(normalize, bool) or not isinstance(normalize, (int, float)) or not (
            math.isfinite(normalize) and normalize > 0):
        raise objective_table.error("normalize", f"must be one of {list(NORMALIZATIONS)} or a number > 0, "
                                                 f"got {_describe(normalize)}")
    constraints = _constraints(top, by_name, len(interfaces))
    optimizer, options, runs = _optimizer(r, top)
    solver = _solver_options(r, top)
    problem = top.guard(None, DesignProblem, model=model, design=design, objective=objective,
                        constraints=constraints, normalize=normalize, warm_start=runs.pop("warm_start") is not False,
                        **solver)
    disc = top.guard(None, _check_design, model, design, entries) if check else None
    title, desc = _texts(top)
    return RunSpec(problem=problem, optimizer=optimizer, options=options, name=title or Path(r.source).stem,
                   description=desc, source=r.source, text=text, discretization=disc, **runs)


# --- bodies
def _bodies(r: _Reader, top: _Table) -> list:
    from contopt.assembly.model import Body

    out, seen = [], {}
    for i, t in enumerate(top.tables("bodies", ("name", "mesh", "material", "fbar", "sets"),
                                     ("name", "mesh", "material"))):
        name = t.str("name")
        if name in seen:
            raise t.error("name", f"duplicate body name {name!r} (also bodies[{seen[name]}].name)")
        seen[name] = i
        mesh = _mesh(r, t.sub("mesh"))
        for s in t.tables("sets", ("name", "from", "x", "y", "z", "nearest"), ("name",)):
            mesh = _derived_set(s, mesh)
        material = _material(t.sub("material"))
        out.append(t.guard(None, Body, name, mesh, material, fbar=t.bool("fbar", True)))
    if not out:
        raise top.error("bodies", "needs at least one [[bodies]] table")
    return out


_MESH_KEYS = {
    "box": {"lengths": "vector+", "divisions": "ints", "origin": "vector", "grading": "grading"},
    "cylinder_shell_sector": {"radius": "positive", "arc": "angle", "width": "positive", "thickness": "positive",
                              "divisions": "ints", "center": "vector", "axis": "axis", "mid_angle": "angle",
                              "outward": "bool"},
    "annulus": {"r_inner": "positive", "r_outer": "positive", "length": "positive", "divisions": "ints",
                "theta": "angles", "center": "vector"},
    "cylinder": {"radius": "positive", "length": "positive", "divisions": "ints", "center": "vector",
                 "core_size": "number", "core_roundness": "number"},
}


def _mesh(r: _Reader, t: _Table):
    import inspect

    from contopt.mesh import generators
    from contopt.mesh.io import read_mesh

    if t.has("file"):
        t.only(("file", "body"))
        file = Path(t.str("file"))
        path = file if file.is_absolute() else r.base_dir / file
        if not path.exists():
            raise t.error("file", f"no such file: {path}")
        return t.guard(None, read_mesh, path, body=t.str("body", None))
    if not t.has("generator"):
        raise t.error(None, f"needs generator (one of {list(GENERATORS)}) or file (a mesh file)")
    gen = t.str("generator", choices=GENERATORS)
    keys = _MESH_KEYS[gen]
    allowed = {"generator", *keys, *(f"{k}_deg" for k, v in keys.items() if v.startswith("angle"))}
    t.only(allowed)
    params = inspect.signature(getattr(generators, gen)).parameters
    kw = {}
    for k, kind in keys.items():
        required = params[k].default is inspect.Parameter.empty
        if kind.startswith("angle"):
            v = t.angle(k, _REQUIRED if required else None, n=2 if kind == "angles" else 1)
            if v is not None:
                kw[k] = v
            continue
        if not t.has(k):
            if required:
                raise t.error(k, "required key is missing")
            continue
        if kind == "vector+":
            kw[k] = t.vector(k)
            if min(kw[k]) <= 0:
                raise t.error(k, f"must be 3 numbers > 0, got {_describe(t.raw(k))}")
        elif kind == "vector":
            kw[k] = t.vector(k)
        elif kind == "ints":
            kw[k] = t.ints(k)
        elif kind == "positive":
            kw[k] = t.positive(k)
        elif kind == "number":
            kw[k] = t.number(k)
        elif kind == "axis":
            kw[k] = t.str(k, choices=AXES)
        elif kind == "bool":
            kw[k] = t.bool(k)
        elif kind == "grading":
            kw[k] = _grading(t, k)
    return t.guard(None, getattr(generators, gen), **kw)


def _grading(t: _Table, k: str):
    """box grading: a ratio for all axes, or per axis a ratio, "uniform" or a list of coordinates."""
    v = t.raw(k)
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return t.positive(k)
    bad = t.error(k, "must be a ratio > 0, or a list of 3 entries each a ratio > 0, \"uniform\" or a list of "
                     f"increasing coordinates; got {_describe(v)}")
    if not isinstance(v, list) or len(v) != 3:
        raise bad
    out = []
    for e in v:
        if e == "uniform":
            out.append(None)
        elif isinstance(e, (int, float)) and not isinstance(e, bool) and math.isfinite(e) and e > 0:
            out.append(float(e))
        elif isinstance(e, list) and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in e):
            out.append(np.asarray(e, dtype=np.float64))
        else:
            raise bad
    return out


def _derived_set(t: _Table, mesh):
    """A node (and facet) set selected from an existing set by coordinate ranges or a nearest point."""
    from contopt.mesh.core import HEX_FACES

    name = t.str("name")
    if name in mesh.node_sets or name in mesh.facet_sets:
        raise t.error("name", f"the mesh already has a set {name!r}; choose another name")
    source = t.str("from", "all")
    if source not in mesh.facet_sets and source not in mesh.node_sets:
        names = sorted(set(mesh.facet_sets) | set(mesh.node_sets))
        raise t.error("from", f"the mesh has no set {source!r}; {_suggest(source, names)}sets: {names}")
    ranges = {a: t.vector(a, None, n=2, infinite=True) for a in AXES}
    nearest = t.raw("nearest", None)
    if nearest is not None:  # one point [x, y, z] or a list of points
        many = isinstance(nearest, list) and bool(nearest) and all(isinstance(p, list) for p in nearest)
        points = nearest if many else [nearest]
        for p in points:
            if not (isinstance(p, list) and len(p) == 3 and all(
                    isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in p)):
                raise t.error("nearest", f"must be a point [x, y, z] or a list of points, got {_describe(nearest)}")
        nearest = np.asarray(points, dtype=np.float64)
    if nearest is not None and any(v is not None for v in ranges.values()):
        raise t.error("nearest", "give coordinate ranges (x, y, z) or nearest, not both")
    if nearest is None and all(v is None for v in ranges.values()):
        raise t.error(None, "needs coordinate ranges (x = [min, max], ...) or nearest = [x, y, z]")
    for a, rng in ranges.items():
        if rng is not None and rng[0] > rng[1]:
            raise t.error(a, f"must be [min, max] with min <= max, got {_describe(t.raw(a))}")
    tol = _SET_TOL * float(np.ptp(mesh.points, axis=0).max())

    def inside(X):
        keep = np.ones(len(X), bool)
        for d, a in enumerate(AXES):
            if ranges[a] is not None:
                keep &= (X[:, d] >= ranges[a][0] - tol) & (X[:, d] <= ranges[a][1] + tol)
        return keep

    if nearest is not None:  # in the order of the points given
        nodes = mesh.node_set(source)
        picked = [int(nodes[np.argmin(np.linalg.norm(mesh.points[nodes] - p, axis=1))]) for p in nearest]
        if len(set(picked)) < len(picked):
            raise t.error("nearest", "two of the points pick the same node; give points near distinct nodes")
        return mesh.with_sets(node_sets={name: np.array(picked, dtype=np.int64)})
    if source in mesh.facet_sets:
        facets = mesh.facet_set(source)
        centres = mesh.points[mesh.facet_nodes(facets)].mean(axis=1)
        facets = facets[inside(centres)]
        if not len(facets):
            raise t.error(None, f"selects no facet of {source!r}")
        nodes = np.unique(mesh.cells[facets[:, 0][:, None], HEX_FACES[facets[:, 1]]])
        return mesh.with_sets(node_sets={name: nodes}, facet_sets={name: facets})
    nodes = mesh.node_set(source)
    nodes = nodes[inside(mesh.points[nodes])]
    if not len(nodes):
        raise t.error(None, f"selects no node of {source!r}")
    return mesh.with_sets(node_sets={name: nodes})


def _material(t: _Table):
    from contopt.material.hyperelastic import MooneyRivlin, neo_hookean

    model = t.str("model", choices=MATERIALS)
    nonnegative = (">= 0", lambda v: v >= 0)
    nu_check = ("in (-1, 0.5)", lambda v: -1.0 < v < 0.5)
    if model == "neo-hookean":
        t.only(("model", "E", "nu", "mass_density"))
        return t.guard(None, neo_hookean, t.positive("E"), t.number("nu", check=nu_check),
                       t.number("mass_density", 0.0, nonnegative))
    if t.has("kappa") or t.has("A") or t.has("B"):
        t.only(("model", "kappa", "A", "B", "mass_density"),
               hint=" (give kappa, A, B or E, nu, b_fraction, not both)")
        A, B = t.number("A", 0.0, nonnegative), t.number("B", 0.0, nonnegative)
        if A + B <= 0:
            raise t.error("A", f"A + B must be > 0 (the shear modulus is 2 (A + B)), got A={A}, B={B}")
        return t.guard(None, MooneyRivlin, kappa=t.positive("kappa"), A=A, B=B,
                       mass_density=t.number("mass_density", 0.0, nonnegative))
    t.only(("model", "E", "nu", "b_fraction", "mass_density"),
           hint=" (or kappa, A, B instead of E, nu, b_fraction)")
    return t.guard(None, MooneyRivlin.from_E_nu, t.positive("E"), t.number("nu", check=nu_check),
                   t.number("b_fraction", 0.0, ("in [0, 1]", lambda v: 0.0 <= v <= 1.0)),
                   t.number("mass_density", 0.0, nonnegative))


# --- names
def _body_name(t: _Table, k: str, by_name: dict) -> str:
    name = t.str(k)
    if name not in by_name:
        raise t.error(k, f"unknown body {name!r}; {_suggest(name, by_name)}bodies: {list(by_name)}")
    return name


def _set_name(t: _Table, k: str, body, kind: str) -> str:
    """A set of ``body``: a facet set, or for ``kind="node"`` a node set or a facet set (its nodes)."""
    name = t.str(k)
    sets = body.mesh.facet_sets
    if kind == "node":
        sets = {**body.mesh.node_sets, **sets}
    if name not in sets:
        raise t.error(k, f"body {body.name!r} has no {kind} set {name!r}; {_suggest(name, sets)}"
                         f"its {kind} sets: {sorted(sets)}")
    return name


# --- conditions
def _supports(top: _Table, by_name: dict) -> tuple:
    from contopt.assembly.model import Dirichlet, Model

    out = []
    for t in top.tables("supports", ("body", "set", "components", "value"), ("body", "set")):
        body = _body_name(t, "body", by_name)
        node_set = _set_name(t, "set", by_name[body], "node")
        comps = t.str("components", "xyz")
        if any(c not in "xyz" for c in comps) or len(set(comps)) != len(comps):
            raise t.error("components", f"must be distinct letters of 'xyz' (e.g. 'z' or 'xyz'), got {comps!r}")
        value = t.raw("value", 0.0)
        if isinstance(value, list):
            value = t.vector("value", n=len(comps))
        else:
            value = t.number("value", 0.0)
        bc = t.guard(None, Dirichlet, body, node_set, comps, value)
        t.guard(None, Model, bodies=(by_name[body],), dirichlet=(bc,))
        out.append(bc)
    return tuple(out)


def _soft_supports(top: _Table, by_name: dict) -> tuple:
    """Springs to ground fading as ``1 - t`` (for a body held only by contact until it touches)."""
    from contopt.assembly.model import SoftSupport

    out = []
    for t in top.tables("soft_supports", ("body", "stiffness"), ("body", "stiffness")):
        out.append(t.guard(None, SoftSupport, _body_name(t, "body", by_name), t.positive("stiffness")))
    return tuple(out)


def _loads(top: _Table, by_name: dict) -> tuple:
    from contopt.assembly.model import Acceleration, BodyForce, Traction

    out = []
    for t in top.tables("loads", None, ("type",)):
        kind = t.str("type", choices=LOAD_TYPES)
        if kind == "traction":
            t.only(("type", "body", "set", "traction"))
            body = _body_name(t, "body", by_name)
            out.append(Traction(body, _set_name(t, "set", by_name[body], "facet"), t.vector("traction")))
        elif kind == "body-force":
            t.only(("type", "body", "force"))
            out.append(BodyForce(_body_name(t, "body", by_name), t.vector("force")))
        else:
            t.only(("type", "body", "acceleration"))
            body = _body_name(t, "body", by_name)
            rho = by_name[body].material.mass_density
            if rho <= 0:
                raise t.error("body", f"an acceleration load needs the body's material.mass_density > 0; "
                                      f"body {body!r} has {rho}")
            out.append(Acceleration(body, t.vector("acceleration")))
    return tuple(out)


def _contact(top: _Table, by_name: dict, bodies: list) -> tuple:
    from contopt.assembly.model import Model
    from contopt.contact.interface import ContactInterface
    from contopt.contact.laws import LAWS, law_named
    from contopt.contact.verify import PenetrationCheck

    out = []
    for t in top.tables("contact", ("nonmortar", "mortar", "enforcement", "eps", "skin", "max_angle_deg", "check"),
                        ("nonmortar", "mortar")):
        sides = {}
        for side in ("nonmortar", "mortar"):
            s = t.sub(side, ("body", "set"), ("body", "set"))
            body = _body_name(s, "body", by_name)
            sides[side] = (body, _set_name(s, "set", by_name[body], "facet"))
        if sides["nonmortar"][0] == sides["mortar"][0]:
            raise t.error("mortar", f"self-contact is not supported: both sides are on body {sides['mortar'][0]!r}")
        law = law_named(t.str("enforcement", "alm", LAWS), eps=t.positive("eps", None))
        c = t.sub("check", ("tolerance", "enabled"), (), None)
        check = PenetrationCheck() if c is None else c.guard(
            None, PenetrationCheck, tolerance=c.number("tolerance", 1e-3, ("in (0, 1)", lambda v: 0 < v < 1)),
            enabled=c.bool("enabled", True))
        iface = t.guard(None, ContactInterface, sides["nonmortar"], sides["mortar"], law=law, check=check,
                        skin=t.number("skin", None, (">= 0", lambda v: v >= 0)),
                        max_angle_deg=t.number("max_angle_deg", 75.0, ("in (0, 90]", lambda v: 0 < v <= 90)))
        t.guard(None, Model, bodies=tuple(bodies), interfaces=(iface,))
        out.append(iface)
    return tuple(out)


# --- design
def _design(t: _Table, by_name: dict):
    from contopt.design import Design, Heaviside, Simp

    eta = t.positive("eta", 10.0)
    p = t.positive("p", 3.0)
    nu0 = t.number("nu0", 1e-2, ("in (0, 1)", lambda v: 0 < v < 1))
    entries, seen = [], {}
    for b in t.tables("bodies", ("body", "volume_fraction", "density", "bspline", "symmetry", "skins", "solid",
                                 "void", "skin_eps"), ("body",)):
        name = _body_name(b, "body", by_name)
        if name in seen:
            raise b.error("body", f"body {name!r} is designed twice (also {seen[name]})")
        seen[name] = b.path
        entries.append((b, _designed_body(b, name)))
    if not entries:
        raise t.error("bodies", "needs at least one [[design.bodies]] table")
    design = t.guard(None, Design, bodies=tuple(d for _, d in entries), heaviside=Heaviside(eta), simp=Simp(p, nu0))
    return design, entries


def _designed_body(t: _Table, name: str):
    from contopt.design import CyclicSymmetry, Density, DesignedBody, RadialSkin

    if t.has("density") == t.has("bspline"):
        raise t.error(None, "needs exactly one parameterization: density = {radius = ...} or "
                            "bspline = {control_points = [...]}")
    if t.has("density"):
        d = t.sub("density", ("radius",), ("radius",))
        param = Density(d.positive("radius"))
    else:
        param = _bspline(t.sub("bspline"))
    symmetry = None
    if t.has("symmetry"):
        s = t.sub("symmetry", ("sectors", "reflection", "axis", "center", "start", "start_deg"), ("sectors",))
        symmetry = s.guard(None, CyclicSymmetry, s.int("sectors", minimum=1), s.bool("reflection", True),
                           s.str("axis", "z", AXES), s.vector("center", (0.0, 0.0, 0.0)), s.angle("start", 0.0))
    skins = []
    for s in t.tables("skins", ("radius", "side", "slope", "axis", "center"), ("radius",)):
        skins.append(s.guard(None, RadialSkin, s.positive("radius"), s.str("side", "inside", SIDES),
                             s.positive("slope", 5.0), s.str("axis", "z", AXES), s.vector("center", (0.0, 0.0, 0.0))))
    vf = t.number("volume_fraction", None, ("in (0, 1)", lambda v: 0 < v < 1))
    return t.guard(None, DesignedBody, name, param, volume_fraction=vf, symmetry=symmetry, skins=tuple(skins),
                   solid=_boxes(t, "solid"), void=_boxes(t, "void"),
                   skin_eps=t.positive("skin_eps", 1e-4))


def _bspline(t: _Table):
    from contopt.design import BSplineGrid

    t.only(("control_points", "patches", "degree", "lower", "upper", "origin", "lengths"))
    if t.has("control_points") == t.has("patches"):
        raise t.error(None, "needs control_points = [nx, ny, nz] or patches = [nx, ny, nz] (one of the two)")
    degree = t.int("degree", 3)
    if degree not in (1, 2, 3, 4, 5):
        raise t.error("degree", f"must be one of [1, 2, 3, 4, 5], got {degree!r}")
    for a, b in (("lower", "origin"), ("upper", "lengths")):
        if t.has(a) and t.has(b):
            raise t.error(b, f"give {a} or {b}, not both")
    origin = t.vector("lower", None) if t.has("lower") else t.vector("origin", None)
    lengths = t.vector("lengths", None)
    if t.has("upper"):
        upper = t.vector("upper")
        if origin is None:
            raise t.error("lower", "required with upper (the box is lower..upper)")
        lengths = tuple(u - lo for u, lo in zip(upper, origin))
        if min(lengths) <= 0:
            raise t.error("upper", f"must exceed lower in every direction, got {list(upper)} and {list(origin)}")
    if lengths is not None and min(lengths) <= 0:
        raise t.error("lengths", f"must be 3 numbers > 0, got {list(lengths)}")
    if t.has("control_points"):
        control = t.ints("control_points", minimum=degree + 1)
        return t.guard(None, BSplineGrid.with_control_points, control, degree, origin, lengths)
    return t.guard(None, BSplineGrid, t.ints("patches"), degree, origin, lengths)


def _boxes(t: _Table, k: str):
    from contopt.design import BoxRegion

    if not t.has(k):
        return None
    boxes = []
    for b in t.tables(k, ("lower", "upper"), ("lower", "upper")):
        lower, upper = b.vector("lower", infinite=True), b.vector("upper", infinite=True)
        if any(lo > up for lo, up in zip(lower, upper)):
            raise b.error("upper", f"must be >= lower in every direction, got {list(upper)} and {list(lower)}")
        boxes.append(BoxRegion(lower, upper))
    if not boxes:
        raise t.error(k, "needs {lower = [...], upper = [...]} or a list of them")
    return boxes[0] if len(boxes) == 1 else BoxUnion(tuple(boxes))


def _check_design(model, design, entries):
    """Build the discretization and each designed body's design matrix; errors name the entry."""
    from contopt.assembly.system import discretize
    from contopt.design import Design

    disc = discretize(model)
    for t, body in entries:
        t.guard(None, Design(bodies=(body,), heaviside=design.heaviside, simp=design.simp).build, disc)
    return disc


# --- responses
def _response(t: _Table, by_name: dict, n_interfaces: int, extra: tuple = ()):
    from contopt.responses.functionals import builtin

    name = t.str("response", choices=_RESPONSE_OPTIONS)
    own = _RESPONSE_OPTIONS[name]
    others = sorted({k for keys in _RESPONSE_OPTIONS.values() for k in keys} - set(own))
    for k in t.data:
        if k in others:
            raise t.error(k, f"not an option of response {name!r}; its options: {sorted(own + ('name',))}")
    t.only(("response", "name", *own, *extra))
    kw = {}
    if t.has("name"):
        kw["name"] = t.str("name")
    if t.has("bodies"):
        bodies = t.names("bodies")
        for b in bodies:
            if b not in by_name:
                raise t.error("bodies", f"unknown body {b!r}; {_suggest(b, by_name)}bodies: {list(by_name)}")
        kw["bodies"] = bodies if len(bodies) > 1 else bodies[0]
    if t.has("interfaces"):
        v = t.raw("interfaces")
        v = [v] if isinstance(v, int) and not isinstance(v, bool) else v
        if n_interfaces == 0:
            raise t.error("interfaces", "the model has no [[contact]] interfaces")
        if not isinstance(v, list) or not v or not all(
                isinstance(i, int) and not isinstance(i, bool) and 0 <= i < n_interfaces for i in v):
            raise t.error("interfaces", f"must be indices of [[contact]] entries in [0, {n_interfaces - 1}], "
                                        f"got {_describe(t.raw('interfaces'))}")
        kw["interfaces"] = tuple(v)
    elif name in ("contact-force", "pressure-variance") and n_interfaces == 0:
        raise t.error("response", f"{name!r} needs a [[contact]] interface; the model has none")
    if t.has("normalized"):
        kw["normalized"] = t.bool("normalized")
    if t.has("quadrature"):
        from contopt.responses.functionals import QUADRATURES

        kw["quadrature"] = t.str("quadrature", choices=QUADRATURES)
    return t.guard(None, builtin, name, **kw)


def _constraints(top: _Table, by_name: dict, n_interfaces: int) -> tuple:
    from contopt.optimize.problem import Constraint

    out = []
    for t in top.tables("constraints", None, ("response",)):
        response = _response(t, by_name, n_interfaces, extra=("upper", "lower", "scale"))
        upper, lower = t.number("upper", None), t.number("lower", None)
        if upper is None and lower is None:
            raise t.error(None, "needs an upper or a lower bound (or both)")
        if upper is not None and lower is not None and lower > upper:
            raise t.error("lower", f"must not exceed upper ({lower} > {upper})")
        out.append(t.guard(None, Constraint, response, upper=upper, lower=lower, scale=t.positive("scale", None)))
    return tuple(out)


# ----------------------------------------------------------------------------------------- comparing
def _response_key(r) -> tuple:
    """What defines a response: its class, name, selections and (for combinations) parts and rule."""
    combine = getattr(r, "combine", None)
    rule = getattr(combine, "__qualname__", None) or repr(combine)
    return (type(r).__name__, r.name, getattr(r, "bodies", None), getattr(r, "interfaces", None),
            getattr(r, "quadrature", None), rule if combine is not None else None,
            tuple(_response_key(p) for p in getattr(r, "parts", ())))


def _model_of(model):
    """The Model of a Model, Discretization or System."""
    from contopt.assembly.system import Discretization
    from contopt.solve.system import System

    if isinstance(model, System):
        return model.model
    return model.model if isinstance(model, Discretization) else model


def problem_differences(a, b) -> list[str]:
    """What differs between two design problems (an empty list: the same problem).

    Compares the models (body names, mesh points and cells, materials, F-bar, supports with their
    values and node sets, loads, contact interfaces with their facet sets), the designs (maps, each
    designed body's settings, and the design matrices G built on the mesh with their summaries),
    the objective and constraints (class, name, selections), normalization and solver options.
    Supports whose value is a callable are compared by identity. E.g. a problem file against the
    Python builder it mirrors: ``problem_differences(load_spec(path).problem, builder())``.
    """
    from contopt.assembly.system import discretize

    out = []

    def same(what, x, y):
        try:
            equal = bool(np.array_equal(np.asarray(x), np.asarray(y))) if not (callable(x) or callable(y)) \
                else x is y
        except (TypeError, ValueError):
            equal = x == y
        if not equal:
            out.append(f"{what}: {x!r} != {y!r}" if len(repr(x)) + len(repr(y)) < 300 else f"{what} differ")
        return equal

    ma, mb = (_model_of(p.model) for p in (a, b))
    if not same("bodies", [x.name for x in ma.bodies], [x.name for x in mb.bodies]):
        return out
    for x, y in zip(ma.bodies, mb.bodies):
        if same(f"bodies[{x.name}] mesh shape", (x.mesh.points.shape, x.mesh.cells.shape),
                (y.mesh.points.shape, y.mesh.cells.shape)):
            same(f"bodies[{x.name}] mesh points", x.mesh.points, y.mesh.points)
            same(f"bodies[{x.name}] mesh cells", x.mesh.cells, y.mesh.cells)
        same(f"bodies[{x.name}] material", dataclasses.astuple(x.material), dataclasses.astuple(y.material))
        same(f"bodies[{x.name}] fbar", x.fbar, y.fbar)
    if same("number of supports", len(ma.dirichlet), len(mb.dirichlet)):
        for i, (x, y) in enumerate(zip(ma.dirichlet, mb.dirichlet)):
            if same(f"supports[{i}]", (x.body, x.node_set, x.components), (y.body, y.node_set, y.components)):
                same(f"supports[{i}] value", x.value if callable(x.value) else np.atleast_1d(x.value),
                     y.value if callable(y.value) else np.atleast_1d(y.value))
                same(f"supports[{i}] nodes", ma.body(x.body).mesh.node_set(x.node_set),
                     mb.body(y.body).mesh.node_set(y.node_set))
    if same("number of loads", len(ma.loads), len(mb.loads)):
        for i, (x, y) in enumerate(zip(ma.loads, mb.loads)):
            if same(f"loads[{i}]", (type(x).__name__, *dataclasses.astuple(x)), (type(y).__name__,
                                                                                *dataclasses.astuple(y))):
                if hasattr(x, "facet_set"):
                    same(f"loads[{i}] facets", ma.body(x.body).mesh.facet_set(x.facet_set),
                         mb.body(y.body).mesh.facet_set(y.facet_set))
    sa_, sb_ = getattr(ma, "soft_supports", ()), getattr(mb, "soft_supports", ())
    if same("soft supports", [x.body for x in sa_], [x.body for x in sb_]):
        same("soft support stiffness", np.allclose([x.stiffness for x in sa_], [x.stiffness for x in sb_],
                                                    rtol=1e-12, atol=0), True)
    if same("number of contact interfaces", len(ma.interfaces), len(mb.interfaces)):
        for i, (x, y) in enumerate(zip(ma.interfaces, mb.interfaces)):
            if same(f"contact[{i}]", dataclasses.astuple(x), dataclasses.astuple(y)):
                for side in ("nonmortar", "mortar"):
                    (bx, sx), (by, sy) = getattr(x, side), getattr(y, side)
                    same(f"contact[{i}].{side} facets", ma.body(bx).mesh.facet_set(sx), mb.body(by).mesh.facet_set(sy))
    da, db = a.design, b.design
    same("design maps", (da.heaviside, da.simp), (db.heaviside, db.simp))
    if same("designed bodies", [x.body for x in da.bodies], [x.body for x in db.bodies]):
        for x, y in zip(da.bodies, db.bodies):
            for key in ("parameterization", "volume_fraction", "symmetry", "skins", "skin_eps"):
                same(f"design of {x.body}: {key}", repr(getattr(x, key)), repr(getattr(y, key)))
        if not out:
            sa, sb = da.build(discretize(ma)), db.build(discretize(mb))
            same("design summary", sa.summary(), sb.summary())
            for pa, pb in zip(sa.parts, sb.parts):
                if same(f"design of {pa.spec.body}: G shape", pa.G.shape, pb.G.shape):
                    diff = abs(pa.G - pb.G)
                    if diff.nnz and diff.max() > 0:
                        out.append(f"design of {pa.spec.body}: G differs by up to {diff.max():.3g}")
                same(f"design of {pa.spec.body}: fixed cells", pa.fixed, pb.fixed)
                if pa.skin is not None or pb.skin is not None:
                    same(f"design of {pa.spec.body}: skin", pa.skin, pb.skin)
    same("objective", _response_key(a.objective), _response_key(b.objective))
    same("constraints", [(_response_key(c.response), c.upper, c.lower, c.scale) for c in a.constraints],
         [(_response_key(c.response), c.upper, c.lower, c.scale) for c in b.constraints])
    for key in ("normalize", "newton", "linear", "augmentation", "adjoint", "warm_start"):
        same(key, repr(getattr(a, key)), repr(getattr(b, key)))
    return out
