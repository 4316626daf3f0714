"""The adjoint's options (:class:`AdjointOptions`), apart from the solver that imports JAX: reading
a problem file about them (``contopt schema``, ``contopt explain``) loads none."""

from __future__ import annotations

from dataclasses import dataclass

from contopt.errors import ConfigError

#: how the adjoint saddle point is solved
METHODS = ("schur-cg", "uzawa", "direct")


@dataclass(frozen=True)
class AdjointOptions:
    """How the adjoint saddle point is solved (:mod:`contopt.adjoint.saddle`).

    method : ``"schur-cg"`` (conjugate gradients on the Schur complement of the contact rows),
        ``"uzawa"`` or ``"direct"`` (one factorization of the whole saddle-point matrix)
    rtol : converged when ``|G w + dtheta/dlam| <= rtol * scale`` with ``scale`` the
        larger of ``|dtheta/dlam|`` and ``|G K^-1 dtheta/du|`` (the constraint
        residual of the unconstrained adjoint)
    max_iter : iterations of ``schur-cg`` / ``uzawa`` before giving up
    """

    method: str = "schur-cg"
    rtol: float = 1e-10
    max_iter: int = 200

    def __post_init__(self):
        if self.method not in METHODS:
            raise ConfigError(f"adjoint.method must be one of {METHODS}, got {self.method!r}")
        if not (0 < self.rtol < 1):
            raise ConfigError(f"adjoint.rtol must lie in (0, 1), got {self.rtol!r}")
        if not isinstance(self.max_iter, int) or self.max_iter < 1:
            raise ConfigError(f"adjoint.max_iter must be a positive integer, got {self.max_iter!r}")
