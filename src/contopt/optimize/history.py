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
from contopt.optimize.problem import Record

log = logging.getLogger(__name__)

_SCALARS = ("index", "f", "objective", "newton_iterations", "alm_updates", "newton_solves", "cold")
_ARRAYS = ("x", "g", "df", "dg", "volume_fractions", "u")


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that a reader (or a crash) sees the old file or the new one."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def _record_bytes(rec: Record) -> bytes:
    arrays = {k: np.asarray(getattr(rec, k)) for k in _ARRAYS}
    arrays.update({k: np.asarray(getattr(rec, k)) for k in _SCALARS})
    for i, (lam, p) in enumerate(zip(rec.multipliers, rec.pressures)):
        arrays[f"multipliers_{i}"], arrays[f"pressures_{i}"] = np.asarray(lam), np.asarray(p)
    arrays["eps"] = np.asarray(rec.eps, dtype=np.float64)
    arrays["n_interfaces"] = np.asarray(len(rec.multipliers))
    arrays["responses"] = np.asarray(json.dumps(rec.responses))
    arrays["seconds"] = np.asarray(json.dumps(rec.seconds))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _record_from(data) -> Record:
    kw = {k: data[k].copy() for k in _ARRAYS}
    kw.update(index=int(data["index"]), f=float(data["f"]), objective=float(data["objective"]),
              newton_iterations=int(data["newton_iterations"]), alm_updates=int(data["alm_updates"]),
              newton_solves=int(data["newton_solves"]), cold=bool(data["cold"]))
    n = int(data["n_interfaces"])
    kw["multipliers"] = tuple(data[f"multipliers_{i}"].copy() for i in range(n))
    kw["pressures"] = tuple(data[f"pressures_{i}"].copy() for i in range(n))
    kw["eps"] = tuple(float(e) for e in data["eps"])
    kw["responses"] = json.loads(str(data["responses"]))
    kw["seconds"] = json.loads(str(data["seconds"]))
    return Record(**kw)


class Checkpoint:
    """The checkpoint of one run directory (see the module docstring)."""

    def __init__(self, directory: str | os.PathLike):
        self.root = Path(directory)
        self.dir = self.root / "checkpoint"

    @property
    def meta_path(self) -> Path:
        return self.dir / "meta.json"

    def exists(self) -> bool:
        return self.meta_path.exists()

    def record_path(self, index: int) -> Path:
        return self.dir / f"eval_{index:05d}.npz"

    def start(self, fingerprint: dict, resume: bool, overwrite: bool = False) -> dict:
        """Prepare the directory; returns the stored meta (``{}`` for a fresh run).

        A fresh run refuses a directory that holds another run unless ``overwrite``;
        a resume refuses a checkpoint of a different problem.
        """
        if resume:
            if not self.exists():
                raise ConfigError(f"nothing to resume in {self.root}: no checkpoint/meta.json there; "
                                  "start the run without --resume")
            meta = json.loads(self.meta_path.read_text())
            stored = meta.get("fingerprint", {})
            diff = sorted(k for k in set(stored) | set(fingerprint) if stored.get(k) != fingerprint.get(k))
            if diff:
                raise ConfigError(
                    f"the checkpoint in {self.root} belongs to a different run (differs in: {', '.join(diff)}); "
                    "resume with the same case and options, or start a new run in another directory"
                )
            return meta
        if self.exists() and not overwrite:
            raise ConfigError(f"{self.root} already holds a run; continue it with --resume, choose another "
                              "output directory, or pass --overwrite to start again")
        try:
            if self.dir.exists():
                shutil.rmtree(self.dir)
            self.dir.mkdir(parents=True)
            self.write_meta({"fingerprint": fingerprint})
        except OSError as err:
            raise ConfigError(f"cannot write the run directory {self.root}: {err}; choose another --out") from err
        return {}

    def write_meta(self, meta: dict) -> None:
        atomic_write_text(self.meta_path, json.dumps(meta, indent=1, sort_keys=True))

    def update_meta(self, **items) -> None:
        meta = json.loads(self.meta_path.read_text())
        meta.update(items)
        self.write_meta(meta)

    def save(self, rec: Record) -> None:
        atomic_write_bytes(self.record_path(rec.index), _record_bytes(rec))

    def records(self) -> list[Record]:
        """The stored evaluations 0, 1, ... up to the first missing or unreadable one."""
        out = []
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
    path = Path(root) / "history.json"
    return json.loads(path.read_text()) if path.exists() else []
