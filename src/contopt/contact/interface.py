"""A contact interface between two bodies: which surfaces, which contact law, how it is checked."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from contopt.contact.coulomb import Coulomb
from contopt.contact.facets import contact_facets
from contopt.contact.laws import ContactLaw, law_named
from contopt.contact.verify import PenetrationCheck, SideAdvice
from contopt.errors import ConfigError, MeshError

log = logging.getLogger(__name__)

_DEFAULT_CHECK = PenetrationCheck()


def _surface(name: str, value) -> tuple[str, str]:
    if not isinstance(value, (tuple, list)) or len(value) != 2 or not all(isinstance(v, str) and v for v in value):
        raise ConfigError(f"ContactInterface.{name} must be (body name, facet set name), got {value!r}")
    return (value[0], value[1])


@dataclass(frozen=True, eq=False, init=False)
class ContactInterface:
    """Mortar contact between a nonmortar and a mortar surface, frictionless or with Coulomb friction.

    Parameters
    ----------
    nonmortar, mortar : (body name, facet set name). The nonmortar side carries
        the pressure unknowns; choose the finer (or softer) surface. Or give neither and
        ``surfaces=(a, b)``: the model then chooses the nonmortar side by the mortar rule
        (:func:`choose_sides`: the finer surface; for facets of about one size the more curved,
        then the softer) and says which it chose and why (``choice``).
    law : the contact law, :class:`contopt.contact.laws.AugmentedLagrangian` (default) or
        :class:`contopt.contact.laws.Penalty`, with its penalty ``eps`` and options; a name
        (``"alm"``, ``"penalty"``) gives that law with its defaults. The default ``eps`` is
        ``10 E*/h`` (ALM) or ``100 E*/h`` (penalty), with ``E*`` the contact modulus
        ``1/E* = 1/E1' + 1/E2'`` (``E' = E/(1-nu^2)``) and ``h`` the median nonmortar facet
        size; the paper's eps = 10 (E = 1) is ``AugmentedLagrangian(eps=10)``.
    skin : search distance added to the facet bounding boxes (default: half the facet size)
    max_angle_deg : facet pairs whose normals are further than this from
        facing each other are not paired
    check : the independent check of every converged state
        (:class:`contopt.contact.verify.PenetrationCheck`)
    friction : None (frictionless), a :class:`contopt.contact.coulomb.Coulomb` or its
        coefficient ``mu`` (a number). Friction makes the solution depend on the load path (load
        steps matter, every step converges its augmentations) and the tangent unsymmetric.
    surfaces : the two surfaces in any order, instead of ``nonmortar`` and ``mortar``.
    name : what responses and messages call the interface, unique in a model; default
        ``"{nonmortar body}-{mortar body}"`` (with ``surfaces``: the bodies in the order given, so
        the name does not change with the side the model chooses)

    ``sides`` says who decided: ``"given"`` (the user), ``"auto"`` (``surfaces`` given, not yet
    decided: the Model decides, :meth:`resolved`) or ``"chosen"``; ``choice`` says why.
    """

    nonmortar: tuple[str, str]
    mortar: tuple[str, str]
    law: ContactLaw
    skin: float | None = None
    max_angle_deg: float = 75.0
    check: PenetrationCheck = field(default_factory=PenetrationCheck)
    friction: Coulomb | None = None
    sides: str = "given"
    choice: str = ""
    name: str = ""

    # written out (not the dataclass's) because ``law`` may be given by name: the attribute is
    # always a ContactLaw. The default check is shared: PenetrationCheck is frozen.
    def __init__(
        self,
        nonmortar: Sequence[str] | None = None,
        mortar: Sequence[str] | None = None,
        law: ContactLaw | str = "alm",
        skin: float | None = None,
        max_angle_deg: float = 75.0,
        check: PenetrationCheck = _DEFAULT_CHECK,
        friction: Coulomb | float | None = None,
        surfaces: Sequence[Sequence[str]] | None = None,
        sides: str = "given",
        choice: str = "",
        name: str | None = None,
    ) -> None:
        if surfaces is not None:
            if nonmortar is not None or mortar is not None:
                raise ConfigError(
                    "ContactInterface: give either nonmortar and mortar, or surfaces (then the nonmortar side "
                    "is chosen for you), not both"
                )
            if not isinstance(surfaces, (tuple, list)) or len(surfaces) != 2:
                raise ConfigError(
                    f"ContactInterface.surfaces must be two (body name, facet set name), got {surfaces!r}"
                )
            nonmortar, mortar, sides = surfaces[0], surfaces[1], "auto"
        elif nonmortar is None or mortar is None:
            raise ConfigError(
                "ContactInterface needs nonmortar and mortar (body name, facet set name), or surfaces=(a, b) to "
                "have the nonmortar side chosen"
            )
        if sides not in ("given", "auto", "chosen"):
            raise ConfigError(f"ContactInterface.sides must be 'given', 'auto' or 'chosen', got {sides!r}")
        object.__setattr__(self, "nonmortar", _surface("nonmortar", nonmortar))
        object.__setattr__(self, "mortar", _surface("mortar", mortar))
        name = f"{self.nonmortar[0]}-{self.mortar[0]}" if name is None else name
        if not isinstance(name, str) or not name:
            raise ConfigError(f"ContactInterface.name must be a non-empty string, got {name!r}")
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "sides", sides)
        object.__setattr__(self, "choice", str(choice))
        object.__setattr__(self, "law", law_named(law) if isinstance(law, str) else law)
        object.__setattr__(self, "skin", skin)
        object.__setattr__(self, "max_angle_deg", max_angle_deg)
        object.__setattr__(self, "check", check)
        if friction is not None and not isinstance(friction, Coulomb):
            if isinstance(friction, bool) or not isinstance(friction, (int, float)):
                raise ConfigError(
                    "ContactInterface.friction must be None, a Coulomb(...) or a friction coefficient, "
                    f"got {friction!r}"
                )
            friction = Coulomb(float(friction))
        object.__setattr__(self, "friction", friction)
        if not isinstance(self.law, ContactLaw):
            raise ConfigError(
                f"ContactInterface.law must be a contact law (AugmentedLagrangian(), Penalty()) or "
                f"its name, got {self.law!r}"
            )
        if not isinstance(self.check, PenetrationCheck):
            raise ConfigError(f"ContactInterface.check must be a PenetrationCheck, got {self.check!r}")
        if self.skin is not None and not (np.isfinite(self.skin) and self.skin >= 0):
            raise ConfigError(f"ContactInterface.skin must be >= 0, got {self.skin!r}")
        if not (0 < self.max_angle_deg <= 90):
            raise ConfigError(f"ContactInterface.max_angle_deg must lie in (0, 90], got {self.max_angle_deg!r}")
        if self.nonmortar[0] == self.mortar[0]:
            raise ConfigError(f"self-contact is not supported: both sides are on body {self.nonmortar[0]!r}")

    @property
    def label(self) -> str:
        return f"{self.nonmortar[0]}/{self.nonmortar[1]} -> {self.mortar[0]}/{self.mortar[1]}"

    def resolved(self, model) -> ContactInterface:
        """This interface with its sides decided: itself unless ``sides == "auto"``."""
        if self.sides != "auto":
            return self
        self.validate(model)  # the sets exist and face each other, said with the interface's name
        nonmortar, mortar, _, why = choose_sides(model, self.nonmortar, self.mortar)
        choice = f"nonmortar {nonmortar[0]}/{nonmortar[1]}: {why}"
        log.info("contact interface %s/%s <-> %s/%s: %s", *self.nonmortar, *self.mortar, choice)
        return replace(self, nonmortar=nonmortar, mortar=mortar, sides="chosen", choice=choice)

    def mismatch(self, model) -> str:
        """Why the mortar rule would make the other surface nonmortar for its resolution or shape
        ("" when it agrees, or prefers it only for being softer): the weighted gaps of a coarse
        nonmortar do not see a finer, curved mortar's nodes between its own."""
        nonmortar, _, rule, why = choose_sides(model, self.mortar, self.nonmortar)
        return why if nonmortar == self.mortar and rule in ("finer", "curved") else ""

    def side_advice(self, model) -> SideAdvice:
        """What the mortar rule says of this interface's sides (:meth:`mismatch`), for the state check."""
        mismatch = self.mismatch(model)
        if not mismatch:
            return SideAdvice()
        return SideAdvice(mismatch=mismatch, swap="/".join(self.mortar), size=surface_measures(model, self.mortar).h)

    def validate(self, model) -> None:
        """Check against a model: bodies and facet sets exist, the surfaces face each other, and a rigid
        body is the mortar side."""
        rigid = [is_rigid(model, getattr(self, side)) for side in ("nonmortar", "mortar")]
        if all(rigid):
            raise ConfigError(f"contact interface {self.label}: both bodies are rigid; contact needs a deformable side")
        if rigid[0] and self.sides != "auto":
            raise ConfigError(
                f"contact interface {self.label}: body {self.nonmortar[0]!r} is rigid and must be the mortar side: "
                f"swap nonmortar and mortar (or give surfaces to have them chosen)"
            )
        surfaces = []
        for side in ("nonmortar", "mortar"):
            body_name, facet_set = getattr(self, side)
            body = model.body(body_name)
            try:
                facets = body.mesh.facet_set(facet_set)
            except MeshError as e:
                raise MeshError(f"contact interface {self.label}: body {body_name!r}: {e}") from None
            if len(facets) == 0:
                raise MeshError(f"contact interface {self.label}: the {side} facet set {facet_set!r} is empty")
            surfaces.append(body.mesh.points[contact_facets(body.mesh, facets)])
        _check_facing(self.label, *surfaces)

    def _moduli(self, model) -> list[float]:
        """The plane-strain moduli ``E' = E/(1-nu^2)`` of the nonmortar and the mortar body (inf: rigid)."""
        return [surface_modulus(model, getattr(self, side)) for side in ("nonmortar", "mortar")]

    def _modulus_and_size(self, model) -> tuple[float, float]:
        """The contact modulus ``E*`` of the pair and the median nonmortar facet size ``h``."""
        body = model.body(self.nonmortar[0])
        x = body.mesh.points[contact_facets(body.mesh, self.nonmortar[1])]
        return 1.0 / sum(1.0 / m for m in self._moduli(model)), float(np.median(facet_sizes(x)))

    def default_eps(self, model) -> float:
        """The law's penalty on this interface: its ``eps``, or ``factor * E* / h`` (class docstring)."""
        return self.law.resolve_eps(*self._modulus_and_size(model))

    def max_eps(self, model) -> float:
        """The largest penalty the law may grow to (:meth:`ContactLaw.max_penalty`), from the stiffer
        deformable body's ``E'`` and the median nonmortar facet size."""
        # a rigid side has no modulus to bound the penalty by: the deformable side's E' does
        stiffer = max(m for m in self._moduli(model) if np.isfinite(m))
        return self.law.max_penalty(stiffer, self._modulus_and_size(model)[1])

    def friction_eps(self, model) -> float:
        """The tangential penalty of stick (0 without friction), see :class:`Coulomb`."""
        return 0.0 if self.friction is None else self.friction.resolve_eps(*self._modulus_and_size(model))


#: facet sizes within this ratio count as one size (the more curved surface then is nonmortar)
SIZE_TIE = 0.8
#: curvatures that differ by less than this many radians per facet count as equally curved
KINK_TIE = 0.05
#: contact moduli within this ratio count as equally stiff
STIFFNESS_TIE = 0.5


@dataclass(frozen=True)
class SurfaceMeasures:
    """What the mortar rule compares of a contact surface (reference configuration).

    h : median facet size (square root of the area); curvature : the larger principal curvature,
    from the angles between the normals of edge-neighbouring facets over the distance of their
    centres (0: flat; 1/R on a cylinder); modulus : the body's plane-strain modulus ``E/(1 - nu^2)``
    """

    h: float
    curvature: float
    modulus: float

    def describe(self) -> str:
        shape = "flat" if self.curvature * self.h < KINK_TIE else f"radius {1.0 / self.curvature:.3g}"
        stiffness = "rigid" if np.isinf(self.modulus) else f"E' {self.modulus:.3g}"
        return f"facets {self.h:.3g}, {shape}, {stiffness}"


def plane_strain_modulus(material) -> float:
    """``E' = E / (1 - nu^2)`` of a material (the contact modulus of one side)."""
    return material.youngs_modulus / (1.0 - material.poisson_ratio**2)


def is_rigid(model, surface: tuple[str, str]) -> bool:
    """Whether the body of ``surface = (body, set)`` is a rigid tool (``Body.rigid``)."""
    return model.body(surface[0]).rigid is not None


def surface_modulus(model, surface: tuple[str, str]) -> float:
    """The plane-strain modulus of the body of ``surface``: inf for a rigid tool (``1/E*`` then is the
    other side's ``1/E'`` alone)."""
    return np.inf if is_rigid(model, surface) else plane_strain_modulus(model.body(surface[0]).material)


def surface_measures(model, surface: tuple[str, str]) -> SurfaceMeasures:
    """:class:`SurfaceMeasures` of the facet set ``surface = (body, set)`` of ``model``."""
    body = model.body(surface[0])
    nodes = contact_facets(body.mesh, surface[1])  # (F, 4), triangles padded
    x = body.mesh.points[nodes]
    return SurfaceMeasures(
        h=float(np.median(facet_sizes(x))),
        curvature=_curvature(x, nodes),
        modulus=surface_modulus(model, surface),
    )


def _curvature(x: np.ndarray, nodes: np.ndarray) -> float:
    """Median over the facets (x (F, 4, 3), node ids (F, 4)) of the largest kink angle / centre
    distance to a facet sharing an edge: a surface's larger principal curvature (1/R on a cylinder)."""
    i = np.arange(4)
    edges = np.sort(np.stack([nodes[:, i], nodes[:, (i + 1) % 4]], axis=2).reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(len(nodes)), 4)
    real = edges[:, 0] != edges[:, 1]  # a triangle's edge 3 (node 0 to its repeat) is no edge
    edges, owner = edges[real], owner[real]
    order = np.lexsort(edges.T[::-1])
    e, o = edges[order], owner[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    a, b = o[:-1][same], o[1:][same]
    if a.size == 0:
        return 0.0
    n, c = facet_normals(x), x.mean(axis=1)
    kink = np.arccos(np.clip(np.einsum("ij,ij->i", n[a], n[b]), -1.0, 1.0))
    k = kink / np.maximum(np.linalg.norm(c[a] - c[b], axis=1), 1e-300)
    largest = np.zeros(len(nodes))
    np.maximum.at(largest, a, k)
    np.maximum.at(largest, b, k)
    return float(np.median(largest))


def choose_sides(model, a: tuple[str, str], b: tuple[str, str]) -> tuple[tuple, tuple, str, str]:
    """The mortar rule: ``(nonmortar, mortar, rule, why)`` of two surfaces ``(body, set)``; ``rule``
    is the test that decided: ``"rigid"``, ``"finer"``, ``"curved"``, ``"softer"`` or ``"first"``.

    Against a rigid tool the deformable surface is nonmortar (a tool has no unknowns to carry
    pressures). Otherwise the finer surface is nonmortar (facet sizes differing by more than
    :data:`SIZE_TIE`); for facets of about one size the more curved one (its normals turning by
    :data:`KINK_TIE` rad per facet more), then the softer (:data:`STIFFNESS_TIE`); else ``a``. A
    coarse nonmortar enforces its weighted gaps at its own nodes only, and a finer or curved mortar's
    nodes then sink between them (a 16-gon roller on a beam's top of 0.125: 0.07 h, one node column
    carrying the load).
    """
    ma, mb = surface_measures(model, a), surface_measures(model, b)
    if is_rigid(model, a) != is_rigid(model, b):  # a rigid tool has no unknowns to carry pressures with
        first, rule, why = is_rigid(model, b), "rigid", "the deformable surface (the other is a rigid tool)"
    elif min(ma.h, mb.h) < SIZE_TIE * max(ma.h, mb.h):
        first, rule, why = ma.h < mb.h, "finer", "the finer surface"
    elif abs(ma.curvature - mb.curvature) * max(ma.h, mb.h) > KINK_TIE:
        first, rule = ma.curvature > mb.curvature, "curved"
        why = "facets of about one size, the more curved surface"
    elif min(ma.modulus, mb.modulus) < STIFFNESS_TIE * max(ma.modulus, mb.modulus):
        first, rule = ma.modulus < mb.modulus, "softer"
        why = "the softer surface (facets of about one size, equally curved)"
    else:
        first, rule, why = True, "first", "the first given (the two surfaces are alike)"
    (nm, mn), (m_nm, m_m) = ((a, b), (ma, mb)) if first else ((b, a), (mb, ma))
    return nm, mn, rule, f"{why} ({m_nm.describe()}; the other: {m_m.describe()})"


def facet_sizes(x: np.ndarray) -> np.ndarray:
    """(k,) square root of the area of facets x (k, 4, 3) (a length scale; a triangle's too, padded)."""
    n = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    return np.sqrt(0.5 * np.linalg.norm(n, axis=1))


def facet_normals(x: np.ndarray) -> np.ndarray:
    """(k, 3) unit normals at the facet centres (right-hand rule: outward of the facet's body)."""
    n = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _check_facing(label: str, x_nm: np.ndarray, x_m: np.ndarray) -> None:
    """Error if the two surfaces are close but no close pair of facets faces each other."""
    c_nm, c_m = x_nm.mean(axis=1), x_m.mean(axis=1)
    h = max(facet_sizes(x_nm).max(), facet_sizes(x_m).max())
    dist, idx = cKDTree(c_m).query(c_nm)
    close = dist <= 2.0 * h
    if not close.any():
        log.warning(
            "contact interface %s: the surfaces are initially %.3g apart (facet size %.3g); "
            "they will be paired once they come close",
            label,
            float(dist.min()),
            h,
        )
        return
    dots = np.einsum("ij,ij->i", facet_normals(x_nm)[close], facet_normals(x_m)[idx[close]])
    if not (dots < 0).any():
        raise MeshError(
            f"contact interface {label}: the two facet sets are close but do not face each other "
            "(their outward normals point the same way); check that each set is the surface that "
            "touches the other body"
        )
