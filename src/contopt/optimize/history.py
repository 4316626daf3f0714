"""Checkpoints that survive ``kill -9``, and the iteration history.

A run directory holds::

    checkpoint/meta.json           what was run (a fingerprint) and the objective scale
    checkpoint/eval_00000.npz ...  one file per design evaluation (x, values, gradients, state)
    history.json, history.csv      one row per optimizer iteration

Every file is written to a temporary name, flushed to disk and renamed into
place, so a run killed at any moment leaves whole files only. Resuming
replays the optimizer from the start: it asks for the same designs (the
optimizers are deterministic), the recorded evaluations answer them without
solving, and the run goes on from the last one with the same warm start. The
iterates therefore match an uninterrupted run.

A write that fails (a full disk) removes its temporary and raises
:class:`~contopt.errors.OutputError`; the files already there stay whole, so
the run can be resumed once there is space. A damaged record ends the usable
prefix (it is renamed ``.damaged``); a damaged ``meta.json`` is renamed
``meta.json.damaged`` and rebuilt from the copy every record carries, and so is a
deleted one (:meth:`Checkpoint.restore_meta`).
"""

from __future__ import annotations

import csv
import io
import json
import logging
import os
import shutil
from pathlib import Path

import numpy as np

from contopt.errors import ConfigError
from contopt.io.files import write_bytes_durably
from contopt.optimize.load_case import CaseStart
from contopt.optimize.problem import Record

log = logging.getLogger(__name__)

_SCALARS = ("index", "f", "objective", "newton_iterations", "alm_updates", "newton_solves", "cold")
_ARRAYS = ("x", "g", "df", "dg", "volume_fractions", "u")


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that a reader (or a crash) sees the old file or the new one.

    A failure (e.g. a full disk) removes the temporary and raises :class:`~contopt.errors.OutputError`.
    """
    write_bytes_durably(path, data)


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def _record_bytes(rec: Record, meta: dict | None = None) -> bytes:
    """The ``.npz`` bytes of a record, with a copy of the checkpoint's ``meta`` (JSON) when given."""
    arrays = {k: np.asarray(getattr(rec, k)) for k in _ARRAYS}
    arrays.update({k: np.asarray(getattr(rec, k)) for k in _SCALARS})
    for i, (lam, p) in enumerate(zip(rec.multipliers, rec.pressures)):
        arrays[f"multipliers_{i}"], arrays[f"pressures_{i}"] = np.asarray(lam), np.asarray(p)
    arrays["eps"] = np.asarray(rec.eps, dtype=np.float64)
    arrays["n_interfaces"] = np.asarray(len(rec.multipliers))
    arrays["n_cases"] = np.asarray(len(rec.cases))
    for c, case in enumerate(rec.cases):  # each load case's state: its warm start after a resume
        arrays[f"case_{c}_u"], arrays[f"case_{c}_eps"] = np.asarray(case.u), np.asarray(case.eps, dtype=np.float64)
        for i, (lam, p) in enumerate(zip(case.multipliers, case.pressures)):
            arrays[f"case_{c}_multipliers_{i}"], arrays[f"case_{c}_pressures_{i}"] = np.asarray(lam), np.asarray(p)
    arrays["responses"] = np.asarray(json.dumps(rec.responses))
    arrays["seconds"] = np.asarray(json.dumps(rec.seconds))
    if meta is not None:
        arrays["meta"] = np.asarray(json.dumps(meta, sort_keys=True))
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]  # numpy's stub matches **arrays to allow_pickle: bool
    return buf.getvalue()


