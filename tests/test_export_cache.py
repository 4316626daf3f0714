"""The ahead-of-time kernels (contopt.export_cache): same numbers as the jit, safe files, honest keys.

Each test keeps its entries in its own folder (``CONTOPT_EXPORT_CACHE``); the XLA executables go to
the persistent compilation cache of the test session, so after a first run nothing compiles.
"""

import logging
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from contopt import export_cache
from contopt.assembly import kernels
from contopt.contact import mortar
from contopt.export_cache import read_entry, static_token, write_entry
from contopt.material.energy import mooney_rivlin_energy

CHUNK = 8  # the chunk of the mortar kernels here (as the batched calls of tests/contact use 16)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A fresh entry folder, and kernels that forget the variants earlier tests made."""
    monkeypatch.setenv("CONTOPT_EXPORT_CACHE", str(tmp_path))
    used = [
        kernels.RESIDUAL_TANGENT_BATCH,
        kernels.STRESS_BATCH,
        mortar.VALUES_BATCH,
        mortar.VALUES_JAC_BATCH,
        mortar.HESSIAN_BATCH,
    ]
    for k in used:
        k.clear()
    yield tmp_path
    for k in used:
        k.clear()  # the next tests find their own folder again


def bulk_args(rng, m=4):
    """Four distorted hex8 cells: (u, grad, wdet, rho) and params of a Mooney-Rivlin material."""
    from contopt.fem.hex8 import cell_geometry
    from contopt.mesh import box

    mesh = box((1.0, 1.0, 0.5), (2, 2, 1))
    geo = cell_geometry(mesh.points + 0.02 * rng.standard_normal(mesh.points.shape), mesh.cells)
    u = 0.05 * rng.standard_normal((m, 8, 3))
    rho = rng.uniform(0.3, 1.0, m)
    params = jnp.asarray([2.0, 0.4, 0.1])
    return tuple(jnp.asarray(a) for a in (u, geo.grad[:m], geo.wdet[:m], rho)), params


