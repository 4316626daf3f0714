"""Sparse direct solvers for (symmetric, possibly indefinite) stiffness matrices.

One entry point, :func:`factorize`, returns a factorization object that solves
``K x = b`` for one or many right-hand sides and reuses the factor::

    factor = factorize(K, "auto")        # or LinearSolverOptions(backend=...)
    x = factor.solve(b)                  # b: (n,) or (n, k)
    factor.backend, factor.info, factor.seconds
    factor.free()                        # also done on garbage collection

Backends, in the order ``"auto"`` tries them:

``pardiso``  Intel MKL Pardiso through pypardiso. Symmetric matrices use
             ``mtype=-2`` (real symmetric indefinite, LDL^T with Bunch-Kaufman
             pivoting and pivot perturbation) on the upper triangle, so it
             handles definite and indefinite tangents alike and reports the
             inertia.
``cholmod``  CHOLMOD supernodal Cholesky (scikit-sparse, optional). Only for
             SPD matrices: on an indefinite one it falls back (to pardiso when
             available, else to CHOLMOD's unpivoted simplicial LDL^T, checked by
             a residual, else to scipy).
``petsc``    Not a factorization: conjugate gradients preconditioned with PETSc's
             smoothed-aggregation AMG (optional: ``pip install contopt[petsc]``, Python
             3.12+), for matrices too large to factor. Its solves take a tolerance
             (``solve(b, rtol)``); it needs the :class:`Geometry` of the rows
             (``factorize(K, options, geometry)``) to know the rigid-body modes.
``scipy``    SuperLU (``scipy.sparse.linalg.splu``): always there, partial
             pivoting, but much slower on 3D models, and the gap grows with size.

``"auto"`` tries pardiso first because it factored 3D elasticity fastest beyond a few
thousand dofs and pivots (indefinite tangents too), then cholmod, then scipy; from
``iterative_above`` rows on (and with a geometry) it takes petsc first. The timings and the
command that measures them: docs/performance.md ("Sparse direct solvers") and docs/scaling.md.

With ``factor_reuse`` (off by default) a direct backend's freed factor is kept, and the next
matrix on the same rows is first solved by GMRES preconditioned with it (its solves then take a
tolerance, and ``iterative`` is True); it is factored only when that does not converge in a few
iterations (:mod:`contopt.solve.linear.reuse`). ``free()`` then hands the factor over for the next
matrix instead of releasing it; :func:`release_kept_factor` releases it.

A singular matrix (empty row, unsupported rigid body) raises
:class:`contopt.errors.LinearSolverError`; it never segfaults and never returns
NaN silently.

The package: ``options`` (:class:`LinearSolverOptions` and the valid option values),
``base`` (the :class:`Factorization` protocol, the common ``Factor`` class, input checks,
the probe solve), one module per backend (``pardiso``, ``cholmod``, ``superlu``), and
here the dispatch. A backend (PETSc, say) plugs in as one more module with ``load()``
(raises ImportError or OSError when its library is missing) and
``factor(K, rows, opts)``, which returns a ``base.Factor`` subclass (``backend`` set,
``_solve`` and ``_release`` implemented) or raises ``base.Unsuitable``; then its name
goes into ``options.BACKENDS`` (where it stands there is its rank for ``"auto"``), its
``load`` and ``factor`` into ``_LOADERS`` and ``_METHODS`` below, and its fallbacks, if
any, into ``_method_chain``.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from dataclasses import replace

from contopt import extras
from contopt.errors import ConfigError, LinearSolverError, UnavailableSolverError
from contopt.solve.linear import choice, cholmod, pardiso, petsc, reuse, superlu
from contopt.solve.linear.base import (
    Factor,
    Factorization,
    Geometry,
    Unsuitable,
    as_canonical_csr,
    check_matrix,
    check_parts,
    logger,
    return_free_heap,
    row_indices,
    singular_error,
)

# Internals that tests/solve/test_linear.py inspects under their names of the single module
# (it also patches _is_available, _METHODS and _SCIPY_WARNED, which are defined here).
from contopt.solve.linear.base import upper_with_diagonal as _upper_with_diagonal  # noqa: F401
from contopt.solve.linear.options import BACKEND_CHOICES, BACKENDS, LinearSolverOptions
from contopt.solve.linear.pardiso import PARDISO_POOL as _PARDISO_POOL  # noqa: F401
from contopt.solve.linear.pardiso import PARDISO_POOL_SIZE, release_pardiso_pool
from contopt.timing import Stopwatch

__all__ = [
    "BACKENDS",
    "PARDISO_POOL_SIZE",
    "Factorization",
    "Geometry",
    "LinearSolverOptions",
    "available_backends",
    "factorize",
    "release_kept_factor",
    "release_pardiso_pool",
]

#: free the factor kept for the next matrix (``LinearSolverOptions.factor_reuse``)
release_kept_factor = reuse.release_kept

_INSTALL_HINT = (
    "Install a fast sparse solver: `pip install 'contopt[pardiso]'` (MKL Pardiso, fastest; x86-64) "
    "or `pip install 'contopt[cholmod]'` (CHOLMOD; needs libsuitesparse-dev); "
    "for the iterative solver `pip install 'contopt[petsc]'` (Python 3.12+)."
)

#: backend -> what loads its library (raises when it is not installed)
_LOADERS: dict[str, Callable[[], object]] = {
    "pardiso": pardiso.library,
    "cholmod": cholmod.load,
    "petsc": petsc.load,
    "scipy": superlu.load,
}


def _load(name: str) -> object:
    """Load backend ``name``'s library; MissingExtra when ``$CONTOPT_WITHOUT`` hides its extra."""
    if name in extras.EXTRAS and name in extras.hidden():
        raise extras.MissingExtra(extras.missing(name, f"the {name} backend needs"))
    try:
        return _LOADERS[name]()
    except ModuleNotFoundError as err:  # pypardiso, scikit-sparse, petsc4py: the extra is not installed
        raise extras.MissingExtra(extras.missing(name, f"the {name} backend needs") + f" ({err})") from err


