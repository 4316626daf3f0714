"""Load-path responses: a force (or another quantity) read at several load steps and combined into one number.

A load-path response reads a quantity ``F_k`` at the load factors ``t_k = k / steps``, ``k = 1 ..
steps``, or at the load factors ``steps = [t_1, .., t_n]`` given (increasing within (0, 1]: the
steps after a tool touches, or one step alone); ``on`` chooses it:

* ``"contact"`` (default): the contact force (:class:`ContactForce`, with ``interfaces``,
  ``quadrature`` and ``direction``);
* ``"reaction"``: the force a body's support or prescribed motion puts on it
  (:class:`contopt.responses.quantities.Reaction`: ``bodies`` one body, ``set`` its node set where
  it has several, ``direction`` by default the motion's);
* ``"displacement"``: the mean displacement of a node set along ``direction``
  (:class:`contopt.responses.quantities.MeanDisplacement`: ``bodies`` one body, ``set``, ``direction``);
* ``"energy"``: the strain energy of ``bodies`` (default all; :class:`StrainEnergy`).

With every condition and load scaled by
``t`` from the unloaded bodies, ``t_k`` is the share of the prescribed motion (or the load) at step
k, so ``(t_k, F_k)`` is the force-displacement curve. The solve must end a load step on every
``t_k`` (its :attr:`stops`; :func:`contopt.solve.static.solve_static` ``stops=``, with the path
recorded) and the adjoint runs back over those steps (:mod:`contopt.adjoint.path`), through the
friction history where there is one.

* :class:`ForceTarget`: ``sum_k w_k (F_k - F*(t_k))^2`` with ``w_k = 1 / n`` over the n steps read (the mean squared
  miss, in force^2) and the target ``F*`` interpolated linearly between the given points ``(t, F)``;
* :class:`ForceMax`, :class:`ForceMin`: the largest or smallest ``F_k``, aggregated smoothly
  (Kreisselmeier-Steinhauser): ``(1/s) log((1/n) sum_k exp(s F_k))`` with ``s`` the ``sharpness``
  in 1/force, within ``log(n)/s`` below the largest value (``-s`` for the smallest, above it).
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from contopt.errors import ConfigError
from contopt.responses.base import Fields, Partials, Response, as_fields
from contopt.responses.catalog import ON, READS


def checked_steps(steps, who: str) -> tuple:
    """The load factors ``t_k`` that ``steps`` names: a count n >= 1 (``k / n``, k = 1 .. n) or a list of
    load factors increasing within (0, 1]; ConfigError naming the response class ``who`` otherwise."""
    if isinstance(steps, (list, tuple, np.ndarray)):
        ok = all(isinstance(t, (int, float, np.integer, np.floating)) and not isinstance(t, bool) for t in steps)
        t = np.asarray(steps, dtype=np.float64) if ok and len(steps) else np.zeros(0)
        if not t.size or not np.all(np.isfinite(t)) or t[0] <= 0 or t[-1] > 1 or np.any(np.diff(t) <= 0):
            raise ConfigError(
                f"{who}.steps must be load factors that increase within (0, 1] when it is a list, e.g. "
                f"[0.5, 0.75, 1.0], got {list(steps)!r}"
            )
        return tuple(float(v) for v in t)
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ConfigError(
            f"{who}.steps must be a whole number of load steps >= 1 or a list of load factors in (0, 1], got {steps!r}"
        )
    return tuple(k / int(steps) for k in range(1, int(steps) + 1))


def checked_target(target, who: str) -> np.ndarray:
    """(m, 2) target points ``(t, F)`` with t increasing in [0, 1]; ConfigError otherwise."""
    try:
        pts = np.asarray(target, dtype=np.float64)
    except (TypeError, ValueError):
        pts = np.zeros((0, 0))
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 1 or not np.all(np.isfinite(pts)):
        raise ConfigError(
            f"{who}.target must be a list of [load factor, force] points, e.g. [[0, 0], [1, 4]], got {target!r}"
        )
    t = pts[:, 0]
    if np.any(np.diff(t) <= 0) or t[0] < 0 or t[-1] > 1:
        raise ConfigError(f"{who}.target must have load factors that increase within [0, 1], got {t.tolist()}")
    return pts


def _one_body(bodies, who: str, on: str) -> str:
    names = (bodies,) if isinstance(bodies, str) else tuple(bodies) if bodies is not None else ()
    if len(names) != 1 or not isinstance(names[0], str):
        raise ConfigError(f'{who}.bodies must name one body with on = "{on}", got {bodies!r}')
    return names[0]


def path_quantity(on: str, options: dict, who: str, name: str) -> Response:
    """The response of one state read at each load step (module docstring): ``on`` and its
    ``options`` (those of :data:`READS`, None where not given); ConfigError naming ``who``'s option."""
    from contopt.responses.functionals import ContactForce, StrainEnergy  # which maps the names to these classes
    from contopt.responses.quantities import MeanDisplacement, Reaction

    if not isinstance(on, str) or on not in ON:
        raise ConfigError(f"{who}.on must be one of {ON}, got {on!r}")
    for k, v in options.items():
        if v is not None and k not in READS[on]:
            takes = [o for o, reads in READS.items() if k in reads]
            raise ConfigError(f'{who}.{k} is not read with on = "{on}" (it is with on = {takes}); leave it out')
    o = options
    if on == "contact":
        quadrature = o["quadrature"] or "overlap"
        return ContactForce(interfaces=o["interfaces"], quadrature=quadrature, direction=o["direction"], name=name)
    if on == "energy":
        return StrainEnergy(bodies=o["bodies"], name=name)
    body = _one_body(o["bodies"], who, on)
    if on == "reaction":
        return Reaction(body, set=o["set"], direction=o["direction"], name=name)
    for k in ("set", "direction"):
        if o[k] is None:
            raise ConfigError(f'{who}.{k} is needed with on = "displacement" (the node set and the direction it reads)')
    return MeanDisplacement(body, o["set"], o["direction"], name=name)


