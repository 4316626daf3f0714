"""Explicit, idempotent JAX set-up for entry points (CLI, tests, benchmarks).

Each function imports JAX itself: the entry points import this module before they know whether
the command at hand needs JAX at all (a problem file read into its Model, `contopt --help`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path


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


def setup_jax(cache: bool = True) -> None:
    """What every entry point calls first: float64 and (optionally) the compile cache."""
    enable_x64()
    if cache:
        enable_compilation_cache()