@functools.cache
def _is_available(name: str) -> bool:
    if name not in _LOADERS:
        return False
    try:
        _load(name)
    except Exception as exc:  # ImportError, or OSError when mkl_rt is missing
        logger.debug("linear-solver backend %s unavailable: %s", name, exc)
        return False
    return True


def available_backends() -> list[str]:
    """Installed backends, fastest first (``scipy`` is always last and always there)."""
    return [name for name in BACKENDS if _is_available(name)]


def why_unavailable(name: str) -> str:
    """Why backend ``name`` cannot be loaded here ("" when it can)."""
    if name not in _LOADERS:
        return f"unknown backend {name!r}"
    try:
        _load(name)
    except Exception as exc:
        return str(exc) or type(exc).__name__
    return ""


_SCIPY_WARNED = False


def _factor_scipy(K, rows, opts) -> Factor:
    """SuperLU, saying once per process that a fast backend is missing."""
    global _SCIPY_WARNED
    if not _SCIPY_WARNED:
        _SCIPY_WARNED = True
        logger.warning(
            "Using scipy's SuperLU for sparse factorization: much slower than "
            "Pardiso/CHOLMOD on 3D models (measured ~3x at 4k dofs, 12-13x at "
            "26k dofs, and the gap grows with size). %s",
            _INSTALL_HINT,
        )
    return superlu.factor(K, rows, opts)


#: method -> factor(K, rows, opts); "cholmod_ldlt" is a fallback only
_METHODS = {
    "pardiso": pardiso.factor,
    "cholmod": cholmod.factor_llt,
    "cholmod_ldlt": cholmod.factor_ldlt,
    "scipy": _factor_scipy,
}


