"""Explicit, idempotent JAX set-up for entry points (CLI, tests, benchmarks), and the process's
address-space limit (``ulimit -v``), which the memory check and the command line's messages read.

Each function imports JAX itself: the entry points import this module before they know whether
the command at hand needs JAX at all (a problem file read into its Model, `contopt --help`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from types import ModuleType

resource: ModuleType | None  # None where the platform has none (Windows): no address-space limit
try:  # now, not when the limit is asked for: under `ulimit -v` a late import may fail for want of memory
    import resource
except ImportError:  # pragma: no cover - not POSIX
    resource = None


def enable_x64() -> None:
    """Switch JAX to float64. Called by entry points, never at import time."""
    import jax

    jax.config.update("jax_enable_x64", True)


def enable_compilation_cache(cache_dir: str | os.PathLike | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache so repeated runs do not recompile.

    The directory defaults to ``$CONTOPT_JAX_CACHE`` or ``~/.cache/contopt/jax``. Returns it, or
    None when it cannot be used: a path that cannot be created or written (a file, no
    permission) is no error, since the cache only saves compile time and a run does not need it.
    A one-line warning (logger ``contopt.config``) names the path and the reason, and the run
    goes on without the cache (JAX compiles in every process).
    """
    import jax

    path = Path(cache_dir or os.environ.get("CONTOPT_JAX_CACHE") or Path.home() / ".cache" / "contopt" / "jax")
    try:
        path.mkdir(parents=True, exist_ok=True)
        # mkdir accepts an existing directory it cannot write into; JAX would fail on each write
        if not os.access(path, os.W_OK | os.X_OK):
            raise PermissionError("not writable")
    except OSError as err:
        reason = "a file, not a directory" if path.is_file() else err.strerror or str(err)
        logging.getLogger(__name__).warning(
            "JAX compilation cache off: cannot use %s as its directory (%s); set CONTOPT_JAX_CACHE "
            "to a writable directory",
            path,
            reason,
        )
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    return path


def cache_entries() -> int | None:
    """Files in JAX's persistent compilation cache, or None when it is off (to tell a compile from a load)."""
    import jax

    # a dynamic attribute of jax.config (its type declares no options); config.read() refuses
    # options that also have a context manager, as this one does
    where = getattr(jax.config, "jax_compilation_cache_dir")  # noqa: B009 (mypy: see above)
    if not where or not Path(where).is_dir():
        return None
    return sum(1 for _ in Path(where).iterdir())


#: the address space JAX, its compiler's threads and the linear solvers' libraries need to start: the
#: tiny cantilever started under `ulimit -v` 2.3 GB and failed under 2.0 GB (oneMKL could not map its
#: threading library; under 1 GB XLA could not start its threads) on a 2-core machine; more cores, more threads
JAX_ADDRESS_SPACE = 3 * 2**30


def setup_jax(cache: bool = True) -> None:
    """What every entry point calls first: float64, (optionally) the compile cache, and glibc's malloc
    arenas capped (:func:`limit_malloc_arenas`).

    Warns (one line) when ``ulimit -v`` leaves less than :data:`JAX_ADDRESS_SPACE`: below it a native
    library may end the process with its own message, which Python cannot catch.
    """
    limit = address_space_limit()
    if limit is not None and limit < JAX_ADDRESS_SPACE:
        logging.getLogger(__name__).warning(
            "the address-space limit (ulimit -v) of %s is below the %s that JAX and the solvers' libraries "
            "need to start on a small machine; should contopt end in a native library's error "
            "(pthread_create, bad_alloc, oneMKL), raise the limit",
            format_gib(limit),
            format_gib(JAX_ADDRESS_SPACE),
        )
    limit_malloc_arenas()
    enable_x64()
    if cache:
        enable_compilation_cache()


#: glibc's malloc arenas for the threads that allocate (:func:`limit_malloc_arenas`); glibc's own cap is
#: 8 per core, an arena per thread (XLA's, MKL's and OpenBLAS's pools), each keeping the pages freed in it
MALLOC_ARENAS = 2
_M_ARENA_MAX = -8  # mallopt's parameter number (malloc.h)


def limit_malloc_arenas(arenas: int = MALLOC_ARENAS) -> bool:
    """Cap glibc's malloc arenas at ``arenas`` for the threads that take one from now on (call it before
    JAX starts its thread pools: :func:`setup_jax` does). Each arena keeps the pages freed in it resident
    until trimmed, beside the others': with glibc's default the Hertz line at Kratos' size peaked 40 MB
    higher at the same wall (docs/performance.md). Returns whether the cap was set: not where
    ``MALLOC_ARENA_MAX`` is in the environment (glibc took it at start), nor without glibc's ``mallopt``."""
    if os.environ.get("MALLOC_ARENA_MAX"):
        return False
    try:
        import ctypes

        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        return False
    return bool(mallopt(_M_ARENA_MAX, int(arenas)))


def address_space_limit() -> int | None:
    """The soft limit on this process's address space in bytes (``ulimit -v``, RLIMIT_AS), None if unlimited."""
    if resource is None:  # pragma: no cover - not POSIX
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY or soft <= 0 else int(soft)


def address_space_left() -> int | None:
    """Bytes of address space this process may still map under :func:`address_space_limit` (the limit
    less what is mapped now, from ``/proc/self/statm``; the whole limit where that cannot be read), or
    None without a limit."""
    limit = address_space_limit()
    if limit is None:
        return None
    try:
        with open("/proc/self/statm") as fh:
            mapped = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        mapped = 0
    return max(limit - mapped, 0)


def format_gib(n: float) -> str:
    """``2.86 GiB``, ``391 MiB``: a memory size for a message (no numpy: said where numpy may not load)."""
    return f"{n / 2**30:.3g} GiB" if n >= 2**30 else f"{n / 2**20:.3g} MiB"
