"""The options of :func:`contopt.solve.linear.factorize` and their valid values, declared once.

The command line and the problem-file reader import these tuples instead of repeating the names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from contopt.errors import ConfigError

#: Backends in order of preference for ``backend="auto"`` (see the package docstring); ``petsc``
#: (iterative) is chosen first only from :attr:`LinearSolverOptions.iterative_above` dofs on.
BACKENDS: tuple[str, ...] = ("pardiso", "cholmod", "petsc", "scipy")
#: The backends that solve iteratively (a Krylov method): their solves take a tolerance.
ITERATIVE: tuple[str, ...] = ("petsc",)
#: Valid values of :attr:`LinearSolverOptions.backend`.
BACKEND_CHOICES: tuple[str, ...] = ("auto",) + BACKENDS
#: Valid values of :attr:`LinearSolverOptions.pardiso_matrix_type`, with Pardiso's ``mtype``.
PARDISO_MATRIX_TYPES: dict[str, int] = {"symmetric_indefinite": -2, "general": 11}
#: Valid values of :attr:`LinearSolverOptions.singular_check`.
SINGULAR_CHECKS: tuple[str, ...] = ("auto", "always", "never")
#: Valid values of :attr:`LinearSolverOptions.factor_precision`.
FACTOR_PRECISIONS: tuple[str, ...] = ("double", "single")
#: Valid values of :attr:`LinearSolverOptions.pardiso_scaling`.
PARDISO_SCALINGS: tuple[str, ...] = ("always", "retry")
#: Valid values of :attr:`LinearSolverOptions.forcing` (the Krylov tolerance of a Newton iteration).
FORCINGS: tuple[str, ...] = ("eisenstat-walker", "fixed")
#: Valid values of :attr:`LinearSolverOptions.preconditioner`.
PRECONDITIONERS: tuple[str, ...] = ("gamg", "mumps")
#: Valid values of :attr:`LinearSolverOptions.unsymmetric_krylov`.
UNSYMMETRIC_KRYLOVS: tuple[str, ...] = ("gmres", "bicgstab")


@dataclass(frozen=True)
class LinearSolverOptions:
    """How :func:`factorize` factors a stiffness matrix.

    Attributes
    ----------
    backend : ``"auto"`` (a direct solver below ``iterative_above`` free dofs, the iterative
        one from there on when it is installed), ``"pardiso"``, ``"cholmod"``, ``"petsc"``
        (conjugate gradients preconditioned with smoothed-aggregation AMG, PETSc's GAMG) or
        ``"scipy"``.
    symmetric : the matrix is symmetric (stiffness matrices always are). Only the
        upper (pardiso) or lower (cholmod) triangle is then read. ``False``
        excludes cholmod and makes pardiso use ``mtype=11``.
    pardiso_matrix_type : ``"symmetric_indefinite"`` (mtype -2, upper triangle,
        LDL^T; the measured faster one) or ``"general"`` (mtype 11, full
        matrix, LU). Ignored unless ``symmetric``; non-symmetric is always 11.
    pardiso_scaling : ``"always"`` factor with Pardiso's symmetric scaling and
        weighted matching (iparm 11 and 13), or ``"retry"`` only refactor with
        them when pivots were perturbed and a probe solve is inaccurate. Without
        them a high-contrast matrix (SIMP voids with E_min = 1e-9 E) has
        pivots below Pardiso's 1e-8 perturbation threshold and the plain
        factor is wrong. They cost about 10 % on well-scaled matrices, a retry
        costs a second factorization (docs/performance.md); hence ``"always"``.
    fallback : on a matrix the chosen backend cannot factor try the others
        instead of raising (cholmod on an indefinite matrix -> pardiso, else
        CHOLMOD LDL^T, else scipy; pardiso defeated by extreme stiffness
        contrast -> cholmod); said in the log (warning) and in
        ``factor.info["fallback_from"]``. ``"auto"`` always falls back.
    singular_check : ``"auto"`` runs one probe solve with a fixed random
        right-hand side only when the factorization hints at singularity
        (perturbed pardiso pivots, tiny Cholesky pivots, unpivoted LDL^T,
        SuperLU), ``"always"`` after every factorization, ``"never"`` skips it
        (solutions are still checked for NaN/inf).
    singular_rtol : the probe's ``||K x - b|| / ||b||`` above which the factor is
        not trusted (see ``contopt.solve.linear.base.probe`` for the measured
        range of both sides).
    check_symmetry : verify ``K == K.T`` (one O(nnz) transpose) when
        ``symmetric``; off by default because assemblers build symmetric
        matrices by construction.
    pardiso_reuse : keep a freed Pardiso factor's analysis (fill-reducing
        ordering, symbolic factorization, scaling) and reuse it for the next
        matrix with the same sparsity pattern, which then costs only the
        numeric factorization. Newton iterations, load steps, the adjoint and
        every design of an optimization share one pattern (without contact, or
        while the contact pairs stay). On 3D elasticity the analysis is more
        than half of a factorization (docs/performance.md). One freed factor is
        kept (its memory too).
    iterative_above : with ``backend="auto"``, matrices with at least this many rows are solved
        iteratively (``petsc``) when it is installed; below, by the fastest direct solver. One
        cold solve of the die-slab's first tangent (``benchmarks/scaling.py --one-solve``):
        44k free dofs Pardiso 1.4 s, CG + GAMG 2.2 s; 336k dofs 39.9 s / 5.9 GB against
        13.6 s / 3.0 GB; the power laws through them cross near 80k (docs/scaling.md).
    trial_above : with ``backend="auto"``, a contact tangent with at least this many rows whose
        direct factor fits in memory is solved by whichever of the direct factor and the AMG its
        first matrices measure as faster (:mod:`contopt.solve.linear.choice`): on the fine
        die-slab the AMG, on the fine Hertz line mesh the factor. Below it, and without the AMG
        installed, the direct solver (docs/scaling.md).
    krylov_rtol : relative residual ``||K x - b|| / ||b||`` at which an iterative solve stops when
        the caller asks for no other (the adjoint, a solve outside Newton); Newton asks for less
        while far from equilibrium (``forcing``) and never less accurate than this near it.
    krylov_max_iter : iterations of one iterative solve before it counts as failed (then a kept
        preconditioner is rebuilt and the solve retried, then a factorization solves). GAMG-CG
        needs 10-40 on the die-slab; a solve that needs hundreds costs more than a factorization
        (the paper-size sabot at the full load spent up to 3 x 1,000 before falling back).
    forcing : ``"eisenstat-walker"``: an iterative solve in Newton iteration k stops at
        ``eta_k ||r_k||`` with ``eta_k = 0.9 (||r_k|| / ||r_{k-1}||)^2``, or tighter where the last
        step's linear model predicted its residual well (safeguarded, at most ``krylov_eta_max``,
        and no tighter than what reaches Newton's tolerance; :mod:`contopt.solve.forcing`), so
        early iterations are cheap; ``"fixed"``: always ``krylov_rtol``. Direct solvers ignore it.
    krylov_eta_max : the loosest tolerance of a Newton iteration's solve. With contact a Newton
        iteration (kernels, mortar integrals, the check) costs as much as tens of Krylov
        iterations, and a loose solve costs Newton iterations: on the coarse die-slab 0.1 took
        36 Newton iterations, 1e-2 39, 1e-3 32, 1e-4 25 (as many as the direct solver) for 235
        Krylov iterations in all, 1e-6 25 for 470 (docs/scaling.md).
    preconditioner : ``"gamg"``: PETSc's smoothed-aggregation AMG with the rigid-body modes of
        the bodies as near-null space, block size 3, SOR smoothers and aggregation threshold
        ``amg_threshold`` (Chebyshev/Jacobi smoothers diverge at the stiffness contrast of
        black-and-white designs, docs/scaling.md); ``"mumps"``: GMRES preconditioned with MUMPS's
        LDL^T factorization of an earlier tangent, kept while it needs few iterations (indefinite
        tangents, and any number of ranks). A ``"gamg"`` run switches to it, and stays with it,
        when the AMG fails (docs/scaling.md).
    unsymmetric_krylov : the Krylov method of the ``petsc`` backend on an unsymmetric matrix
        (``symmetric=False``: the tangent of frictional contact): ``"gmres"`` (restarted, cut short
        when its rate says it will fail) or ``"bicgstab"``. GAMG aggregates on the symmetrized graph
        (PETSc's default), and the factorization it switches to is MUMPS's LU.
    amg_threshold : GAMG's drop tolerance for weak couplings while aggregating.
    preconditioner_reuse : keep the preconditioner for the next matrix of the same pattern (Newton
        iterations, multiplier updates, the adjoint) and rebuild it only when the iterations grow to
        ``reuse_growth`` times those right after it was built, or a solve fails.
    reuse_growth : see ``preconditioner_reuse``.
    factor_reuse : a direct backend keeps its last factor and, for the next matrix on the same
        rows, first tries GMRES preconditioned with it (to Newton's forcing tolerance, in at most
        ``factor_reuse_max_iter`` iterations), factoring only when that fails
        (:mod:`contopt.solve.linear.reuse`). Newton iterations near convergence and multiplier
        updates then cost a few triangular solves instead of a factorization: the fine die-slab
        forward in 0.78x the wall, the paper-size sabot's first analysis in 0.70x, for 7-17 %
        more memory. Off by default: Newton becomes inexact (it stops at its tolerance without
        the margin exact steps give), and multiplier updates held to tight tolerances can stall
        (the Hertz test at ``pressure_rtol = 1e-8``; docs/performance.md).
    factor_reuse_max_iter : see ``factor_reuse``.
    factor_precision : ``"double"``, or ``"single"``: Pardiso factors in float32 (half the factor's
        memory, 1.0 against 1.7 GB on the paper-size sabot, and 0.7x its time) and every solve is
        GMRES in float64 preconditioned with that factor, to the caller's tolerance (Newton's
        forcing term, else ``krylov_rtol``; at most ``factor_reuse_max_iter`` iterations): the
        answers are float64's. A matrix the single factor does not solve that way, or whose
        factorization perturbed pivots, is factored again in double. Other backends ignore it.
    """

    backend: str = "auto"
    symmetric: bool = True
    pardiso_matrix_type: str = "symmetric_indefinite"
    pardiso_scaling: str = "always"
    fallback: bool = True
    singular_check: str = "auto"
    singular_rtol: float = 1e-4
    check_symmetry: bool = False
    pardiso_reuse: bool = True
    iterative_above: int = 100_000
    trial_above: int = 30_000
    krylov_rtol: float = 1e-10
    krylov_max_iter: int = 300
    forcing: str = "eisenstat-walker"
    krylov_eta_max: float = 1e-4
    preconditioner: str = "gamg"
    amg_threshold: float = 0.02
    preconditioner_reuse: bool = True
    reuse_growth: float = 2.0
    factor_reuse: bool = False
    factor_reuse_max_iter: int = 8
    factor_precision: str = "double"
    unsymmetric_krylov: str = "gmres"

    @property
    def iterative(self) -> bool:
        """The chosen backend is iterative (``"auto"`` decides per matrix: False here)."""
        return self.backend in ITERATIVE

    def __post_init__(self):
        _check_choice("backend", self.backend, BACKEND_CHOICES)
        _check_choice("pardiso_matrix_type", self.pardiso_matrix_type, tuple(PARDISO_MATRIX_TYPES))
        _check_choice("singular_check", self.singular_check, SINGULAR_CHECKS)
        _check_choice("pardiso_scaling", self.pardiso_scaling, PARDISO_SCALINGS)
        _check_choice("factor_precision", self.factor_precision, FACTOR_PRECISIONS)
        _check_choice("forcing", self.forcing, FORCINGS)
        _check_choice("preconditioner", self.preconditioner, PRECONDITIONERS)
        _check_choice("unsymmetric_krylov", self.unsymmetric_krylov, UNSYMMETRIC_KRYLOVS)
        for key in ("symmetric", "fallback", "check_symmetry", "pardiso_reuse", "preconditioner_reuse", "factor_reuse"):
            if not isinstance(getattr(self, key), (bool, np.bool_)):
                raise ConfigError(f"LinearSolverOptions.{key} must be True or False, got {getattr(self, key)!r}")
        rtol = self.singular_rtol
        if not (isinstance(rtol, (int, float)) and 0.0 < float(rtol) < 1.0):
            raise ConfigError(f"LinearSolverOptions.singular_rtol must be a number in (0, 1), got {rtol!r}")
        _check_number("krylov_rtol", self.krylov_rtol, 0.0, 1.0)
        _check_number("krylov_eta_max", self.krylov_eta_max, 0.0, 1.0)
        _check_number("amg_threshold", self.amg_threshold, -1.0, 1.0, low_open=False)
        _check_number("reuse_growth", self.reuse_growth, 1.0, float("inf"), low_open=False)
        for key in ("iterative_above", "trial_above", "krylov_max_iter", "factor_reuse_max_iter"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ConfigError(f"LinearSolverOptions.{key} must be a positive integer, got {value!r}")
        if self.backend == "cholmod" and not self.symmetric:
            raise ConfigError(
                "LinearSolverOptions.backend='cholmod' needs symmetric=True "
                "(Cholesky); use 'pardiso', 'scipy' or 'auto' for a "
                "non-symmetric matrix"
            )


def _check_number(key: str, value: Any, low: float, high: float, low_open: bool = True) -> None:
    ok = isinstance(value, (int, float, np.floating)) and not isinstance(value, bool)
    ok = ok and (low < float(value) if low_open else low <= float(value)) and float(value) < high
    if not ok:
        bracket = "(" if low_open else "["
        raise ConfigError(f"LinearSolverOptions.{key} must be a number in {bracket}{low:g}, {high:g}), got {value!r}")


def _check_choice(key: str, value: Any, allowed: tuple[str, ...]) -> None:
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(f"LinearSolverOptions.{key}={value!r} is not one of " + ", ".join(repr(a) for a in allowed))
