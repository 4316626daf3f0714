"""Hyperelastic materials of the paper's appendix C: their parameters (a description, no JAX).

``W(F) = kappa/2 (ln J)^2 + A (I1bar - 3) + B (I2bar - 3)`` with the
isochoric invariants ``I1bar = J^(-2/3) tr C`` and
``I2bar = J^(-4/3) (tr(C)^2 - tr(C^2)) / 2``. Neo-Hookean is ``B = 0``. The
small-strain limit has shear modulus ``mu = 2 (A + B)`` and bulk modulus
``kappa`` (paper eq. C.7).

A material hands the analysis its energy ``W(I1, I2, J, params)``, a pure JAX function of the
invariants of ``F`` (the kernels of :mod:`contopt.material.energy`), and its parameter vector.
This module loads no JAX: a Model (and a problem file read into one) is built without it; the
energy's module is imported when the analysis first asks a material for its energy.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from contopt.errors import ConfigError


@runtime_checkable
class Material(Protocol):
    """What a body's material gives the analysis (a new material implements these five).

    energy : ``W(I1, I2, J, params)``, a pure JAX function of the invariants of F (module docstring);
        a module-level function, so that every body of that material type shares one compiled kernel
    params : (k,) float64 parameters handed to ``energy``
    youngs_modulus, poisson_ratio : small-strain constants (the contact laws' default penalty uses them)
    mass_density : per unit reference volume (acceleration loads)
    """

    @property
    def energy(self) -> Callable: ...

    @property
    def params(self) -> np.ndarray: ...

    @property
    def youngs_modulus(self) -> float: ...

    @property
    def poisson_ratio(self) -> float: ...

    @property
    def mass_density(self) -> float: ...


@dataclass(frozen=True)
class MooneyRivlin:
    """Compressible Mooney-Rivlin material with isochoric invariants (paper C.1-C.3).

    Use :meth:`from_E_nu` or :func:`neo_hookean` to build from engineering
    constants. ``mass_density`` (per unit reference volume) is used only by
    acceleration loads.
    """

    kappa: float
    A: float
    B: float = 0.0
    mass_density: float = 0.0

    def __post_init__(self):
        for name in ("kappa", "A", "B", "mass_density"):
            v = getattr(self, name)
            if not np.isfinite(v):
                raise ConfigError(f"material {name} must be finite, got {v}")
        if self.kappa <= 0:
            raise ConfigError(f"material bulk modulus kappa must be > 0, got {self.kappa}")
        if self.A < 0 or self.B < 0 or self.A + self.B <= 0:
            raise ConfigError(
                f"material needs A >= 0, B >= 0 and A + B > 0 (shear modulus 2(A+B) > 0), got A={self.A}, B={self.B}"
            )
        if self.mass_density < 0:
            raise ConfigError(f"material mass_density must be >= 0, got {self.mass_density}")

    @classmethod
    def from_E_nu(cls, E: float, nu: float, b_fraction: float = 0.0, mass_density: float = 0.0):
        """From Young's modulus and Poisson's ratio: ``mu = E/(2(1+nu))``, ``kappa = E/(3(1-2nu))``.

        ``b_fraction = B/(A+B)`` splits the shear modulus between the two
        Mooney-Rivlin terms (0 gives neo-Hookean).
        """
        if not (E > 0):
            raise ConfigError(f"Young's modulus E must be > 0, got {E}")
        if not (-1.0 < nu < 0.5):
            raise ConfigError(f"Poisson's ratio nu must lie in (-1, 0.5), got {nu}")
        if not (0.0 <= b_fraction <= 1.0):
            raise ConfigError(f"b_fraction = B/(A+B) must lie in [0, 1], got {b_fraction}")
        mu = E / (2.0 * (1.0 + nu))
        kappa = E / (3.0 * (1.0 - 2.0 * nu))
        half = 0.5 * mu
        return cls(kappa=kappa, A=half * (1.0 - b_fraction), B=half * b_fraction, mass_density=mass_density)

    @property
    def mu(self) -> float:
        """Small-strain shear modulus 2(A+B)."""
        return 2.0 * (self.A + self.B)

    @property
    def lame_lambda(self) -> float:
        return self.kappa - 2.0 / 3.0 * self.mu

    @property
    def youngs_modulus(self) -> float:
        return 9.0 * self.kappa * self.mu / (3.0 * self.kappa + self.mu)

    @property
    def poisson_ratio(self) -> float:
        return (3.0 * self.kappa - 2.0 * self.mu) / (2.0 * (3.0 * self.kappa + self.mu))

    @property
    def params(self) -> np.ndarray:
        """(3,) ``[kappa, A, B]`` handed to :func:`contopt.material.energy.mooney_rivlin_energy`."""
        return np.array([self.kappa, self.A, self.B], dtype=np.float64)

    @property
    def energy(self):
        """The energy function ``W(I1, I2, J, params)`` (module level: a stable jit key)."""
        from contopt.material.energy import mooney_rivlin_energy  # JAX: loaded by the analysis only

        return mooney_rivlin_energy

    def psi(self, F):
        """Energy density at a (3, 3) deformation gradient."""
        from contopt.material.energy import energy_of_F  # JAX: loaded by the analysis only

        return energy_of_F(self.energy, F, self.params)


def neo_hookean(E: float, nu: float, mass_density: float = 0.0) -> MooneyRivlin:
    """Neo-Hookean material (``B = 0``) from ``E`` and ``nu``, as in the paper's examples."""
    return MooneyRivlin.from_E_nu(E, nu, 0.0, mass_density)


def simp(nu, p: float = 3.0, nu0: float = 1e-2):
    """Ersatz-material SIMP stiffness factor ``rho_tilde = (1 - nu0) nu^p + nu0``."""
    return (1.0 - nu0) * nu**p + nu0
