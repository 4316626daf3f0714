"""A command under ``mpiexec -n N``: every rank runs it, rank 0 alone speaks and writes.

The ranks compute the same replicated run (see :mod:`contopt.parallel`); what differs:

* ranks 1..N-1 print nothing, log only errors and write their copy of the results into a
  private temporary directory (removed at the end) instead of ``--out`` (they write what may
  need every rank: output that needs the model, stresses say, is computed by all ranks together;
  the pictures, the design's surface and report.html only rank 0 makes); with
  ``--resume`` they start from a copy of ``--out`` taken before rank 0 touches it, so that every
  rank resumes from the same checkpoint;
* a rank that fails, or returns an error, aborts all of them with its message (the others would
  wait forever in the next collective operation).
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from contopt.cli.exits import exit_status
from contopt.errors import ContoptError
from contopt.parallel import abort_on_error, world


def run(args, command: Callable[[object], int]) -> int:
    """``command(args)`` on every rank of this run (directly when there is one)."""
    try:
        comm = world()
    except ContoptError as e:  # launched by mpiexec without MPI for Python
        print(f"contopt: error: {e}", file=sys.stderr)
        return exit_status(e)
    if not comm.distributed:
        return command(args)
    private = None
    with abort_on_error(comm):
        if comm.rank > 0:
            private = _private_out(args, comm.rank)
            logging.getLogger().setLevel(logging.ERROR)
        comm.barrier()  # the copies for --resume are taken before rank 0 writes
        try:
            with _quiet(comm.rank > 0):
                code = command(args)
        finally:
            if private is not None:
                shutil.rmtree(private, ignore_errors=True)
        if code != 0:
            print(f"contopt rank {comm.rank}: exit {code}; stopping all {comm.size} ranks", file=sys.stderr)
            sys.stderr.flush()
            comm.abort(code)
        comm.barrier()
    return code


def _private_out(args, rank: int) -> Path | None:
    """Point ``args.out`` of a rank > 0 at a private copy (what --resume reads) or an empty directory."""
    if not getattr(args, "out", None) or args.out == "-":
        return None
    private = Path(tempfile.mkdtemp(prefix=f"contopt-rank{rank}-"))
    target = private / "out"
    if getattr(args, "resume", False) and Path(args.out).is_dir():
        shutil.copytree(args.out, target)
    args.out = str(target)
    return private


@contextlib.contextmanager
def _quiet(quiet: bool):
    if not quiet:
        yield
        return
    with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
        yield
