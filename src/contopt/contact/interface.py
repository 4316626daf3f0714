"""A contact interface between two bodies: which surfaces, which contact law, how it is checked."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from contopt.contact.friction import Coulomb
from contopt.contact.laws import ContactLaw, law_named
from contopt.contact.verify import PenetrationCheck
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
        the pressure unknowns; choose the finer (or softer) surface.
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
    friction : None (frictionless), a :class:`contopt.contact.friction.Coulomb` or its
        coefficient ``mu`` (a number). Friction makes the solution depend on the load path (load
        steps matter, every step converges its augmentations) and the tangent unsymmetric.
    """

    nonmortar: tuple[str, str]
    mortar: tuple[str, str]
    law: ContactLaw
    skin: float | None = None
    max_angle_deg: float = 75.0
    check: PenetrationCheck = field(default_factory=PenetrationCheck)
    friction: Coulomb | None = None

    # written out (not the dataclass's) because ``law`` may be given by name: the attribute is
    # always a ContactLaw. The default check is shared: PenetrationCheck is frozen.
    def __init__(
        self,
        nonmortar: Sequence[str],
        mortar: Sequence[str],
        law: ContactLaw | str = "alm",
        skin: float | None = None,
        max_angle_deg: float = 75.0,
        check: PenetrationCheck = _DEFAULT_CHECK,
        friction: Coulomb | float | None = None,
    ) -> None:
        object.__setattr__(self, "nonmortar", _surface("nonmortar", nonmortar))
        object.__setattr__(self, "mortar", _surface("mortar", mortar))
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
    def enforcement(self) -> str:
        """The law's name (``"alm"`` or ``"penalty"``)."""
        return self.law.name

    @property
    def label(self) -> str:
        return f"{self.nonmortar[0]}/{self.nonmortar[1]} -> {self.mortar[0]}/{self.mortar[1]}"

    def validate(self, model) -> None:
        """Check against a model: bodies and facet sets exist, and the surfaces face each other."""
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
            surfaces.append(body.mesh.points[body.mesh.facet_nodes(facets)])
        _check_facing(self.label, *surfaces)

    def _moduli(self, model) -> list[float]:
        """The plane-strain moduli ``E' = E/(1-nu^2)`` of the nonmortar and the mortar body."""
        mats = [model.body(getattr(self, side)[0]).material for side in ("nonmortar", "mortar")]
        return [m.youngs_modulus / (1.0 - m.poisson_ratio**2) for m in mats]

    def _modulus_and_size(self, model) -> tuple[float, float]:
        """The contact modulus ``E*`` of the pair and the median nonmortar facet size ``h``."""
        body = model.body(self.nonmortar[0])
        x = body.mesh.points[body.mesh.facet_nodes(self.nonmortar[1])]
        return 1.0 / sum(1.0 / m for m in self._moduli(model)), float(np.median(facet_sizes(x)))

    def default_eps(self, model) -> float:
        """The law's penalty on this interface: its ``eps``, or ``factor * E* / h`` (class docstring)."""
        return self.law.resolve_eps(*self._modulus_and_size(model))

    def max_eps(self, model) -> float:
        """The largest penalty the law may grow to (:meth:`ContactLaw.max_penalty`), from the stiffer
        body's ``E'`` and the median nonmortar facet size."""
        return self.law.max_penalty(max(self._moduli(model)), self._modulus_and_size(model)[1])

    def friction_eps(self, model) -> float:
        """The tangential penalty of stick (0 without friction), see :class:`Coulomb`."""
        return 0.0 if self.friction is None else self.friction.resolve_eps(*self._modulus_and_size(model))


def facet_sizes(x: np.ndarray) -> np.ndarray:
    """(k,) square root of the area of facets x (k, 4, 3) (a length scale)."""
    n = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    return np.sqrt(0.5 * np.linalg.norm(n, axis=1))


def facet_normals(x: np.ndarray) -> np.ndarray:
    """(k, 3) unit normals at the facet centres (right-hand rule: outward of the facet's body)."""
    n = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _check_facing(label: str, x_nm: np.ndarray, x_m: np.ndarray) -> None:
    """Error if the two surfaces are close but no close pair of facets faces each other."""
    from scipy.spatial import cKDTree

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