class PathResponse(Response):
    """Base of the load-path responses: the quantity ``on`` at the load factors ``t_k`` of ``steps`` (module
    docstring), combined by :meth:`combine` (a JAX-traceable function of the (n,) values)."""

    def __init__(
        self,
        steps: int | Sequence[float],
        interfaces=None,
        quadrature: str | None = None,
        direction=None,
        on: str = "contact",
        bodies=None,
        set: str | None = None,
        name: str = "",
    ):
        self.name = name or self.name
        who = type(self).__name__
        self._stops = checked_steps(steps, who)
        # as given: a count, or the load factors listed
        self.steps: int | tuple = int(steps) if isinstance(steps, (int, np.integer)) else self._stops
        self.on = on
        options = {"interfaces": interfaces, "quadrature": quadrature, "direction": direction}
        options.update(bodies=bodies, set=set)
        self.quantity = path_quantity(on, options, who, self.name)

    @property
    def stops(self) -> tuple:  # type: ignore[override]
        """The load factors ``t_k`` read: ``k / steps`` for a count, else the given list."""
        return self._stops

    def combine(self, forces):
        raise NotImplementedError

    def check(self, system) -> None:
        self.quantity.check(system)

    def indices(self, fields: Fields) -> list[int]:
        """The index in ``fields.path`` of each ``t_k``; ConfigError where the solve did not stop there."""
        times = np.array([s.t for s in fields.path])
        out = []
        for t in self.stops:
            hit = np.flatnonzero(np.abs(times - t) < 1e-9)
            if not hit.size:
                raise ConfigError(
                    f"response {self.name!r} reads the load step at t = {t:.6g}, but the solve has none there; solve "
                    "with solve_static(..., stops=response.stops, record_path=True)"
                )
            out.append(int(hit[-1]))
        return out

    def evaluate_path(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        self.check(fields.system)
        idx = self.indices(fields)
        results = [self.quantity.evaluate(Fields.from_state(fields.system, fields.path[k]), gradient) for k in idx]
        forces = jnp.asarray([v for v, _ in results], dtype=jnp.float64)
        value = float(self.combine(forces))
        if not gradient:
            return value, {}
        weights = np.asarray(jax.grad(self.combine)(forces))
        parts = [p for _, p in results if p is not None]  # each, evaluated with the gradient
        return value, {k: Partials.combine([p], [c]) for k, p, c in zip(idx, parts, weights)}

    def evaluate(self, fields: Fields, gradient: bool = True):
        if gradient:
            raise ConfigError(
                f"response {self.name!r} reads several load steps: its derivative comes from evaluate_path "
                "(sensitivities does that)"
            )
        return self.evaluate_path(fields, gradient=False)[0], None

    def values(self, fields: Fields) -> np.ndarray:
        """(n,) the quantity read at every ``t_k`` (for the pictures and the history)."""
        fields = as_fields(fields, self.name)
        return np.array(
            [self.quantity.value(Fields.from_state(fields.system, fields.path[k])) for k in self.indices(fields)]
        )


class ForceTarget(PathResponse):
    """``(1/n) sum_k (F_k - F*(t_k))^2`` over the n load factors read: the mean squared miss of a target
    force-displacement curve (or of the quantity ``on``'s curve)."""

    name = "force_target"

    def __init__(
        self,
        target,
        steps: int | Sequence[float],
        interfaces=None,
        quadrature: str | None = None,
        direction=None,
        on: str = "contact",
        bodies=None,
        set: str | None = None,
        name: str = "",
    ):
        super().__init__(steps, interfaces, quadrature, direction, on, bodies, set, name)
        self.target = checked_target(target, type(self).__name__)
        self.wanted = np.interp(np.array(self.stops), self.target[:, 0], self.target[:, 1])  # F*(t_k)

    def combine(self, forces):
        return jnp.mean((forces - self.wanted) ** 2)


class ForceMax(PathResponse):
    """The largest force (quantity ``on``) over the path, smoothly: ``(1/s) log((1/n) sum_k exp(s F_k))``."""

    name = "force_max"
    sign = 1.0

    def __init__(
        self,
        steps: int | Sequence[float],
        sharpness: float,
        interfaces=None,
        quadrature: str | None = None,
        direction=None,
        on: str = "contact",
        bodies=None,
        set: str | None = None,
        name: str = "",
    ):
        super().__init__(steps, interfaces, quadrature, direction, on, bodies, set, name)
        s = sharpness
        if isinstance(s, bool) or not isinstance(s, (int, float, np.floating)) or not (np.isfinite(s) and s > 0):
            raise ConfigError(
                f"{type(self).__name__}.sharpness must be a positive number (1/force, or 1/the unit of what on "
                f"reads), got {s!r}"
            )
        self.sharpness = float(s)

    def combine(self, forces):
        s = self.sign * self.sharpness
        return jax.scipy.special.logsumexp(s * forces, b=1.0 / forces.size) / s


class ForceMin(ForceMax):
    """The smallest force (quantity ``on``) over the path, smoothly: ``-(1/s) log((1/n) sum_k exp(-s F_k))``."""

    name = "force_min"
    sign = -1.0
