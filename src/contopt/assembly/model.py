"""What a user describes: bodies, supports, prescribed motions and loads.

Everything is a frozen dataclass checked at construction; names of bodies and
sets are checked against the meshes when the :class:`Model` is built, so a
typo fails at once with the list of valid names.

Load factor: every condition is applied at a load factor ``t`` in [0, 1].
Numbers (prescribed displacements, tractions, body forces) are multiplied by
``t``; a callable prescribed displacement receives ``t`` itself.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from contopt.errors import ConfigError, MeshError
from contopt.material.hyperelastic import Material, neo_hookean
from contopt.mesh.core import Mesh

_AXES = "xyz"
_log = logging.getLogger(__name__)
#: Poisson's ratio above which tet4 locks (a constant-strain tet cannot keep its volume in bending)
TET4_LOCKING_NU = 0.45
#: the warnings given once a process
_WARNED: set = set()


def _warn_tet4_locking(body: str, nu: float) -> None:
    """Warn once a process that tet4 locks for nearly incompressible materials (one line)."""
    if "tet4" in _WARNED:
        return
    _WARNED.add("tet4")
    _log.warning(
        "body %r: tet4 locks (is far too stiff) for nu above about %g, and its nu is %g: mesh it with tet10 "
        "(order = 2)",
        body,
        TET4_LOCKING_NU,
        nu,
    )


def _check_vector(name: str, v, n: int = 3) -> tuple:
    arr = np.asarray(v, dtype=float).reshape(-1)
    if arr.size != n or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must be {n} finite numbers, got {v!r}")
    return tuple(float(x) for x in arr)


@dataclass(frozen=True, eq=False)
class Body:
    """One body: a hex8, tet4 or tet10 mesh and its material, or a rigid tool.

    ``fbar`` switches the mean-dilatation F-bar formulation of hex8 (on by default:
    plain hex8 locks for nearly incompressible materials). Tets take none: tet10 does not lock,
    and F-bar at tet4's single quadrature point would be the identity; a tet4 body with
    Poisson's ratio above :data:`TET4_LOCKING_NU` logs a warning (once) that points to tet10.

    ``rigid``: a :class:`RigidMotion` makes the body a rigid tool with no unknowns: every node of its
    mesh follows the motion (the Model prescribes them, node set ``all``), it takes no material (a
    placeholder fills ``material``: under a rigid motion ``F = R`` and no material stores energy),
    no supports and no loads, and in contact it is the mortar side. Its mesh is usually the layer
    under a tool's surface (:func:`contopt.mesh.tool.tool_layer`); the reaction on its nodes is the
    force the contact transmits.
    """

    name: str
    mesh: Mesh
    material: Material | None = None
    fbar: bool = True
    rigid: RigidMotion | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"body name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.mesh, Mesh):
            raise ConfigError(f"body {self.name!r}: mesh must be a contopt.mesh.Mesh, got {type(self.mesh).__name__}")
        if self.rigid is not None:
            self._rigid()
        elif not isinstance(self.material, Material):
            raise ConfigError(
                f"body {self.name!r}: material must be a material (e.g. neo_hookean(E, nu) or "
                f"MooneyRivlin(...)), or the body rigid=RigidMotion(...); got {type(self.material).__name__}"
            )
        if not isinstance(self.fbar, bool):
            raise ConfigError(f"body {self.name!r}: fbar must be true or false, got {self.fbar!r}")
        if self.rigid is None and self.material is not None and self.mesh.element == "tet4":
            nu = float(self.material.poisson_ratio)
            if nu > TET4_LOCKING_NU:
                _warn_tet4_locking(self.name, nu)

    def _rigid(self) -> None:
        if not isinstance(self.rigid, RigidMotion):
            raise ConfigError(f"body {self.name!r}: rigid must be a RigidMotion(...), got {type(self.rigid).__name__}")
        if self.material is not None and self.material is not RIGID_MATERIAL:
            raise ConfigError(
                f"body {self.name!r} is rigid: it takes no material (its motion alone decides where it is)"
            )
        object.__setattr__(self, "material", RIGID_MATERIAL)
        if "all" not in self.mesh.node_sets:  # the set the Model prescribes
            object.__setattr__(self, "mesh", self.mesh.with_sets(node_sets={"all": np.arange(self.mesh.n_nodes)}))


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


def _rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) the rotation by ``angle`` (radians, right-handed) about the unit vector ``axis`` (Rodrigues)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


@dataclass(frozen=True)
class RigidMotion:
    """The prescribed motion of a rigid tool: ``x = R(t) (X - point) + point + c(t)``.

    translation : the tool's displacement c: (3,) numbers scaled by the load factor, or a
        :class:`LoadPath` of three components (a path: press, then slide)
    axis : (3,) the rotation's axis (made a unit vector); point : (3,) a point on the axis, in the
        reference configuration (it moves with the translation)
    angle : the rotation angle in radians (right-handed about ``axis``), scaled by the load factor, or
        a :class:`LoadPath` of one component (radians)

    ``RigidMotion()`` holds the tool where it is. A value of :class:`Dirichlet` (``value(X, t)``:
    the displacements ``x - X``, (k, 3)); a frozen value, so a Model that holds it pickles and
    compares like the rest.
    """

    translation: tuple | LoadPath = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    point: tuple = (0.0, 0.0, 0.0)
    angle: float | LoadPath = 0.0

    def __post_init__(self):
        if isinstance(self.translation, LoadPath):
            if self.translation.n_components != 3:
                raise ConfigError(
                    f"RigidMotion.translation: the path has {self.translation.n_components} values per row, "
                    "a translation needs 3 (t, ux, uy, uz)"
                )
        else:
            object.__setattr__(self, "translation", _check_vector("RigidMotion.translation", self.translation))
        axis = np.asarray(_check_vector("RigidMotion.axis", self.axis))
        if not np.linalg.norm(axis) > 0:
            raise ConfigError("RigidMotion.axis must be a nonzero vector [x, y, z], got [0, 0, 0]")
        object.__setattr__(self, "axis", tuple(float(a) for a in axis / np.linalg.norm(axis)))
        object.__setattr__(self, "point", _check_vector("RigidMotion.point", self.point))
        if isinstance(self.angle, LoadPath):
            if self.angle.n_components != 1:
                raise ConfigError(
                    f"RigidMotion.angle: the path has {self.angle.n_components} values per row, an angle needs "
                    "1 (t, angle)"
                )
        elif isinstance(self.angle, bool) or not isinstance(self.angle, (int, float)) or not np.isfinite(self.angle):
            raise ConfigError(f"RigidMotion.angle must be a number (radians) or a LoadPath, got {self.angle!r}")
        else:
            object.__setattr__(self, "angle", float(self.angle))

    def rotation(self, t: float) -> np.ndarray:
        """(3, 3) the rotation R at load factor t."""
        angle = self.angle(np.zeros((1, 3)), t)[0, 0] if isinstance(self.angle, LoadPath) else t * self.angle
        return _rotation_matrix(np.asarray(self.axis), float(angle))

    def offset(self, t: float) -> np.ndarray:
        """(3,) the translation c at load factor t."""
        if isinstance(self.translation, LoadPath):
            return self.translation(np.zeros((1, 3)), t)[0]
        return t * np.asarray(self.translation)

    def __call__(self, X: np.ndarray, t: float) -> np.ndarray:
        """(k, 3) the displacements ``x - X`` of the reference points X (k, 3) at load factor t."""
        X = np.asarray(X, dtype=np.float64).reshape(-1, 3)
        p = np.asarray(self.point)
        return (X - p) @ self.rotation(t).T + p + self.offset(t) - X


#: what fills a rigid body's material (never used: a rigid motion stores no energy in any material)
RIGID_MATERIAL = neo_hookean(1.0, 0.0)


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

    Construction checks every name against the bodies and their meshes, adds the prescribed motion
    of every rigid body (a Dirichlet on its node set ``all``: a rigid body takes no other support and
    no load), and decides the nonmortar side of every interface given as two ``surfaces``
    (``ContactInterface.resolved``; a rigid body's surface is always the mortar side).
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
                material = self.body(load.body).material  # a Material: Body fills a rigid one's
                density = material.mass_density if material is not None else 0.0
                if isinstance(load, Acceleration) and density <= 0:
                    raise ConfigError(
                        f"Acceleration on body {load.body!r} needs material.mass_density > 0 (got {density})"
                    )
            else:
                raise ConfigError(f"unknown load type {type(load).__name__}; use Traction, BodyForce or Acceleration")
        for support in self.soft_supports:
            if not isinstance(support, SoftSupport):
                raise ConfigError(f"soft_supports entries must be SoftSupport(...), got {type(support).__name__}")
            self.body(support.body)
        self._prescribe_rigid()
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

    def _prescribe_rigid(self) -> None:
        """Every node of a rigid body follows its motion (one Dirichlet on its node set ``all``, added
        here); nothing else may hold or load it."""
        rigid = {b.name: b.rigid for b in self.bodies if b.rigid is not None}
        own = [bc for bc in self.dirichlet if bc.body in rigid and bc.value is rigid[bc.body]]
        for bc in self.dirichlet:
            if bc.body in rigid and bc not in own:
                raise ConfigError(
                    f"body {bc.body!r} is rigid: its motion prescribes every node; remove the support on "
                    f"{bc.body}/{bc.node_set} (move the tool with its motion)"
                )
        for what, entries in (("load", self.loads), ("soft support", self.soft_supports)):
            for entry in entries:
                if entry.body in rigid:
                    raise ConfigError(
                        f"body {entry.body!r} is rigid: a {what} on it does nothing (its motion prescribes every "
                        "node); remove it"
                    )
        added = tuple(
            Dirichlet(name, "all", "xyz", motion)
            for name, motion in rigid.items()
            if not any(bc.body == name for bc in own)  # a Model rebuilt from one (dataclasses.replace) has it
        )
        object.__setattr__(self, "dirichlet", self.dirichlet + added)

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
