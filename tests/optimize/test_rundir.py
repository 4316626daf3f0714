"""The run directory: one writer at a time, a full disk, a damaged meta.json, a failed first analysis.

Every optimization here is the small cantilever (96 cells) with MMA and 3 iterations; the
uninterrupted run that the others are compared with is made once per module.
"""

import errno
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from _cantilever import cantilever_problem  # tests/optimize/_cantilever.py

from contopt.assembly.system import discretize
from contopt.errors import ConfigError, ContoptError, ConvergenceError, OutputError
from contopt.optimize.driver import OutputOptions, optimize
from contopt.optimize.mma import MMAOptions
from contopt.optimize.rundir import RunLock

SMALL = (12, 4, 2)
OPTIONS = MMAOptions(max_iter=3)
QUIET = OutputOptions(vtu="none", plot=False)


def _small(**kw):
    return cantilever_problem("density", divisions=SMALL, **kw)


def _objectives(run_dir) -> list[float]:
    return [r["objective"] for r in json.loads((Path(run_dir) / "history.json").read_text())]


def _temporaries(run_dir) -> list[str]:
    return [str(p) for p in Path(run_dir).rglob("*") if ".tmp" in p.name]


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """An uninterrupted run with every output (VTU and pictures), and its result."""
    out = tmp_path_factory.mktemp("whole")
    return out, optimize(_small(), "mma", OPTIONS, out=out)


# ------------------------------------------------------------------------------------------ the lock
def test_a_directory_in_use_is_refused_naming_the_pid(whole, tmp_path):
    """--overwrite, --resume and a fresh run of a directory another process writes: refused, untouched."""
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"}
    with RunLock(out):  # this test process plays the run that still writes
        for kw in ({"overwrite": True}, {"resume": True}, {}):
            with pytest.raises(ConfigError, match=rf"in use by another run \(PID {os.getpid()}\b") as err:
                optimize(_small(), "mma", OPTIONS, out=out, outputs=QUIET, **kw)
            assert "\n" not in str(err.value)
    after = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"}
    assert after == before  # nothing of the first run was lost
    # the lock is the run's only while it runs: released, a resume proceeds (all replayed)
    res = optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert res.replayed == res.analyses == whole[1].analyses


def test_resume_and_overwrite_together_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="--resume and --overwrite exclude each other"):
        optimize(_small(), "mma", OPTIONS, out=tmp_path, resume=True, overwrite=True)
    assert not (tmp_path / "checkpoint").exists()


# ------------------------------------------------------------------------------------- a full disk
def _no_space(*_):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _fail_fsync_of(name: str, monkeypatch):
    """ENOSPC when a file whose temporary is named like ``name`` is flushed (its data written)."""
    real = os.fsync

    def fsync(fd):
        if name in os.readlink(f"/proc/self/fd/{fd}"):
            _no_space()
        return real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def _fail_nth_call(monkeypatch, owner, attribute: str, n: int):
    """The n-th call of ``owner.attribute(self_or_none, path, ...)`` writes half a file, then ENOSPC."""
    real = getattr(owner, attribute)
    calls = []

    def fake(*args, **kwargs):
        calls.append(1)
        if len(calls) == n:
            path = next(a for a in args if isinstance(a, (str, os.PathLike)))
            Path(path).write_bytes(b"half a file")
            _no_space()
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, attribute, fake)


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="finds the file of a descriptor in /proc")
@pytest.mark.parametrize("where", ["checkpoint", "picture", "vtu"])
def test_a_full_disk_is_a_clear_error_leaves_no_temporary_and_resumes(where, whole, tmp_path, monkeypatch):
    import matplotlib.figure
    import meshio

    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        if where == "checkpoint":
            _fail_fsync_of("eval_00002", patch)
        elif where == "picture":
            _fail_nth_call(patch, matplotlib.figure.Figure, "savefig", 3)  # convergence.png of iteration 2
        else:
            _fail_nth_call(patch, meshio, "write", 3)  # vtu/beam_0002.vtu
        with pytest.raises(OutputError) as err:
            optimize(_small(), "mma", OPTIONS, out=out)
    message = str(err.value)
    assert isinstance(err.value, ContoptError) and err.value.errno == errno.ENOSPC and "\n" not in message
    assert "No space left on device" in message and "--resume" in message
    assert "keeps its 2 recorded analyses" in message or "keeps its 3 recorded analyses" in message
    assert _temporaries(out) == []
    res = optimize(_small(), "mma", OPTIONS, out=out, resume=True)
    assert res.replayed >= 2 and res.analyses == whole[1].analyses
    np.testing.assert_allclose(_objectives(out), _objectives(whole[0]), rtol=1e-9)
    assert json.loads((out / "summary.json").read_text())["status"] == whole[1].status
    assert _temporaries(out) == []


