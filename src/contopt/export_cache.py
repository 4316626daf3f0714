"""Ahead-of-time kernels: the jitted kernels of the steady path, traced once and kept on disk.

JAX's persistent compilation cache keeps XLA's executables only: every process still traces each
kernel to a jaxpr and lowers it to StableHLO before it can look the executable up (3-4 s of the
first Newton iteration of a contact problem, docs/performance.md "Start-up"). A :class:`Kernel`
wraps a jitted function and calls it through :mod:`jax.export` instead: the first call with given
argument shapes and static arguments exports the function (one trace and lowering) and writes the
serialized :class:`jax.export.Exported` to ``<compilation cache>/export/``; later processes read it
and call ``jax.jit(exported.call)``, whose XLA executable the persistent cache holds.

Every call with the cache on goes through an ``Exported``, freshly made or read, so a process runs
the same StableHLO whether it traced the kernel or loaded it: the results do not depend on the
state of the cache. (They may differ from a plain ``jax.jit`` of the kernel in the last bits of
entries with cancellation: XLA compiles the exported module, which JAX has canonicalized, not the
jit's own; tests/test_export_cache.py bounds this.)

An entry's name is a hash of everything that changes the traced program: the kernel's name, the
source of the contopt package (every module, so the kernels' dependencies are covered), the
static arguments (a function by its module and name, with the hash of its file when it is not
contopt's), the argument shapes, dtypes and weak types, and the versions of jax, jaxlib and the
calling convention, float64 and the backend. A static argument that cannot be named stably (a
lambda, a closure, a partial) makes that call a plain jit. The file holds the key itself and the
payload's hash: an unreadable, corrupt or mismatched file is reported in one warning, traced again
and rewritten. Files are written to a temporary name and renamed (``os.replace``): concurrent
processes writing one entry leave one whole file.

``CONTOPT_EXPORT_CACHE=0`` turns this off (plain ``jax.jit``, as without a compilation cache);
``CONTOPT_EXPORT_CACHE=DIR`` keeps the entries in DIR.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import logging
import os
import secrets
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import jax
import jax.export  # not an attribute of jax until imported (jax 0.7)
import jaxlib
import numpy as np

from contopt import __version__

log = logging.getLogger(__name__)

#: first line of every entry; bump it when the file layout changes
MAGIC = b"contopt-export-v1\n"
_PACKAGE = Path(__file__).resolve().parent


def export_dir() -> Path | None:
    """Where the entries are: ``$CONTOPT_EXPORT_CACHE`` if it names a folder, else
    ``<jax_compilation_cache_dir>/export``; None when it is off or there is no compilation cache."""
    setting = os.environ.get("CONTOPT_EXPORT_CACHE", "").strip()
    if setting.lower() in ("0", "false", "no", "off"):
        return None
    if setting:
        return Path(setting)
    where = getattr(jax.config, "jax_compilation_cache_dir")  # noqa: B009 (see contopt.config)
    return Path(where) / "export" if where else None


_SOURCE: list[str] = []


def source_fingerprint() -> str:
    """sha256 of contopt's version and of every module of the package (computed once a process)."""
    if not _SOURCE:
        h = hashlib.sha256(__version__.encode())
        for path in sorted(_PACKAGE.rglob("*.py")):
            h.update(path.relative_to(_PACKAGE).as_posix().encode() + b"\0")
            h.update(path.read_bytes() + b"\0")
        _SOURCE.append(h.hexdigest())
    return _SOURCE[0]


def static_token(value: Any) -> str | None:
    """A stable text for a static argument, or None when it has none (then the call is not cached)."""
    if isinstance(value, np.generic):
        value = value.item()  # a numpy bool or number: as the Python one
    if value is None or isinstance(value, (bool, int, float, str)):
        return f"{type(value).__name__}:{value!r}"
    if inspect.isfunction(value) or inspect.isbuiltin(value):
        module, name = getattr(value, "__module__", None) or "", getattr(value, "__qualname__", "")
        if not module or "<" in name or getattr(value, "__closure__", None):
            return None  # a lambda, a local function or a closure: no stable name
        if module == "contopt" or module.startswith("contopt."):
            return f"fn:{module}:{name}"  # covered by the source fingerprint
        try:
            where = inspect.getsourcefile(value)
            digest = hashlib.sha256(Path(where).read_bytes()).hexdigest() if where else None
        except (OSError, TypeError):
            digest = None
        return f"fn:{module}:{name}:{digest}" if digest else None
    return None


def _environment() -> dict:
    return {
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "calling_convention": jax.export.maximum_supported_calling_convention_version,
        "x64": bool(getattr(jax.config, "jax_enable_x64")),  # noqa: B009 (see contopt.config)
        "backend": jax.default_backend(),
        "matmul_precision": str(getattr(jax.config, "jax_default_matmul_precision")),  # noqa: B009
    }