def _record_from(data) -> Record:
    kw = {k: data[k].copy() for k in _ARRAYS}
    kw.update(
        index=int(data["index"]),
        f=float(data["f"]),
        objective=float(data["objective"]),
        newton_iterations=int(data["newton_iterations"]),
        alm_updates=int(data["alm_updates"]),
        newton_solves=int(data["newton_solves"]),
        cold=bool(data["cold"]),
    )
    n = int(data["n_interfaces"])
    kw["multipliers"] = tuple(data[f"multipliers_{i}"].copy() for i in range(n))
    kw["pressures"] = tuple(data[f"pressures_{i}"].copy() for i in range(n))
    kw["eps"] = tuple(float(e) for e in data["eps"])
    kw["responses"] = json.loads(str(data["responses"]))
    kw["seconds"] = json.loads(str(data["seconds"]))
    kw["cases"] = tuple(
        CaseStart(
            u=data[f"case_{c}_u"].copy(),
            multipliers=tuple(data[f"case_{c}_multipliers_{i}"].copy() for i in range(n)),
            eps=tuple(float(e) for e in data[f"case_{c}_eps"]),
            pressures=tuple(data[f"case_{c}_pressures_{i}"].copy() for i in range(n)),
        )
        for c in range(int(data["n_cases"]) if "n_cases" in data else 0)  # records of earlier releases: none
    )
    return Record(**kw)


class Checkpoint:
    """The checkpoint of one run directory (see the module docstring).

    ``meta`` (what was run, the objective scale) is kept in memory, written to ``meta.json`` and
    copied into every record, so a damaged or deleted ``meta.json`` can be rebuilt from the records.
    """

    def __init__(self, directory: str | os.PathLike):
        self.root = Path(directory)
        self.dir = self.root / "checkpoint"
        self.meta: dict = {}

    @property
    def meta_path(self) -> Path:
        return self.dir / "meta.json"

    def exists(self) -> bool:
        return self.meta_path.exists()

    def has_records(self) -> bool:
        """Does the checkpoint hold a completed analysis (a record file)?"""
        return self.dir.is_dir() and any(self.dir.glob("eval_*.npz"))

    def record_path(self, index: int) -> Path:
        return self.dir / f"eval_{index:05d}.npz"

    def start(self, fingerprint: dict, resume: bool, overwrite: bool = False) -> dict:
        """Prepare the directory; returns the stored meta (``{}`` for a fresh run).

        A fresh run refuses a directory that holds another run's analyses unless ``overwrite``
        (one that holds none, e.g. after a failed first analysis, is simply started again);
        a resume refuses a checkpoint of a different problem.
        """
        if resume:
            if not self.restore_meta():
                if self.has_records():
                    raise ConfigError(
                        f"cannot resume {self.root}: checkpoint/meta.json is missing and no record carries a "
                        "readable copy of it; start again with --overwrite or in another directory"
                    )
                raise ConfigError(
                    f"nothing to resume in {self.root}: no checkpoint/meta.json there; start the run without --resume"
                )
            meta = self._stored_meta(fingerprint)
            stored = meta.get("fingerprint", {})
            diff = sorted(k for k in set(stored) | set(fingerprint) if stored.get(k) != fingerprint.get(k))
            if diff:
                raise ConfigError(
                    f"the checkpoint in {self.root} belongs to a different run (differs in: {', '.join(diff)}); "
                    "resume with the same case and options, or start a new run in another directory"
                )
            self.meta = dict(meta)
            return meta
        if self.has_records() and not overwrite:
            raise ConfigError(
                f"{self.root} already holds a run; continue it with --resume, choose another "
                "output directory, or pass --overwrite to start again"
            )
        try:
            if self.dir.exists():
                shutil.rmtree(self.dir)
            self.dir.mkdir(parents=True)
            self.write_meta({"fingerprint": fingerprint})
        except OSError as err:
            raise ConfigError(f"cannot write the run directory {self.root}: {err}; choose another --out") from err
        return {}

    def _stored_meta(self, fingerprint: dict) -> dict:
        """``meta.json``, or when it is damaged (kept as ``meta.json.damaged``): its copy in the
        records, or a fresh one when no analysis was recorded."""
        try:
            meta = json.loads(self.meta_path.read_text())
            if isinstance(meta, dict) and isinstance(meta.get("fingerprint"), dict):
                return meta
            damage = "it holds no fingerprint of the run"
        except (OSError, ValueError) as err:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
            damage = f"{type(err).__name__}: {err}"
        kept = self.meta_path.with_name("meta.json.damaged")
        self.meta_path.replace(kept)
        what = f"{self.meta_path} is damaged ({damage}); it was kept as {kept.name}"
        if not self.has_records():
            log.warning("%s; no analysis was recorded, so the run starts from the beginning", what)
            self.write_meta({"fingerprint": fingerprint})
            return dict(self.meta)
        copy, source = self._meta_copy()
        if copy is None:
            raise ConfigError(
                f"{what}, and no record carries a readable copy of it, so the recorded analyses "
                "cannot be checked against this run; start again with --overwrite or in another directory"
            )
        log.warning("%s and was rebuilt from its copy in %s", what, source)
        self.write_meta(copy)
        return dict(copy)

    def restore_meta(self) -> bool:
        """Rebuild a missing ``meta.json`` from the copy the records carry (logged); is there one now?

        A run directory whose ``meta.json`` was deleted keeps its records reachable: ``--resume``,
        ``contopt report`` and ``export-design`` call this first. False when there is no record with
        a readable copy (then there is no run to restore).
        """
        if self.exists():
            return True
        if not self.has_records():
            return False
        copy, source = self._meta_copy()
        if copy is None:
            return False
        self.write_meta(copy)
        log.warning(
            "%s was missing; rebuilt from its copy in %s (%d recorded analyses)",
            self.meta_path,
            source,
            len(list(self.dir.glob("eval_*.npz"))),
        )
        return True

    def _meta_copy(self) -> tuple[dict | None, str]:
        """The copy of ``meta.json`` in the latest record that has a readable one, and that record's name
        ((None, "") when none has: records written before they carried copies, or all damaged)."""
        for path in sorted(self.dir.glob("eval_*.npz"), reverse=True):
            try:
                with np.load(path, allow_pickle=False) as data:
                    meta = json.loads(str(data["meta"])) if "meta" in data.files else None
            except Exception as err:  # a damaged record is no copy
                log.debug("no copy of meta.json in %s: %s", path, err)
                continue
            if isinstance(meta, dict) and isinstance(meta.get("fingerprint"), dict):
                return meta, path.name
        return None, ""

    def write_meta(self, meta: dict) -> None:
        atomic_write_text(self.meta_path, json.dumps(meta, indent=1, sort_keys=True))
        self.meta = dict(meta)

    def update_meta(self, **items) -> None:
        self.write_meta({**self.meta, **items})

    def save(self, rec: Record) -> None:
        atomic_write_bytes(self.record_path(rec.index), _record_bytes(rec, self.meta))

    def records(self) -> list[Record]:
        """The stored evaluations 0, 1, ... up to the first missing or unreadable one."""
        out: list[Record] = []
        while self.record_path(len(out)).exists():
            path = self.record_path(len(out))
            try:
                with np.load(path, allow_pickle=False) as data:
                    out.append(_record_from(data))
            except Exception as err:  # a damaged file ends the usable prefix (kept for inspection)
                log.warning("checkpoint %s is unreadable (%s); resuming from the evaluations before it", path, err)
                path.rename(path.with_suffix(".damaged"))
                break
        return out


