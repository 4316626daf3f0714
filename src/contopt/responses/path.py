"""Load-path responses: a force read at several load steps and combined into one number.

A load-path response reads the contact force ``F_k`` (:class:`ContactForce`, with its options) at
the load factors ``t_k = k / steps``, ``k = 1 .. steps``: with every condition and load scaled by
``t`` from the unloaded bodies, ``t_k`` is the share of the prescribed motion (or the load) at step
k, so ``(t_k, F_k)`` is the force-displacement curve. The solve must end a load step on every
``t_k`` (its :attr:`stops`; :func:`contopt.solve.static.solve_static` ``stops=``, with the path
recorded) and the adjoint runs back over those steps (:mod:`contopt.adjoint.path`), through the
friction history where there is one.

* :class:`ForceTarget`: ``sum_k w_k (F_k - F*(t_k))^2`` with ``w_k = 1 / steps`` (the mean squared
  miss, in force^2) and the target ``F*`` interpolated linearly between the given points ``(t, F)``;
* :class:`ForceMax`, :class:`ForceMin`: the largest or smallest ``F_k``, aggregated smoothly
  (Kreisselmeier-Steinhauser): ``(1/s) log((1/n) sum_k exp(s F_k))`` with ``s`` the ``sharpness``
  in 1/force, within ``log(n)/s`` below the largest value (``-s`` for the smallest, above it).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from contopt.errors import ConfigError
from contopt.responses.base import Fields, Partials, Response, as_fields


def checked_steps(steps, who: str) -> int:
    """``steps`` as a positive int; ConfigError naming the response class ``who`` otherwise."""
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ConfigError(f"{who}.steps must be a whole number of load steps >= 1, got {steps!r}")
    return int(steps)


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


class PathResponse(Response):
    """Base of the load-path responses: the contact force at ``t_k = k / steps`` (module docstring),
    combined by :meth:`combine` (a JAX-traceable function of the (steps,) forces)."""

    def __init__(self, steps: int, interfaces=None, quadrature: str = "overlap", direction=None, name: str = ""):
        from contopt.responses.functionals import ContactForce  # which maps the names to these classes

        self.name = name or self.name
        self.steps = checked_steps(steps, type(self).__name__)
        self.force = ContactForce(interfaces=interfaces, quadrature=quadrature, direction=direction, name=self.name)

    @property
    def stops(self) -> tuple:  # type: ignore[override]
        """(steps,) the load factors ``t_k`` read."""
        return tuple(k / self.steps for k in range(1, self.steps + 1))

    def combine(self, forces):
        raise NotImplementedError

    def check(self, system) -> None:
        self.force.check(system)

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
        results = [self.force.evaluate(Fields.from_state(fields.system, fields.path[k]), gradient) for k in idx]
        forces = jnp.asarray([v for v, _ in results], dtype=jnp.float64)
        value = float(self.combine(forces))
        if not gradient:
            return value, {}
        weights = np.asarray(jax.grad(self.combine)(forces))
        return value, {k: Partials.combine([p], [c]) for k, (_, p), c in zip(idx, results, weights)}

    def evaluate(self, fields: Fields, gradient: bool = True):
        if gradient:
            raise ConfigError(
                f"response {self.name!r} reads several load steps: its derivative comes from evaluate_path "
                "(sensitivities does that)"
            )
        return self.evaluate_path(fields, gradient=False)[0], None

    def forces(self, fields: Fields) -> np.ndarray:
        """(steps,) the force at every ``t_k`` (for the pictures and the history)."""
        fields = as_fields(fields, self.name)
        return np.array(
            [self.force.value(Fields.from_state(fields.system, fields.path[k])) for k in self.indices(fields)]
        )


class ForceTarget(PathResponse):
    """``(1/steps) sum_k (F_k - F*(t_k))^2``: the mean squared miss of a target force-displacement curve."""

    name = "force_target"

    def __init__(
        self, target, steps: int, interfaces=None, quadrature: str = "overlap", direction=None, name: str = ""
    ):
        super().__init__(steps, interfaces, quadrature, direction, name)
        self.target = checked_target(target, type(self).__name__)
        self.wanted = np.interp(np.array(self.stops), self.target[:, 0], self.target[:, 1])  # F*(t_k)

    def combine(self, forces):
        return jnp.mean((forces - self.wanted) ** 2)


class ForceMax(PathResponse):
    """The largest contact force over the path, smoothly: ``(1/s) log((1/n) sum_k exp(s F_k))``."""

    name = "force_max"
    sign = 1.0

    def __init__(
        self, steps: int, sharpness: float, interfaces=None, quadrature: str = "overlap", direction=None, name: str = ""
    ):
        super().__init__(steps, interfaces, quadrature, direction, name)
        s = sharpness
        if isinstance(s, bool) or not isinstance(s, (int, float, np.floating)) or not (np.isfinite(s) and s > 0):
            raise ConfigError(f"{type(self).__name__}.sharpness must be a positive number (1/force), got {s!r}")
        self.sharpness = float(s)

    def combine(self, forces):
        s = self.sign * self.sharpness
        return jax.scipy.special.logsumexp(s * forces, b=1.0 / forces.size) / s


class ForceMin(ForceMax):
    """The smallest contact force over the path, smoothly: ``-(1/s) log((1/n) sum_k exp(-s F_k))``."""

    name = "force_min"
    sign = -1.0
