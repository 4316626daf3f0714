"""Distributed runs (contopt.parallel): the split of the cells, and 1, 2 and 3 ranks (oversubscribed on
two cores) against the serial answer on a coarse contact case: forward state, adjoint gradient and
three optimization iterations, and with Coulomb friction the path and its adjoint; a failing rank
stops the job."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from contopt.parallel import SERIAL, Comm, cell_range, launched_size
from contopt.solve.linear import available_backends

HERE = Path(__file__).parent
MPIEXEC = Path(sys.executable).with_name("mpiexec")
needs_mpi = pytest.mark.skipif(
    "petsc" not in available_backends() or not MPIEXEC.exists(),
    reason="distributed runs need the petsc extra (PETSc, MPICH, mpi4py; Python 3.12+)",
)


class _Rank(Comm):
    def __init__(self, rank: int, size: int):
        self.rank, self.size = rank, size


@pytest.mark.parametrize("n", [0, 1, 7, 96, 1000])
@pytest.mark.parametrize("size", [1, 2, 3, 8])
def test_cell_ranges_cover_every_cell_once_and_differ_by_at_most_one(n, size):
    parts = [cell_range(n, _Rank(r, size)) for r in range(size)]
    covered = np.concatenate([np.arange(n)[p] for p in parts])
    np.testing.assert_array_equal(covered, np.arange(n))
    lengths = [p.stop - p.start for p in parts]
    assert max(lengths) - min(lengths) <= 1


def test_serial_communicator_is_the_identity(monkeypatch):
    x = np.arange(3.0)
    assert SERIAL.sum(x) is x and SERIAL.sum(2.5) == 2.5 and SERIAL.all(True) and not SERIAL.distributed
    monkeypatch.setenv("PMI_SIZE", "3")
    assert launched_size() == 3
    monkeypatch.delenv("PMI_SIZE")
    for name in ("OMPI_COMM_WORLD_SIZE", "MPI_LOCALNRANKS"):
        monkeypatch.delenv(name, raising=False)
    assert launched_size() == 1


def _mpiexec(n: int, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run(
        [str(MPIEXEC), "-n", str(n), sys.executable, *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def _case():
    import importlib.util

    spec = importlib.util.spec_from_file_location("mpi_case", HERE / "_mpi_forward_adjoint.py")
    assert spec is not None and spec.loader is not None
    case = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(case)
    return case


@pytest.fixture(scope="module")
def serial_alm():
    """The serial answer (Pardiso where installed), computed in this process."""
    return _case().solve("alm", backend="auto")


@pytest.fixture(scope="module")
def serial_friction():
    """The frictional case's serial answer (a direct solver), computed in this process."""
    return _case().solve_friction(backend="auto")


@needs_mpi
@pytest.mark.parametrize("ranks, preconditioner", [(1, "gamg"), (2, "gamg"), (3, "gamg"), (2, "mumps")])
def test_forward_state_and_adjoint_gradient_match_the_serial_run(ranks, preconditioner, serial_alm, tmp_path):
    out = tmp_path / "r.npz"
    proc = _mpiexec(ranks, str(HERE / "_mpi_forward_adjoint.py"), "alm", str(out), preconditioner)
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = np.load(out)
    assert int(got["ranks"]) == ranks
    # the preconditioner asked for is the one used, and no solve fell back to another solver
    assert int(got["petsc_fallbacks"]) == 0 and int(got["petsc_setups"]) >= 1
    factored = int(got["petsc_factorizations"])
    assert factored == int(got["petsc_setups"]) if preconditioner == "mumps" else factored == 0
    # both stop Newton at |r| <= 1e-11 |f|, the adjoint's inner Krylov solves at 1e-12: far below 1e-8
    ref = serial_alm
    assert np.abs(got["u"] - ref["u"]).max() <= 1e-8 * np.abs(ref["u"]).max()
    np.testing.assert_allclose(got["force"], ref["force"], rtol=1e-8)
    np.testing.assert_allclose(got["values"], ref["values"], rtol=1e-8)
    for g, r in zip(got["gradients"], ref["gradients"]):
        assert np.abs(g - r).max() <= 1e-8 * np.abs(r).max()


@needs_mpi
@pytest.mark.parametrize("ranks", [2, 3])
def test_a_frictional_path_and_its_adjoint_match_the_serial_run(ranks, serial_friction, tmp_path):
    ref = serial_friction
    assert ref["n_stick"] > 0 and ref["n_slip"] > 0  # both branches of the law in play
    out = tmp_path / "r.npz"
    proc = _mpiexec(ranks, str(HERE / "_mpi_forward_adjoint.py"), "friction", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = np.load(out)
    assert int(got["ranks"]) == ranks
    assert (int(got["n_stick"]), int(got["n_slip"])) == (ref["n_stick"], ref["n_slip"])
    # Newton at |r| <= 1e-11 |f|, GMRES at 1e-12 (measured: 1e-13 state, 2e-11 gradients): far below 1e-8
    assert np.abs(got["u"] - ref["u"]).max() <= 1e-8 * np.abs(ref["u"]).max()
    assert np.abs(got["traction"] - ref["traction"]).max() <= 1e-8 * np.abs(ref["traction"]).max()
    np.testing.assert_allclose(got["values"], ref["values"], rtol=1e-8)
    for g, r in zip(got["gradients"], ref["gradients"]):
        assert np.abs(g - r).max() <= 1e-8 * np.abs(r).max()


@needs_mpi
def test_three_optimization_iterations_on_two_ranks_match_the_serial_run(tmp_path):
    from contopt.cli import main

    common = ["run", "die-slab", "--mesh", "coarse", "--max-iter", "3", "--no-plot", "--vtu", "final"]
    assert main(["-q", *common, "--out", str(tmp_path / "serial")]) == 0
    proc = _mpiexec(2, "-m", "contopt.cli", "-q", *common, "--solver", "petsc", "--out", str(tmp_path / "two"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    serial = json.loads((tmp_path / "serial" / "history.json").read_text())
    two = json.loads((tmp_path / "two" / "history.json").read_text())
    assert len(two) == len(serial) == 4
    for a, b in zip(two, serial):
        assert a["objective_raw"] == pytest.approx(b["objective_raw"], rel=1e-8)
        for key, value in b["constraints"].items():
            assert a["constraints"][key] == pytest.approx(value, rel=1e-6, abs=1e-8)
    # rank 1 wrote nothing into the run directory (its copy went to a private temporary one)
    assert not any("rank" in p.name for p in (tmp_path / "two").iterdir())


@needs_mpi
def test_a_failing_rank_stops_every_rank_with_its_message(tmp_path):
    script = tmp_path / "fail.py"
    script.write_text(
        "from contopt.parallel import abort_on_error, world\n"
        "comm = world()\n"
        "with abort_on_error(comm):\n"
        "    if comm.rank == 1:\n"
        "        raise RuntimeError('the mesh of rank 1 is inverted')\n"
        "    comm.barrier()  # rank 0 would wait here forever\n"
    )
    proc = _mpiexec(2, str(script), timeout=120)
    assert proc.returncode != 0
    assert "rank 1 failed: RuntimeError: the mesh of rank 1 is inverted" in proc.stderr, proc.stderr[-3000:]
