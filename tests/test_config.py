"""The JAX set-up of the entry points: a compilation-cache path that cannot be used."""

import logging
import os
import shutil
import subprocess
import sys

import jax
import pytest

from contopt.config import enable_compilation_cache


@pytest.fixture
def keep_cache_dir():
    """Restore the test session's cache directory (a successful call here would change it)."""
    before = getattr(jax.config, "jax_compilation_cache_dir")  # noqa: B009 (see contopt.config)
    yield
    jax.config.update("jax_compilation_cache_dir", before)


def _cache_off(caplog, path, monkeypatch):
    monkeypatch.setenv("CONTOPT_JAX_CACHE", str(path))
    before = getattr(jax.config, "jax_compilation_cache_dir")  # noqa: B009
    with caplog.at_level(logging.WARNING, logger="contopt.config"):
        assert enable_compilation_cache() is None
    assert getattr(jax.config, "jax_compilation_cache_dir") == before  # noqa: B009 (unchanged)
    (record,) = [r for r in caplog.records if r.name == "contopt.config"]
    message = record.getMessage()
    assert "\n" not in message and str(path) in message and "CONTOPT_JAX_CACHE" in message
    return message


def test_cache_path_of_a_file_warns_and_runs_without(tmp_path, caplog, monkeypatch, keep_cache_dir):
    path = tmp_path / "cache"
    path.write_text("")
    assert "a file, not a directory" in _cache_off(caplog, path, monkeypatch)


def test_cache_path_below_a_file_warns_and_runs_without(tmp_path, caplog, monkeypatch, keep_cache_dir):
    (tmp_path / "file").write_text("")
    _cache_off(caplog, tmp_path / "file" / "cache", monkeypatch)


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes anywhere")
def test_unwritable_cache_directory_warns_and_runs_without(tmp_path, caplog, monkeypatch, keep_cache_dir):
    path = tmp_path / "cache"
    path.mkdir()
    path.chmod(0o500)
    try:
        _cache_off(caplog, path, monkeypatch)
    finally:
        path.chmod(0o700)


def test_writable_cache_directory_is_used(tmp_path, monkeypatch, keep_cache_dir):
    monkeypatch.setenv("CONTOPT_JAX_CACHE", str(tmp_path / "new" / "cache"))
    path = enable_compilation_cache()
    assert path == tmp_path / "new" / "cache" and path.is_dir()
    assert getattr(jax.config, "jax_compilation_cache_dir") == str(path)  # noqa: B009


@pytest.mark.skipif(not sys.platform.startswith("linux") or shutil.which("bash") is None, reason="ulimit -v of bash")
def test_the_address_space_limit_is_ulimit_v_and_what_is_left_of_it():
    code = (
        "from contopt.config import address_space_left, address_space_limit; "
        "print(address_space_limit(), address_space_left())"
    )
    done = subprocess.run(
        ["bash", "-c", f"ulimit -v 4000000 && exec {sys.executable} -c '{code}'"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    limit, left = done.stdout.split()
    # what is mapped already (Python and the numpy-free contopt.config) comes off the limit
    assert int(limit) == 4_000_000 * 1024 and 0 < int(left) < int(limit)


_ARENAS = """
import ctypes, os, sys, tempfile, threading
from contopt.config import limit_malloc_arenas
applied = limit_malloc_arenas(2) if sys.argv[1] == "on" else False
libc = ctypes.CDLL(None)
libc.malloc.restype = ctypes.c_void_p
libc.malloc.argtypes = [ctypes.c_size_t]
libc.fopen.restype = ctypes.c_void_p
libc.malloc_info.argtypes = [ctypes.c_int, ctypes.c_void_p]
libc.fclose.argtypes = [ctypes.c_void_p]
together = threading.Barrier(8)
def work():
    libc.malloc(1000)  # a thread's first allocation takes it an arena
    together.wait()  # none ends (and frees its arena for the next) before all have allocated
threads = [threading.Thread(target=work) for _ in range(8)]
for t in threads: t.start()
for t in threads: t.join()
path = os.path.join(tempfile.mkdtemp(), "info.xml")
f = libc.fopen(path.encode(), b"w")
libc.malloc_info(0, f)
libc.fclose(f)
print(applied, open(path).read().count("<heap nr="))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc arenas")
def test_limit_malloc_arenas_caps_the_arenas_that_threads_take():
    """Eight threads allocating at once take eight arenas besides the main one under glibc's default (up to 8
    per core); capped, they share two."""
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_ARENA_MAX"}
    counts = {}
    for mode in ("off", "on"):
        out = subprocess.run([sys.executable, "-c", _ARENAS, mode], capture_output=True, text=True, env=env, check=True)
        applied, n = out.stdout.split()
        counts[mode] = (applied, int(n))
    assert counts["on"] == ("True", 2)
    assert counts["off"][1] >= 4  # glibc's own cap: 8 per core, at least 2 cores' worth on any machine here
    # where MALLOC_ARENA_MAX is set glibc took it at start: the environment's value stands
    env["MALLOC_ARENA_MAX"] = "3"
    out = subprocess.run([sys.executable, "-c", _ARENAS, "on"], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.split() == ["False", "3"]
