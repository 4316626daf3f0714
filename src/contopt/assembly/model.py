"""What a user describes: bodies, supports, prescribed motions and loads.

Everything is a frozen dataclass checked at construction; names of bodies and
sets are checked against the meshes when the :class:`Model` is built, so a
typo fails at once with the list of valid names.

Load factor: every condition is applied at a load factor ``t`` in [0, 1].
Numbers (prescribed displacements, tractions, body forces) are multiplied by
``t``; a callable prescribed displacement receives ``t`` itself.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from contopt.errors import ConfigError, MeshError
from contopt.material.hyperelastic import Material
from contopt.mesh.core import Mesh

_AXES = "xyz"


def _check_vector(name: str, v, n: int = 3) -> tuple:
    arr = np.asarray(v, dtype=float).reshape(-1)
    if arr.size != n or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must be {n} finite numbers, got {v!r}")
    return tuple(float(x) for x in arr)


@dataclass(frozen=True, eq=False)
class Body:
    """One deformable body: a hex8 mesh and its material.

    ``fbar`` switches the mean-dilatation F-bar formulation (on by default:
    plain hex8 locks for nearly incompressible materials).
    """

    name: str
    mesh: Mesh
    material: Material
    fbar: bool = True

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"body name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.mesh, Mesh):
            raise ConfigError(f"body {self.name!r}: mesh must be a contopt.mesh.Mesh, got {type(self.mesh).__name__}")
        if not isinstance(self.material, Material):
            raise ConfigError(
                f"body {self.name!r}: material must be a material (e.g. neo_hookean(E, nu) or "
                f"MooneyRivlin(...)), got {type(self.material).__name__}"
            )
        if not isinstance(self.fbar, bool):
            raise ConfigError(f"body {self.name!r}: fbar must be true or false, got {self.fbar!r}")


Displacement = float | tuple | Callable


@dataclass(frozen=True)
class LoadPath:
    """A prescribed motion along a path: piecewise linear in the load factor from zero at t = 0.

    points : rows ``(t, v_1, ..., v_m)`` with ``0 < t_1 < ... <= 1``, the last at t = 1; the value
    is held after the last row. ``LoadPath(((0.5, 0, 0, -0.01), (1.0, 0.1, 0, -0.01)))`` presses
    down over the first half of the load, then drags along x (friction: the order matters).
    A ``Dirichlet`` value: ``Dirichlet(body, set, "xyz", LoadPath(...))``.
    """

    points: tuple

    def __post_init__(self):
        try:
            rows = np.asarray(self.points, dtype=float)
        except (TypeError, ValueError):
            rows = np.zeros((0, 0))
        if rows.ndim != 2 or rows.shape[0] < 1 or rows.shape[1] < 2 or not np.all(np.isfinite(rows)):
            raise ConfigError(
                f"LoadPath.points must be rows (t, value, ...) of numbers, one value per component, got {self.points!r}"
            )
        t = rows[:, 0]
        if not (t[0] > 0 and np.all(np.diff(t) > 0) and abs(t[-1] - 1.0) <= 1e-12):
            raise ConfigError(
                f"LoadPath.points must have increasing load factors in (0, 1] ending at 1, got {t.tolist()}"
            )
        object.__setattr__(self, "points", tuple(tuple(float(v) for v in r) for r in rows))

    @property
    def n_components(self) -> int:
        return len(self.points[0]) - 1

    def __call__(self, X: np.ndarray, t: float) -> np.ndarray:
        """(k, m) the values at load factor t for k nodes X (k, 3)."""
        rows = np.asarray(self.points)
        ts = np.r_[0.0, rows[:, 0]]
        vals = np.vstack([np.zeros(rows.shape[1] - 1), rows[:, 1:]])
        v = np.array([np.interp(t, ts, vals[:, j]) for j in range(vals.shape[1])])
        return np.tile(v, (len(X), 1))


@dataclass(frozen=True, eq=False)
class Dirichlet:
    """Prescribed displacement components on a node set (or the nodes of a facet set).

    Parameters
    ----------
    body, node_set : where
    components : subset of ``"xyz"`` (e.g. ``"z"`` for a roller, ``"xyz"`` to clamp)
    value : a number (same for all components) or one number per component,
        both scaled by the load factor ``t``; or a callable
        ``value(X, t) -> (k, len(components))`` of the reference coordinates
        ``X`` (k, 3) and ``t`` (not scaled: e.g. a rotation by ``t * angle``).
    """

    body: str
    node_set: str
    components: str = "xyz"
    value: Displacement = 0.0

    def __post_init__(self):
        comps = self.components
        if (
            not isinstance(comps, str)
            or not comps
            or any(c not in _AXES for c in comps)
            or len(set(comps)) != len(comps)
        ):
            raise ConfigError(
                f"Dirichlet components must be distinct letters of 'xyz' (e.g. 'z' or 'xyz'), got {comps!r}"
            )
        if isinstance(self.value, LoadPath) and self.value.n_components != len(comps):
            raise ConfigError(
                f"Dirichlet on {self.body}/{self.node_set}: the load path has {self.value.n_components} values per "
                f"row, the components {comps!r} need {len(comps)}"
            )
        if not callable(self.value):
            arr = np.atleast_1d(np.asarray(self.value, dtype=float))
            if arr.size not in (1, len(comps)) or not np.all(np.isfinite(arr)):
                raise ConfigError(
                    f"Dirichlet value on {self.body}/{self.node_set} must be a number, {len(comps)} numbers "
                    f"(one per component {comps!r}) or a callable value(X, t); got {self.value!r}"
                )

    @property
    def component_indices(self) -> np.ndarray:
        return np.array([_AXES.index(c) for c in self.components], dtype=np.int64)

    def values(self, X: np.ndarray, t: float) -> np.ndarray:
        """(k, len(components)) prescribed displacements at load factor t."""
        k, nc = len(X), len(self.components)
        if callable(self.value):
            out = np.asarray(self.value(X, t), dtype=float)
            if out.shape != (k, nc):
                out = np.broadcast_to(out, (k, nc)) if out.size in (1, nc) else out
            if out.shape != (k, nc) or not np.all(np.isfinite(out)):
                raise ConfigError(
                    f"Dirichlet callable on {self.body}/{self.node_set} must return finite values of shape "
                    f"({k}, {nc}), got {np.shape(out)}"
                )
            return np.array(out)
        return np.broadcast_to(t * np.atleast_1d(np.asarray(self.value, dtype=float)), (k, nc)).copy()


@dataclass(frozen=True, eq=False)
class Traction:
    """Dead surface traction (force per unit reference area) on a facet set, scaled by t."""

    body: str
    facet_set: str
    traction: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "traction", _check_vector("Traction.traction", self.traction))


@dataclass(frozen=True, eq=False)
class BodyForce:
    """Body force per unit reference volume on a whole body, scaled by t."""

    body: str
    force: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "force", _check_vector("BodyForce.force", self.force))


@dataclass(frozen=True, eq=False)
class Acceleration:
    """Inertia load of a rigid acceleration ``a``: body force ``b = -rho_mass a`` (scaled by t).

    Uses the body's ``material.mass_density`` (which must then be positive).
    """

    body: str
    acceleration: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "acceleration", _check_vector("Acceleration.acceleration", self.acceleration))


Load = Traction | BodyForce | Acceleration


@dataclass(frozen=True, eq=False)
class SoftSupport:
    """Weak springs to ground on every node of a body that fade out with the load: ``(1 - t) k``.

    For a body held only by contact (free to translate or rotate until it
    touches): at the start of the load its stiffness matrix is singular and
    Newton cannot take a step. The springs (an elastic foundation of
    ``stiffness`` force per length per unit reference volume, lumped to the
    nodes) make it definite while the body moves onto its supports; they are
    scaled by ``1 - t`` so that at the full load (``t = 1``) they vanish and the
    equilibrium, the responses and the adjoint are those of the model without
    them. Choose ``stiffness`` near ``|b| / gap`` (body force per volume over
    the clearance to close): weaker springs make the early load steps jump,
    stiffer ones are only overcome late in the load.
    """

    body: str
    stiffness: float

    def __post_init__(self):
        if not (np.isfinite(self.stiffness) and self.stiffness > 0):
            raise ConfigError(
                f"SoftSupport on body {self.body!r}: stiffness must be finite and > 0, got {self.stiffness!r}"
            )


@runtime_checkable
class Interface(Protocol):
    """What a Model asks of a contact interface (:class:`contopt.contact.ContactInterface`; contact
    sits above this layer, so the Model knows it by this protocol, not by its class).

    name : what responses call it, unique in a model; label : how messages name it; resolved : itself
    with its nonmortar side decided against the model; validate : ConfigError/MeshError unless its
    bodies and facet sets exist and face each other
    """

    name: str

    @property
    def label(self) -> str: ...

    def resolved(self, model: Model) -> Interface: ...

    def validate(self, model: Model) -> None: ...


@dataclass(frozen=True, eq=False)
class Model:
    """Bodies, boundary conditions and loads (contact interfaces join in ``interfaces``).

    Construction checks every name against the bodies and their meshes, and decides the nonmortar
    side of every interface given as two ``surfaces`` (``ContactInterface.resolved``).
    """

    bodies: tuple
    dirichlet: tuple = ()
    loads: tuple = ()
    interfaces: tuple = field(default=())  # each an Interface (a ContactInterface to the layers above)
    soft_supports: tuple = ()

    def __post_init__(self):
        for name in ("bodies", "dirichlet", "loads", "interfaces", "soft_supports"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        if not self.bodies:
            raise ConfigError("a model needs at least one body")
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ConfigError(f"body names must be unique, got {names}")
        for bc in self.dirichlet:
            if not isinstance(bc, Dirichlet):
                raise ConfigError(f"dirichlet entries must be Dirichlet(...), got {type(bc).__name__}")
            self._check_set(bc.body, node_set=bc.node_set)
        for load in self.loads:
            if isinstance(load, Traction):
                self._check_set(load.body, facet_set=load.facet_set)
                if len(self.body(load.body).mesh.facet_set(load.facet_set)) == 0:
                    raise ConfigError(
                        f"Traction on {load.body}/{load.facet_set}: the facet set is empty, so the "
                        "load would act on nothing; give a set with faces"
                    )
            elif isinstance(load, (BodyForce, Acceleration)):
                body = self.body(load.body)
                if isinstance(load, Acceleration) and body.material.mass_density <= 0:
                    raise ConfigError(
                        f"Acceleration on body {load.body!r} needs material.mass_density > 0 "
                        f"(got {body.material.mass_density})"
                    )
            else:
                raise ConfigError(f"unknown load type {type(load).__name__}; use Traction, BodyForce or Acceleration")
        for support in self.soft_supports:
            if not isinstance(support, SoftSupport):
                raise ConfigError(f"soft_supports entries must be SoftSupport(...), got {type(support).__name__}")
            self.body(support.body)
        for iface in self.interfaces:
            if not isinstance(iface, Interface):
                raise ConfigError(f"interfaces must be ContactInterface(...), got {type(iface).__name__}")
        seen: dict[str, int] = {}
        for i, iface in enumerate(self.interfaces):
            if iface.name in seen:
                raise ConfigError(
                    f"duplicate contact interface name {iface.name!r} (interfaces {seen[iface.name]} and {i}); "
                    "give each its own name"
                )
            seen[iface.name] = i
        # an interface given as two surfaces gets its nonmortar side chosen by the mortar rule
        object.__setattr__(self, "interfaces", tuple(iface.resolved(self) for iface in self.interfaces))
        for iface in self.interfaces:
            iface.validate(self)

    def body(self, name: str) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise ConfigError(f"unknown body {name!r}; the model has bodies {[b.name for b in self.bodies]}")

    def body_index(self, name: str) -> int:
        return [b.name for b in self.bodies].index(self.body(name).name)

    def _check_set(self, body_name: str, node_set: str | None = None, facet_set: str | None = None):
        mesh = self.body(body_name).mesh
        try:
            if node_set is not None:
                mesh.node_set(node_set)
            if facet_set is not None:
                mesh.facet_set(facet_set)
        except MeshError as e:
            raise MeshError(f"body {body_name!r}: {e}") from None
