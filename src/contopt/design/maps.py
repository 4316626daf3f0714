"""Pointwise design maps as forward/vjp pairs (paper eqs. 35, 36, 46).

Each map acts entry by entry on arrays of shape (k,); ``vjp(a, bar)`` returns
``bar * d(forward)/da`` evaluated at the same input ``a``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.errors import ConfigError
from contopt.material.hyperelastic import simp


def _positive(owner: str, key: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{owner}.{key} must be a number > 0, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise ConfigError(f"{owner}.{key} must be a number > 0, got {value!r}")
    return v


@dataclass(frozen=True)
class Heaviside:
    """Smoothed Heaviside ``nu = 1/2 + 1/2 tanh(eta (phi - threshold))`` (eq. 35): level set -> volume fraction.

    ``threshold`` (0 in the paper) is where ``nu = 1/2``, in the units of ``phi``; the robust
    formulation's eroded and dilated designs (:class:`Robust`) shift it.
    """

    eta: float = 10.0
    threshold: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "eta", _positive("heaviside", "eta", self.eta))
        t = self.threshold
        if not isinstance(t, (int, float)) or not np.isfinite(t):
            raise ConfigError(f"heaviside.threshold must be a finite number, got {t!r}")
        object.__setattr__(self, "threshold", float(t))

    def forward(self, phi: np.ndarray) -> np.ndarray:
        return 0.5 + 0.5 * np.tanh(self.eta * (np.asarray(phi, dtype=np.float64) - self.threshold))

    def vjp(self, phi: np.ndarray, nu_bar: np.ndarray) -> np.ndarray:
        # d/dphi = eta/2 (1 - tanh^2): written with tanh, not 1/cosh^2, which overflows for large eta phi
        th = np.tanh(self.eta * (np.asarray(phi, dtype=np.float64) - self.threshold))
        return nu_bar * 0.5 * self.eta * (1.0 - th * th)

    def inverse(self, nu: float) -> float:
        """The level set whose volume fraction is ``nu`` in (0, 1): ``threshold + ln(nu/(1-nu)) / (2 eta)``."""
        if not 0.0 < nu < 1.0:
            raise ConfigError(f"a volume fraction for the initial design must lie in (0, 1), got {nu!r}")
        return float(self.threshold + np.log(nu / (1.0 - nu)) / (2.0 * self.eta))


@dataclass(frozen=True)
class EtaContinuation:
    """A continuation of the Heaviside sharpness within one optimization run.

    The run starts at ``eta = start`` and multiplies it by ``factor`` after every ``every``
    iterations, or as soon as the optimizer converges at the current sharpness, until it reaches the
    design's ``eta`` (the last step is capped there); the final sharpness runs to the end.

    start : the first sharpness, > 0 and below the design's eta
    factor : the sharpness' growth per step, > 1
    every : iterations at each sharpness before it is raised, an integer >= 1
    """

    start: float = 4.0
    factor: float = 1.5
    every: int = 20

    def __post_init__(self):
        object.__setattr__(self, "start", _positive("eta_continuation", "start", self.start))
        f = self.factor
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not np.isfinite(f) or f <= 1.0:
            raise ConfigError(
                f"eta_continuation.factor must be a number > 1 (the sharpness' growth per step), got {f!r}"
            )
        object.__setattr__(self, "factor", float(f))
        n = self.every
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ConfigError(f"eta_continuation.every must be an integer >= 1 (iterations per sharpness), got {n!r}")
        object.__setattr__(self, "every", int(n))

    def etas(self, eta: float) -> tuple[float, ...]:
        """The sharpnesses in order, up to the design's ``eta`` (the last one), e.g. 4, 6, 9, 10 for 10."""
        if not self.start < eta:
            raise ConfigError(
                f"eta_continuation.start ({self.start:g}) must be below the design's eta ({eta:g}), where the "
                "continuation ends: lower start or raise eta"
            )
        out = [self.start]
        while out[-1] * self.factor < eta * (1.0 - 1e-12):
            out.append(out[-1] * self.factor)
        return (*out, float(eta))


#: the robust formulation's three designs, in the order of their analyses
REALIZATIONS = ("eroded", "intermediate", "dilated")


@dataclass(frozen=True)
class Robust:
    """The robust formulation (Wang, Lazarov & Sigmund 2011) for density designs.

    The filtered density ``(1 + phi) / 2`` (in [0, 1]) is projected three times, with the
    Heaviside's threshold at ``1/2 + delta`` (eroded), ``1/2`` (intermediate, the design that is
    made) and ``1/2 - delta`` (dilated); the optimization takes the worst of the three objectives.
    In the units of ``phi`` (in [-1, 1]) the thresholds are ``2 delta``, 0 and ``-2 delta``.

    delta : the threshold's shift, in (0, 0.5)
    """

    delta: float = 0.15

    def __post_init__(self):
        d = self.delta
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not 0.0 < d < 0.5:
            raise ConfigError(f"robust.delta must be a number in (0, 0.5) (the threshold's shift), got {d!r}")
        object.__setattr__(self, "delta", float(d))

    def threshold(self, realization: str) -> float:
        """The Heaviside threshold of one realization, in the units of ``phi``."""
        if realization not in REALIZATIONS:
            raise ConfigError(f"a robust realization is one of {REALIZATIONS}, got {realization!r}")
        return {"eroded": 2.0 * self.delta, "intermediate": 0.0, "dilated": -2.0 * self.delta}[realization]


@dataclass(frozen=True)
class Simp:
    """Ersatz SIMP ``rho = (1 - nu0) nu^p + nu0`` (eq. 36): volume fraction -> stiffness factor."""

    p: float = 3.0
    nu0: float = 1e-2

    def __post_init__(self):
        object.__setattr__(self, "p", _positive("simp", "p", self.p))
        if not 0.0 < float(self.nu0) < 1.0:
            raise ConfigError(f"simp.nu0 must lie in (0, 1), got {self.nu0!r}")
        object.__setattr__(self, "nu0", float(self.nu0))

    def forward(self, nu: np.ndarray) -> np.ndarray:
        return simp(np.asarray(nu, dtype=np.float64), self.p, self.nu0)

    def vjp(self, nu: np.ndarray, rho_bar: np.ndarray) -> np.ndarray:
        nu = np.asarray(nu, dtype=np.float64)
        return rho_bar * (1.0 - self.nu0) * self.p * nu ** (self.p - 1.0)


def r_union(a: np.ndarray, b: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """Smooth union (R-function disjunction) of level sets, eq. 46.

    ``(a + b + sqrt((a-b)^2 + eps) - sqrt(eps)) / 2``: positive where ``a > 0``
    or ``b > 0``, differentiable everywhere for ``eps > 0``.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return 0.5 * (a + b + np.sqrt((a - b) ** 2 + eps) - np.sqrt(eps))


def r_union_partials(a: np.ndarray, b: np.ndarray, eps: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """``(d/da, d/db)`` of :func:`r_union`, entry by entry."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    s = (a - b) / np.sqrt((a - b) ** 2 + eps)
    return 0.5 * (1.0 + s), 0.5 * (1.0 - s)
