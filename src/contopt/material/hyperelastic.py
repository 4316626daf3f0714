"""Hyperelastic energies of the paper's appendix C, as functions of invariants.

``W(F) = kappa/2 (ln J)^2 + A (I1bar - 3) + B (I2bar - 3)`` with the
isochoric invariants ``I1bar = J^(-2/3) tr C`` and
``I2bar = J^(-4/3) (tr(C)^2 - tr(C^2)) / 2``. Neo-Hookean is ``B = 0``. The
small-strain limit has shear modulus ``mu = 2 (A + B)`` and bulk modulus
``kappa`` (paper eq. C.7).

An energy is a pure JAX function ``W(I1, I2, J, params)`` of the invariants
of ``F`` (``I1 = tr C``, ``I2 = (tr(C)^2 - tr(C^2))/2``, ``J = det F``) and a
parameter vector, so that one compiled kernel serves every body of the same
material type. Any isotropic hyperelastic law fits this form. The element
kernels differentiate ``W`` by AD with respect to the three scalars and
chain to ``F`` with closed-form invariant derivatives, which is exact and
an order of magnitude faster under XLA than AD of ``psi(F)`` directly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import jax.numpy as jnp
import numpy as np

from contopt.errors import ConfigError


def mooney_rivlin_energy(I1, I2, J, params):
    """Strain energy density per unit reference volume from the invariants of F.

    Parameters
    ----------
    I1, I2, J : scalars ``tr C``, ``(tr(C)^2 - tr(C^2))/2`` and ``det F``
        (J must be positive; J <= 0 gives NaN)
    params : (3,) ``[kappa, A, B]``
    """
    kappa, A, B = params[0], params[1], params[2]
    lnJ = jnp.log(J)
    I1bar = jnp.exp(-2.0 / 3.0 * lnJ) * I1
    I2bar = jnp.exp(-4.0 / 3.0 * lnJ) * I2
    return 0.5 * kappa * lnJ**2 + A * (I1bar - 3.0) + B * (I2bar - 3.0)


def invariants(F):
    """(I1, I2, J) of a (3, 3) deformation gradient: ``tr C``, ``(tr(C)^2 - tr(C^2))/2``, ``det F``."""
    C = F.T @ F
    I1 = jnp.trace(C)
    I2 = 0.5 * (I1**2 - jnp.sum(C * C))
    J = (
        F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
        - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
        + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
    )
    return I1, I2, J


def energy_of_F(energy, F, params):
    """psi(F) = W(I1(F), I2(F), J(F)) for an invariant-based energy ``W``."""
    return energy(*invariants(F), params)


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
        """(3,) ``[kappa, A, B]`` handed to :func:`mooney_rivlin_energy`."""
        return np.array([self.kappa, self.A, self.B], dtype=np.float64)

    @property
    def energy(self):
        """The energy function ``W(I1, I2, J, params)`` (module level: a stable jit key)."""
        return mooney_rivlin_energy

    def psi(self, F):
        """Energy density at a (3, 3) deformation gradient."""
        return energy_of_F(mooney_rivlin_energy, F, jnp.asarray(self.params))


def neo_hookean(E: float, nu: float, mass_density: float = 0.0) -> MooneyRivlin:
    """Neo-Hookean material (``B = 0``) from ``E`` and ``nu``, as in the paper's examples."""
    return MooneyRivlin.from_E_nu(E, nu, 0.0, mass_density)


def simp(nu, p: float = 3.0, nu0: float = 1e-2):
    """Ersatz-material SIMP stiffness factor ``rho_tilde = (1 - nu0) nu^p + nu0``."""
    return (1.0 - nu0) * nu**p + nu0