def flatten_row(row: dict) -> dict:
    """A history row with nested dicts flattened to ``key.sub`` columns (for CSV)."""
    out = {}
    for k, v in row.items():
        if isinstance(v, dict):
            out.update({f"{k}.{kk}": vv for kk, vv in v.items()})
        else:
            out[k] = v
    return out


def write_history(root: Path, rows: list[dict]) -> None:
    """``history.json`` and ``history.csv`` (one row per iteration), each written atomically."""
    atomic_write_text(root / "history.json", json.dumps(rows, indent=1))
    flat = [flatten_row(r) for r in rows]
    columns = list(dict.fromkeys(k for r in flat for k in r))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns)
    writer.writeheader()
    writer.writerows(flat)
    atomic_write_text(root / "history.csv", buf.getvalue())


def read_history(root: str | os.PathLike) -> list[dict]:
    """The rows of ``history.json`` (``[]`` when there is none, or when it is damaged: a resumed run
    rebuilds them from the checkpoint)."""
    path = Path(root) / "history.json"
    if not path.exists():
        return []
    try:
        rows = json.loads(path.read_text())
    except ValueError as err:
        log.warning("%s is damaged (%s); the history is rebuilt from the checkpoint's records", path, err)
        return []
    return rows if isinstance(rows, list) else []