# ---------------------------------------------------------------------------------- a start design
def _start(space):
    """A start design of the small cantilever: a level set falling along x (volume fraction below 0.3)."""
    X = np.concatenate([p.sites for p in space.parts])
    return -0.05 - 0.05 * X[:, 0]


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="finds the file of a descriptor in /proc")
def test_a_run_from_a_start_design_resumes_from_it(tmp_path, monkeypatch):
    """The start is the first analysis's design, kept in checkpoint/start.npy; interrupted (a full disk
    at the third record) and resumed without it, the run replays from there to the uninterrupted history."""
    whole = optimize(_small(), "mma", OPTIONS, out=tmp_path / "whole", outputs=QUIET, start=_start)
    problem = _small()
    x0 = _start(problem.design.build(discretize(problem.model)))
    first = np.load(tmp_path / "whole" / "checkpoint" / "eval_00000.npz")["x"]
    assert first.tobytes() == x0.tobytes() == np.load(tmp_path / "whole" / "checkpoint" / "start.npy").tobytes()
    out = tmp_path / "cut"
    with monkeypatch.context() as patch:
        _fail_fsync_of("eval_00002", patch)
        with pytest.raises(OutputError):
            optimize(_small(), "mma", OPTIONS, out=out, outputs=QUIET, start=_start)
    with pytest.raises(ConfigError, match="--design-from and --resume exclude each other"):
        optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET, start=_start)
    res = optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert res.replayed >= 2 and res.analyses == whole.analyses
    np.testing.assert_allclose(_objectives(out), _objectives(tmp_path / "whole"), rtol=1e-9)


# ----------------------------------------------------------------------------- a damaged meta.json
def test_a_damaged_meta_json_is_rebuilt_from_the_records(whole, tmp_path, caplog):
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    meta = out / "checkpoint" / "meta.json"
    text = meta.read_text()
    meta.write_text(text[:40])  # cut short, as by a broken disk
    res = optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert res.replayed == res.analyses == whole[1].analyses  # every analysis kept
    assert _objectives(out) == _objectives(whole[0])
    assert json.loads(meta.read_text()) == json.loads(text)
    assert (out / "checkpoint" / "meta.json.damaged").read_text() == text[:40]  # kept for inspection
    assert any("meta.json is damaged" in r.getMessage() and "rebuilt" in r.getMessage() for r in caplog.records)


def test_a_damaged_meta_json_without_records_starts_again(tmp_path):
    (tmp_path / "checkpoint").mkdir()
    (tmp_path / "checkpoint" / "meta.json").write_text("{not json")
    res = optimize(_small(), "mma", MMAOptions(max_iter=1), out=tmp_path, resume=True, outputs=QUIET)
    assert res.replayed == 0 and res.iterations == 1
    assert "fingerprint" in json.loads((tmp_path / "checkpoint" / "meta.json").read_text())


def _strip_meta_copies(out: Path) -> list[Path]:
    """Rewrite every record without its copy of meta.json (as records were written before they carried one)."""
    records = sorted((out / "checkpoint").glob("eval_*.npz"))
    for path in records:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files if k != "meta"}
        np.savez(path, **arrays)
    return records


def test_a_damaged_meta_json_with_records_that_carry_no_copy_is_refused(whole, tmp_path):
    """Records written before they carried a copy of meta.json cannot be checked: a clear refusal."""
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    records = _strip_meta_copies(out)
    (out / "checkpoint" / "meta.json").write_text("")
    with pytest.raises(ConfigError, match=r"meta.json is damaged .*no record carries .* --overwrite"):
        optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert all(p.exists() for p in records) and (out / "checkpoint" / "meta.json.damaged").exists()


def test_a_deleted_meta_json_is_rebuilt_from_the_records(whole, tmp_path, caplog):
    """Every record carries a copy of meta.json: --resume rebuilds a deleted one (and says so) and
    replays every analysis; the latest record's copy is used, so an earlier damaged copy does not matter."""
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    meta = out / "checkpoint" / "meta.json"
    text = meta.read_text()
    meta.unlink()
    res = optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert res.replayed == res.analyses == whole[1].analyses
    assert _objectives(out) == _objectives(whole[0])
    assert json.loads(meta.read_text()) == json.loads(text)
    last = sorted((out / "checkpoint").glob("eval_*.npz"))[-1].name
    said = [r.getMessage() for r in caplog.records]
    assert any(f"meta.json was missing; rebuilt from its copy in {last}" in line for line in said), said