class Kernel:
    """A jitted function called through :mod:`jax.export`, its export kept on disk (module docstring).

    ``kernel(*arrays, **static)`` is ``jitted(*arrays, **static)``: positional arguments are arrays,
    keyword arguments the jitted function's static arguments.
    """

    def __init__(self, jitted: Any, name: str | None = None):
        _KERNELS.append(self)
        self.jitted = jitted
        wrapped = getattr(jitted, "__wrapped__", jitted)
        self.name = name or f"{wrapped.__module__}.{wrapped.__qualname__}"
        self._calls: dict[tuple, Callable] = {}  # (avals, static) -> the callable of that variant
        self.sources: dict[tuple, str] = {}  # the same keys -> "loaded", "exported", "jit" (tests, benchmarks)

    def __call__(self, *args, **static):
        avals = tuple((tuple(a.shape), str(a.dtype), bool(getattr(a, "weak_type", False))) for a in args)
        memo = (avals, tuple(sorted(static.items())))
        fn = self._calls.get(memo)
        if fn is None:
            fn = self._calls[memo] = self._prepare(memo, args, static)
        return fn(*args)

    def clear(self) -> None:
        """Forget the variants of this process (the next call loads or exports again)."""
        self._calls.clear()
        self.sources.clear()

    # ---------------------------------------------------------------------------------------- set-up
    def key(self, args, static) -> dict | None:
        """Everything the traced program depends on, or None when a static argument has no stable name."""
        tokens = {name: static_token(value) for name, value in sorted(static.items())}
        if any(token is None for token in tokens.values()):
            return None
        avals = [[list(a.shape), str(a.dtype), bool(getattr(a, "weak_type", False))] for a in args]
        return {"kernel": self.name, "source": source_fingerprint(), "static": tokens, "args": avals, **_environment()}

    def _prepare(self, memo, args, static) -> Callable:
        folder = export_dir()
        key = self.key(args, static) if folder is not None else None
        if folder is None or key is None:
            self.sources[memo] = "jit"
            return partial(self.jitted, **static)
        text = json.dumps(key, sort_keys=True)
        path = folder / f"{self.name.rsplit('.', 1)[-1].strip('_')}-{hashlib.sha256(text.encode()).hexdigest()[:40]}"
        exported = read_entry(path, text, args) if path.exists() else None
        self.sources[memo] = "loaded" if exported is not None else "exported"
        if exported is None:
            weak = [bool(getattr(a, "weak_type", False)) for a in args]
            specs = [jax.ShapeDtypeStruct(a.shape, a.dtype, weak_type=w) for a, w in zip(args, weak)]
            try:
                exported = jax.export.export(self.jitted)(*specs, **static)
            except Exception as err:  # noqa: BLE001 (any failure of export: the plain jit still works)
                log.warning("export cache: cannot export %s (%s); using jax.jit", self.name, err)
                self.sources[memo] = "jit"
                return partial(self.jitted, **static)
            write_entry(path, text, exported)
        return jax.jit(exported.call)


_KERNELS: list[Kernel] = []


def kernel_sources() -> dict[str, int]:
    """How many kernel variants this process read ("loaded"), traced and exported, or jitted plainly."""
    counts: dict[str, int] = {}
    for kernel in _KERNELS:
        for source in kernel.sources.values():
            counts[source] = counts.get(source, 0) + 1
    return counts


def read_entry(path: Path, key_text: str, args) -> Any:
    """The Exported of ``path`` if it is whole and made for ``key_text`` (and these arguments), else None (warned)."""
    try:
        blob = path.read_bytes()
        magic, key_line, digest, payload = _split(blob)
        if magic != MAGIC:
            raise ValueError("not a contopt export file (or of another layout version)")
        if key_line.decode() != key_text:
            raise ValueError("made for another kernel, source or version")
        if hashlib.sha256(payload).hexdigest().encode() != digest:
            raise ValueError("payload does not match its checksum")
        exported = jax.export.deserialize(bytearray(payload))
        want = [(tuple(a.shape), str(a.dtype)) for a in args]
        have = [(tuple(a.shape), str(a.dtype)) for a in exported.in_avals]
        if want != have:
            raise ValueError(f"argument shapes {have}, expected {want}")
        return exported
    except Exception as err:  # noqa: BLE001 (whatever is wrong with the file, tracing again repairs it)
        log.warning("export cache: ignoring %s (%s); tracing the kernel again and rewriting it", path, err)
        return None


def _split(blob: bytes) -> tuple[bytes, bytes, bytes, bytes]:
    first = blob.index(b"\n") + 1
    second = blob.index(b"\n", first) + 1
    third = blob.index(b"\n", second) + 1
    return blob[:first], blob[first : second - 1], blob[second : third - 1], blob[third:]


def write_entry(path: Path, key_text: str, exported) -> bool:
    """Write ``exported`` for ``key_text`` atomically (temporary file, then ``os.replace``); False if it cannot."""
    try:
        payload = bytes(exported.serialize())
        path.parent.mkdir(parents=True, exist_ok=True)
        # a name of its own per writer (mode as any new file: umask), renamed over the entry when whole
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
        try:
            with open(tmp, "xb") as f:
                f.write(MAGIC + key_text.encode() + b"\n" + hashlib.sha256(payload).hexdigest().encode() + b"\n")
                f.write(payload)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return True
    except ImportError as err:  # serialization needs the flatbuffers package (a dependency of contopt)
        if not _NO_SERIALIZER:
            log.warning("export cache: cannot serialize kernels (%s); they are traced in every process", err)
        _NO_SERIALIZER.append(True)
        return False
    except Exception as err:  # noqa: BLE001 (a cache that cannot be written costs time, not results)
        log.warning("export cache: cannot write %s (%s); the kernel is traced again in the next process", path, err)
        return False


_NO_SERIALIZER: list[bool] = []  # not empty once the warning above was given