def _method_chain(
    opts: LinearSolverOptions, n: int, geometry: Geometry | None, trial: choice.Choice | None = None
) -> list[str]:
    """Methods to try in order: the chosen backend, then its fallbacks; ``trial``: what ``auto``
    measured on these dofs' contact tangents (:mod:`contopt.solve.linear.choice`)."""
    if geometry is not None and geometry.comm.distributed:
        # each rank holds a part of the matrix: only the distributed backend can add them up
        if opts.backend not in ("auto", "petsc") or not _is_available("petsc"):
            raise UnavailableSolverError(
                f"a distributed run ({geometry.comm.size} ranks) solves with the petsc backend only, not "
                f"{opts.backend!r}" + ("" if _is_available("petsc") else f" (petsc: {why_unavailable('petsc')})")
                + ": use --solver petsc (or auto)"
            )  # fmt: skip
        return ["petsc"]
    large = n >= opts.iterative_above and geometry is not None
    if trial is not None:
        # the AMG may fail on contact tangents (their constraints are no rigid-body modes; indefinite at
        # times) or win by its reuse: the trial decides
        large = trial.wants_amg
    # PETSc is loaded (0.2 s) only where it could be chosen
    wanted = opts.backend == "petsc" or (opts.backend == "auto" and large)
    avail = [
        b for b in BACKENDS
        if (opts.symmetric or b != "cholmod") and (b != "petsc" or wanted) and _is_available(b)
    ]  # fmt: skip
    if opts.backend == "auto":
        first = "petsc" if large and "petsc" in avail else next(b for b in avail if b != "petsc")
    else:
        if opts.backend not in avail:
            why = why_unavailable(opts.backend) if opts.backend in _LOADERS else ""
            raise UnavailableSolverError(
                f"linear-solver backend {opts.backend!r} is not available here"
                + (f" ({why})" if why else "")
                + f" (available: {', '.join(avail)}). {_INSTALL_HINT} Or use backend='auto'."
            )
        first = opts.backend
    chain = [first]
    if not (opts.backend == "auto" or opts.fallback):
        return chain
    if first == "cholmod":
        # Cholesky refuses indefinite matrices. Then: pardiso (pivoting, fast)
        # before CHOLMOD's unpivoted simplicial LDL^T (~10x slower than
        # supernodal, measured), before SuperLU.
        chain += [m for m in ("pardiso", "cholmod_ldlt", "scipy") if (m if m != "cholmod_ldlt" else "cholmod") in avail]
    elif first == "pardiso" and "cholmod" in avail:
        chain.append("cholmod")  # for what defeats Pardiso's static pivoting (see pardiso.factor)
    elif first == "petsc":
        chain += [b for b in avail if b not in ("petsc", "scipy")][:1] + ["scipy"]
    return chain


def _direct_fallback(K, opts: LinearSolverOptions) -> Callable[[], Factor]:
    """What an iterative solve that failed falls back to: a factorization of the same matrix."""

    def direct() -> Factor:
        chain = [b for b in available_backends() if b != "petsc" and (opts.symmetric or b != "cholmod")]
        backend = chain[0] if opts.fallback or opts.backend == "auto" else None
        if backend is None:
            raise LinearSolverError(
                "the Krylov solver (PETSc) did not converge and fallback=False: raise krylov_max_iter, or allow "
                "fallback=True"
            )
        return factorize(K, replace(opts, backend=backend))  # type: ignore[return-value]

    return direct


def _resolve_options(options) -> LinearSolverOptions:
    if options is None:
        return LinearSolverOptions()
    if isinstance(options, str):
        return LinearSolverOptions(backend=options)
    if isinstance(options, LinearSolverOptions):
        return options
    raise ConfigError(
        "linear solver options must be a backend name ("
        + ", ".join(repr(a) for a in BACKEND_CHOICES)
        + f") or LinearSolverOptions, got {type(options).__name__}"
    )