def test_a_deleted_meta_json_with_records_that_carry_no_copy_is_refused(whole, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    _strip_meta_copies(out)
    (out / "checkpoint" / "meta.json").unlink()
    with pytest.raises(ConfigError, match=r"meta.json is missing and no record carries .* --overwrite") as err:
        optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert "\n" not in str(err.value) and not (out / "checkpoint" / "meta.json").exists()


def test_a_damaged_history_is_rebuilt_on_resume(whole, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    (out / "history.json").write_text("[{")
    optimize(_small(), "mma", OPTIONS, out=out, resume=True, outputs=QUIET)
    assert _objectives(out) == _objectives(whole[0])


# ------------------------------------------------------------------------ a failed first analysis
@pytest.mark.parametrize("normalize, design", [("full", "the full design"), ("none", "design evaluation 0")])
def test_a_failed_first_analysis_writes_its_last_converged_state(normalize, design, tmp_path):
    """A traction the design cannot carry: the full design (the reference solve) or, without
    normalization, the initial grey design fails. Its last converged load step is written."""
    import meshio

    out = tmp_path / "run"
    with pytest.raises(ConvergenceError) as err:
        optimize(_small(load=10.0, normalize=normalize), "mma", OPTIONS, out=out, outputs=QUIET)
    message, last = str(err.value), err.value.last_state
    assert message.startswith(f"the analysis of {design}") and "\n" not in message
    assert str(out / "design.pvd") in message and "summary.json" in message and "without --overwrite" in message
    assert last is not None and 0.0 < last.t < 1.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["failed_analysis"]["design"].startswith(design)
    state = summary["failed_analysis"]["last_converged_state"]
    assert state["load_factor"] == pytest.approx(last.t) and state["files"] == ["vtu/beam_0000.vtu"]
    u = meshio.read(out / state["files"][0]).point_data["displacement"]
    np.testing.assert_allclose(u.ravel(), np.asarray(last.u), rtol=1e-12, atol=1e-300)
    # the directory holds no completed analysis: a plain run (no overwrite) may use it
    res = optimize(_small(), "mma", MMAOptions(max_iter=1), out=out, outputs=QUIET)
    assert res.iterations == 1 and json.loads((out / "summary.json").read_text())["status"] == "max_iter"
    assert not (out / "vtu").exists()  # the failed state went with the new run's fresh start


def test_a_failed_first_analysis_without_a_run_directory_keeps_its_state_in_the_error():
    with pytest.raises(ConvergenceError, match="^the analysis of the full design") as err:
        optimize(_small(load=10.0), "mma", OPTIONS)
    assert err.value.last_state is not None and "design.pvd" not in str(err.value)


def test_a_directory_with_completed_analyses_still_needs_overwrite(whole, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(whole[0], out)
    with pytest.raises(ConfigError, match="already holds a run"):
        optimize(_small(), "mma", OPTIONS, out=out, outputs=QUIET)


def test_resume_of_a_missing_directory_creates_nothing(tmp_path):
    with pytest.raises(ConfigError, match="nothing to resume in .*no such directory"):
        optimize(_small(), "mma", OPTIONS, out=tmp_path / "nowhere", resume=True)
    assert not (tmp_path / "nowhere").exists()


def test_a_file_system_without_locks_runs_unlocked_with_a_warning(tmp_path, monkeypatch, caplog):
    import fcntl

    def no_locks(fd, operation):
        raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    monkeypatch.setattr(fcntl, "flock", no_locks)
    with RunLock(tmp_path) as lock:
        assert lock.fd is not None
    assert any("cannot lock" in r.getMessage() and "would not be stopped" in r.getMessage() for r in caplog.records)


def test_ranks_other_than_0_draw_nothing(whole, tmp_path, monkeypatch):
    """Ranks > 0 of a distributed run write their copy of the results into a scratch directory
    (contopt.cli.distributed): the pictures, the design's surface and report.html, which need no
    other rank, are made by rank 0 alone. Here a serial run told it is rank 1."""
    from contopt.optimize import driver
    from contopt.parallel import Comm

    class RankOne(Comm):
        rank = 1

    class OnRankOne(driver.DesignNLP):
        def __init__(self, problem, pool=None):  # as design_nlp is called (no load cases here: no pool)
            super().__init__(problem)
            object.__setattr__(self.system.disc, "comm", RankOne())

    monkeypatch.setattr(driver, "design_nlp", OnRankOne)
    optimize(_small(), "mma", OPTIONS, out=tmp_path)
    drawn = {"convergence.png", "design.png", "deformed.png", "design.stl", "report.html"}
    assert drawn <= {p.name for p in whole[0].iterdir()}  # rank 0 (the serial run) makes them
    assert not drawn & {p.name for p in tmp_path.iterdir()}
    # the same run otherwise (the VTU and the summary, which may need every rank, are still written)
    np.testing.assert_allclose(_objectives(tmp_path), _objectives(whole[0]), rtol=1e-9)
    assert (tmp_path / "summary.json").is_file() and list((tmp_path / "vtu").glob("*.vtu"))
