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