def factorize(K, options: LinearSolverOptions | str | None = None, geometry: Geometry | None = None) -> Factorization:
    """Factor the sparse matrix ``K`` (float64, shape (n, n)) for repeated solves.

    Parameters
    ----------
    K : scipy.sparse matrix or array, shape (n, n); symmetric unless
        ``options.symmetric`` is False. CSR avoids a conversion copy.
    options : :class:`LinearSolverOptions`, a backend name, or None (``"auto"``).
    geometry : where the rows sit (node positions, the dof of each row): the iterative backend
        builds the rigid-body modes from it; ``"auto"`` chooses it only when given.

    Returns
    -------
    A :class:`Factorization`: ``solve(b)`` for b of shape (n,) or (n, k),
    ``backend``, ``info``, ``seconds``, ``free()``.

    Raises
    ------
    LinearSolverError
        singular matrix (empty row, unsupported rigid-body mode), NaN/inf
        entries, a requested backend that is not installed, or a backend
        failure after all fallbacks.
    ConfigError
        invalid options.
    """
    clock = Stopwatch()
    opts = _resolve_options(options)
    K = as_canonical_csr(K)
    n = K.shape[0]
    if n == 0:
        raise LinearSolverError("empty (0 x 0) stiffness matrix: no free dofs")
    rows = row_indices(K)
    if geometry is not None and geometry.comm.distributed:
        check_parts(K, rows, geometry.comm)
    else:
        check_matrix(K, rows, opts)
    trial = choice.choice_for(opts, n, geometry, amg_available=lambda: _is_available("petsc"))
    queue = _method_chain(opts, n, geometry, trial)

    def refactor(double: bool = False) -> Factor:
        precise = replace(opts, factor_precision="double") if double else opts
        return _first_that_factors(K, rows, precise, geometry, list(queue), trial)

    keep = opts.factor_reuse and queue[0] != "petsc"
    kept = reuse.take(n, None if geometry is None else geometry.free) if keep else None
    if kept is None:
        reuse.release_kept()  # not reusing, or a factor for other rows: free it before this one's
        factor = refactor()
        if trial is not None and factor.backend != "petsc":
            trial.record_direct(clock.seconds)
        if not (keep or factor.approximate):
            factor.seconds = clock.seconds
            return factor
    else:
        factor = kept
    wrapped = reuse.Reusing(
        K, factor, kept is None, refactor, opts.factor_reuse_max_iter, opts.krylov_rtol,
        None if geometry is None else geometry.free, keep=keep,
    )  # fmt: skip
    wrapped.seconds = clock.seconds
    return wrapped


def _first_that_factors(
    K, rows, opts: LinearSolverOptions, geometry: Geometry | None, queue: list[str], trial: choice.Choice | None
) -> Factor:
    """The factor of the first method of ``queue`` that can make a trustworthy one (logged fallbacks);
    ``trial``: the AMG's record where ``auto`` is measuring it."""
    n = K.shape[0]
    clock = Stopwatch()
    return_free_heap()
    attempts: list[tuple[str, str]] = []
    singular = False
    while queue:
        method = queue.pop(0)
        try:
            if method == "petsc":
                direct = _direct_fallback(K, opts)
                factor = petsc.factor(K, rows, opts, geometry, direct, trial)
            else:
                factor = _METHODS[method](K, rows, opts)
        except Unsuitable as exc:
            attempts.append((method, str(exc)))
            if exc.singular:
                singular = True
                # Pivoting LU/LDL^T would say the same; only a Cholesky not
                # yet tried can still decide (it may be the SPD extreme case).
                queue = [m for m in queue if m == "cholmod"]
            if queue:
                # an indefinite tangent (contact, soft supports) is what CHOLMOD's LDL^T is there for:
                # said once per factorization it would flood a run's log
                expected = (method, queue[0]) == ("cholmod", "cholmod_ldlt")
                logger.log(
                    logging.DEBUG if expected else logging.WARNING,
                    "%s cannot factor this %dx%d matrix (%s); falling back to %s",
                    method,
                    n,
                    n,
                    exc,
                    queue[0],
                )
            continue
        if attempts:
            factor.info["fallback_from"] = attempts[0][0]
            factor.info["fallback_reason"] = attempts[0][1]
            factor.info["attempts"] = attempts
        factor.seconds = clock.seconds
        logger.debug("factorized %dx%d (nnz %d) with %s in %.3f s", n, n, K.nnz, factor.info["method"], factor.seconds)
        return factor
    tried = "; ".join(f"{m}: {r}" for m, r in attempts)
    if singular:
        raise singular_error(tried)
    if opts.backend != "auto" and not opts.fallback:
        raise LinearSolverError(
            f"{opts.backend} cannot factor this matrix ({tried}); allow "
            "fallback=True or choose backend='pardiso'/'scipy'"
        )
    raise LinearSolverError(f"no backend could factor the {n}x{n} matrix ({tried})")