def mortar_args(rng, n=CHUNK):
    """Pairs of a jittered unit square under a larger, rotated square: 4-vertex overlaps (2 triangles)."""
    from contopt.contact import segment_pairs

    a = np.deg2rad(3.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    X = np.empty((n, 8, 3))
    for p in range(n):
        m = ((sq - 0.5) * 1.3 @ R.T + 0.5 + 0.02 * rng.standard_normal(2))[[0, 3, 2, 1]]
        X[p, :4] = np.c_[sq, np.zeros(4)] + 0.01 * rng.standard_normal((4, 3))
        X[p, 4:] = np.c_[m, 0.05 + 0.01 * rng.standard_normal(4)]
    seg = segment_pairs(X[:, :4], X[:, 4:])
    assert (seg.n_vertices == 4).all()
    w = rng.standard_normal((n, 8))
    return jnp.asarray(X), jnp.asarray(seg.topo, dtype=jnp.int32), jnp.asarray(w)


def relative(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def run_twice(kernel, args, static):
    """(result of a fresh export, result of the entry read back in a 'new process')."""
    kernel.clear()
    fresh = kernel(*args, **static)
    assert set(kernel.sources.values()) == {"exported"}
    kernel.clear()
    loaded = kernel(*args, **static)
    assert set(kernel.sources.values()) == {"loaded"}
    return fresh, loaded


def test_bulk_kernel_loaded_equals_exported_bitwise_and_the_jit_to_roundoff(cache, rng):
    args, params = bulk_args(rng)
    static = {"energy": mooney_rivlin_energy, "use_fbar": True, "tangent": True}
    fresh, loaded = run_twice(kernels.RESIDUAL_TANGENT_BATCH, (*args, params), static)
    jitted = kernels.RESIDUAL_TANGENT_BATCH.jitted(*args, params, **static)
    assert len(list(cache.iterdir())) == 1
    for f, lo, j in zip(fresh, loaded, jitted):
        np.testing.assert_array_equal(np.asarray(lo), np.asarray(f))  # one program, read or made
        assert relative(f, j) <= 1e-15


def test_stress_kernel_through_the_cache(cache, rng):
    (u, grad, wdet, _), params = bulk_args(rng)
    static = {"energy": mooney_rivlin_energy, "use_fbar": False}
    fresh, loaded = run_twice(kernels.STRESS_BATCH, (u, grad, wdet, params), static)
    np.testing.assert_array_equal(np.asarray(loaded), np.asarray(fresh))
    assert relative(fresh, kernels.STRESS_BATCH.jitted(u, grad, wdet, params, **static)) <= 1e-15


@pytest.mark.parametrize("name", ["VALUES_BATCH", "VALUES_JAC_BATCH", "HESSIAN_BATCH"])
def test_mortar_kernels_loaded_equal_exported_bitwise_and_the_jit_to_roundoff(cache, rng, name):
    X, topo, w = mortar_args(rng)
    kernel = getattr(mortar, name)
    args = (X, topo, w) if name == "HESSIAN_BATCH" else (X, topo)
    fresh, loaded = run_twice(kernel, args, {"n_tri": 2})
    jitted = kernel.jitted(*args, n_tri=2)
    fresh, loaded, jitted = (r if isinstance(r, tuple) else (r,) for r in (fresh, loaded, jitted))
    for f, lo, j in zip(fresh, loaded, jitted):
        np.testing.assert_array_equal(np.asarray(lo), np.asarray(f))
        assert relative(f, j) <= 1e-15


def test_a_corrupt_entry_warns_is_traced_again_and_rewritten(cache, rng, caplog):
    X, topo, _ = mortar_args(rng)
    kernel = mortar.VALUES_BATCH
    kernel.clear()
    good = kernel(X, topo, n_tri=2)
    (entry,) = cache.iterdir()
    blob = entry.read_bytes()
    for broken in (blob[: len(blob) // 2], blob[:-100] + b"x" * 100, b"garbage"):
        entry.write_bytes(broken)
        kernel.clear()
        with caplog.at_level(logging.WARNING, logger="contopt.export_cache"):
            caplog.clear()
            again = kernel(X, topo, n_tri=2)
        assert [r.levelno for r in caplog.records] == [logging.WARNING]
        assert "tracing the kernel again" in caplog.records[0].getMessage() and str(entry) in caplog.text
        assert set(kernel.sources.values()) == {"exported"}
        for a, b in zip(again, good):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        assert entry.read_bytes() == blob  # rewritten whole (the export is deterministic)
    kernel.clear()
    kernel(X, topo, n_tri=2)
    assert set(kernel.sources.values()) == {"loaded"}


def test_an_entry_made_for_another_key_is_not_used(cache, rng, caplog):
    X, topo, _ = mortar_args(rng)
    kernel = mortar.VALUES_BATCH
    kernel.clear()
    kernel(X, topo, n_tri=2)
    (entry,) = cache.iterdir()
    key_text = entry.read_bytes().split(b"\n")[1].decode()
    assert read_entry(entry, key_text, (X, topo)) is not None
    with caplog.at_level(logging.WARNING, logger="contopt.export_cache"):
        assert read_entry(entry, key_text.replace("VALUES", "values").replace("n_tri", "n_trj"), (X, topo)) is None
        assert read_entry(entry, key_text, (X[:4], topo[:4])) is None  # other shapes
    assert len(caplog.records) == 2


def test_the_key_changes_with_shapes_dtypes_and_static_arguments(cache, rng):
    args, params = bulk_args(rng)
    k = kernels.RESIDUAL_TANGENT_BATCH
    base = {"energy": mooney_rivlin_energy, "use_fbar": True, "tangent": True}
    keys = [
        k.key((*args, params), base),
        k.key((*args, params), {**base, "use_fbar": False}),
        k.key((*args, params), {**base, "tangent": False}),
        k.key((*(a[:2] for a in args), params), base),
        k.key((args[0].astype(jnp.float32), *args[1:], params), base),
        k.key((*args, params), {**base, "energy": _another_energy}),
        kernels.ENERGY_BATCH.key((*args, params), {"energy": mooney_rivlin_energy, "use_fbar": True}),
    ]
    texts = {str(key) for key in keys}
    assert len(texts) == len(keys)
    assert k.key((*args, params), {**base, "use_fbar": np.bool_(True)}) == keys[0]  # numpy bool = bool


def test_the_key_holds_the_versions_of_jax_and_jaxlib(rng):
    """contopt installs with a range of JAX versions: each keeps its own entries in one folder."""
    import jaxlib

    args, params = bulk_args(rng)
    static = {"energy": mooney_rivlin_energy, "use_fbar": True, "tangent": True}
    key = kernels.RESIDUAL_TANGENT_BATCH.key((*args, params), static)
    assert (key["jax"], key["jaxlib"]) == (jax.__version__, jaxlib.__version__)


def test_static_arguments_without_a_stable_name_are_plain_jit(cache, rng):
    assert static_token(lambda I1, I2, J, p: I1) is None
    scale = 2.0
    assert static_token(lambda I1, I2, J, p: scale * I1) is None
    assert static_token(object()) is None
    assert static_token(mooney_rivlin_energy) == "fn:contopt.material.energy:mooney_rivlin_energy"
    token = static_token(_another_energy)
    assert token is not None and token.startswith(f"fn:{__name__}:_another_energy:")  # with its file's hash

    args, params = bulk_args(rng)

    def local_energy(I1, I2, J, p):
        return mooney_rivlin_energy(I1, I2, J, p)

    k = kernels.RESIDUAL_TANGENT_BATCH
    k.clear()
    k(*args, params, energy=local_energy, use_fbar=True, tangent=False)
    assert set(k.sources.values()) == {"jit"} and not any(cache.iterdir())


def test_different_static_arguments_get_their_own_entries(cache, rng):
    args, params = bulk_args(rng)
    k = kernels.RESIDUAL_TANGENT_BATCH
    k.clear()
    with_fbar = k(*args, params, energy=mooney_rivlin_energy, use_fbar=True, tangent=False)
    without = k(*args, params, energy=mooney_rivlin_energy, use_fbar=False, tangent=False)
    assert len(list(cache.iterdir())) == 2
    k.clear()  # a new process: each variant reads its own entry
    for use_fbar, expected in ((True, with_fbar), (False, without)):
        got = k(*args, params, energy=mooney_rivlin_energy, use_fbar=use_fbar, tangent=False)
        for a, b in zip(got, expected):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert set(k.sources.values()) == {"loaded"}
    assert not np.allclose(np.asarray(with_fbar[1]), np.asarray(without[1]))


def test_no_cache_folder_means_plain_jit(monkeypatch, rng):
    monkeypatch.setenv("CONTOPT_EXPORT_CACHE", "0")
    assert export_cache.export_dir() is None
    X, topo, _ = mortar_args(rng)
    mortar.VALUES_BATCH.clear()
    try:
        mortar.VALUES_BATCH(X, topo, n_tri=2)
        assert set(mortar.VALUES_BATCH.sources.values()) == {"jit"}
    finally:
        mortar.VALUES_BATCH.clear()


WRITER = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    import jax, jax.numpy as jnp, numpy as np
    jax.config.update("jax_enable_x64", True)
    from contopt.export_cache import write_entry
    table = jnp.asarray(np.arange(100_000.0))  # a large constant: a payload of ~1 MB, written in pieces
    f = jax.jit(lambda x: jnp.sin(x) * {factor} + 0.0 * jnp.sum(table))
    exported = jax.export.export(f)(jax.ShapeDtypeStruct((64,), jnp.float64))
    sys.stdin.readline()  # start together
    for _ in range(30):
        assert write_entry(Path(sys.argv[1]), "the key", exported)
    """
)


def test_concurrent_writers_of_one_entry_leave_a_whole_file(tmp_path):
    """Two processes write one entry 30 times each (different payloads, so that a mix of the two is
    no valid file) while this one reads it: every read finds no file or a whole one."""
    entry = tmp_path / "entry"
    x = jnp.linspace(0.0, 1.0, 64)
    procs = [
        subprocess.Popen([sys.executable, "-c", WRITER.format(factor=f), str(entry)], stdin=subprocess.PIPE)
        for f in (1.0, 2.0)
    ]
    for p in procs:
        p.stdin.write(b"go\n")
        p.stdin.flush()
    reads = []
    while any(p.poll() is None for p in procs):
        if entry.exists():
            reads.append(read_entry(entry, "the key", (x,)) is not None)
    assert [p.wait(timeout=120) for p in procs] == [0, 0]
    assert all(reads)
    assert [p.name for p in tmp_path.iterdir()] == ["entry"]  # no temporary file left behind
    exported = read_entry(entry, "the key", (x,))
    assert exported is not None
    got = np.asarray(exported.call(x))
    assert any(np.array_equal(got, np.asarray(jnp.sin(x) * f)) for f in (1.0, 2.0))


def test_write_entry_fails_softly_where_it_cannot_write(tmp_path, caplog):
    exported = jax.export.export(jax.jit(jnp.cos))(jax.ShapeDtypeStruct((3,), jnp.float64))
    blocker = tmp_path / "a file"
    blocker.write_text("")
    with caplog.at_level(logging.WARNING, logger="contopt.export_cache"):
        assert not write_entry(blocker / "entry", "k", exported)
    assert "cannot write" in caplog.text


def _another_energy(I1, I2, J, params):
    return mooney_rivlin_energy(I1, I2, J, params) + 0.0 * J
