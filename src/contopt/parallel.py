"""Distributed runs: the communicator every layer reads, serial unless the process runs under MPI.

``mpiexec -n N contopt ...`` starts N copies of the same program. What they share, and how:

* every rank holds the whole model, the state ``u``, the contact pairing, the design and the
  optimizer (replicated: they are small next to the element work and the linear solve);
* the cells of every body are split into N contiguous ranges (:func:`cell_range`); a rank runs
  the element kernels of its range only, and what the kernels give (residual, energy, design
  derivatives) is summed over the ranks (:meth:`Comm.sum`) into the same replicated result on
  every rank;
* the tangent is never summed: each rank keeps the part its cells (and, on rank 0, the contact
  and the supports) contribute, and the iterative solver adds the parts up in a distributed
  PETSc matrix (:mod:`contopt.solve.linear.petsc`);
* sums are a reduction to rank 0 followed by a broadcast, so every rank gets bitwise the same
  numbers and the replicated Newton iterations, line searches and optimizer steps never drift;
* rank 0 writes; a rank that fails aborts the job (:func:`abort_on_error`), never a hang.

Without MPI (or with one rank) :data:`SERIAL` is the communicator and nothing here imports mpi4py.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from contopt.errors import ConfigError

#: environment variables that MPI launchers set: (variable, launcher)
_SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "MPI_LOCALNRANKS")


class Comm:
    """A communicator: ``rank``, ``size`` and the few collective operations contopt needs."""

    rank = 0
    size = 1

    @property
    def distributed(self) -> bool:
        return self.size > 1

    def sum(self, x):
        """The sum over the ranks of ``x`` (a float or an array), the same bits on every rank."""
        return x

    def all(self, flag: bool) -> bool:
        """True when ``flag`` is True on every rank."""
        return bool(flag)

    def bcast(self, obj: Any) -> Any:
        """Rank 0's ``obj`` on every rank."""
        return obj

    def barrier(self) -> None:
        """Wait until every rank is here."""

    def abort(self, code: int = 1) -> None:
        sys.exit(code)


#: the communicator of a process that runs alone
SERIAL = Comm()


class MPIComm(Comm):
    """:class:`Comm` over an mpi4py communicator."""

    def __init__(self, comm):
        self._comm = comm
        self.rank = comm.Get_rank()
        self.size = comm.Get_size()

    @property
    def mpi(self):
        """The mpi4py communicator."""
        return self._comm

    def sum(self, x):
        from mpi4py import MPI

        if np.isscalar(x) or np.ndim(x) == 0:
            total = np.zeros(1) if self.rank == 0 else None
            self._comm.Reduce(np.array([float(x)]), total, op=MPI.SUM, root=0)
            return float(self._comm.bcast(None if total is None else total[0], root=0))
        x = np.ascontiguousarray(x, dtype=np.float64)
        out = np.empty_like(x)
        self._comm.Reduce(x, out if self.rank == 0 else None, op=MPI.SUM, root=0)
        self._comm.Bcast(out, root=0)
        return out

    def all(self, flag: bool) -> bool:
        from mpi4py import MPI

        return bool(self._comm.allreduce(bool(flag), op=MPI.LAND))

    def bcast(self, obj: Any) -> Any:
        return self._comm.bcast(obj, root=0)

    def barrier(self) -> None:
        self._comm.Barrier()

    def abort(self, code: int = 1) -> None:
        # the launcher forwards a rank's output asynchronously and drops what is still in transit
        # when it tears the job down: give the message the time to get out (seen lost without)
        sys.stderr.flush()
        time.sleep(0.5)
        self._comm.Abort(code)


def launched_size() -> int:
    """The number of ranks an MPI launcher started this process among (1 when none did)."""
    for name in _SIZE_VARIABLES:
        value = os.environ.get(name, "")
        if value.isdigit():
            return int(value)
    return 1


def preload_mpi() -> None:
    """Load the MPI library that pip's ``mpich`` puts in ``<prefix>/lib`` (not on the loader's path)."""
    for path in sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmpi.so.*")), key=len):
        try:
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            return
        except OSError:
            continue


@functools.cache
def world() -> Comm:
    """The communicator of this run: MPI's world when launched on several ranks, else :data:`SERIAL`."""
    if launched_size() <= 1:
        return SERIAL
    preload_mpi()
    try:
        from mpi4py import MPI
    except ImportError as exc:
        raise ConfigError(
            f"this process was started by an MPI launcher on {launched_size()} ranks but mpi4py cannot be "
            f"imported ({exc}); install the petsc extra (pip install contopt[petsc]) or run without mpiexec"
        ) from exc
    comm = MPIComm(MPI.COMM_WORLD)
    return comm if comm.size > 1 else SERIAL


def cell_range(n_cells: int, comm: Comm) -> slice:
    """The cells of a body (``n_cells`` of them) that ``comm.rank`` evaluates: one of ``size``
    contiguous ranges whose lengths differ by at most one."""
    base, extra = divmod(n_cells, comm.size)
    start = comm.rank * base + min(comm.rank, extra)
    return slice(start, start + base + (1 if comm.rank < extra else 0))


def node_range(n_nodes: int, comm: Comm) -> slice:
    """The nodes whose rows ``comm.rank`` owns in a distributed matrix (same split as :func:`cell_range`)."""
    return cell_range(n_nodes, comm)


@contextmanager
def abort_on_error(comm: Comm | None = None) -> Iterator[None]:
    """On several ranks, an exception on one of them prints its message and aborts every rank (the
    others would wait forever in the next collective operation)."""
    comm = comm or world()
    try:
        yield
    except SystemExit as exc:
        if comm.distributed and exc.code not in (0, None):
            print(f"contopt rank {comm.rank}: exit {exc.code}; stopping all {comm.size} ranks", file=sys.stderr)
            sys.stderr.flush()
            comm.abort(exc.code if isinstance(exc.code, int) else 1)
        raise
    except BaseException as exc:
        if comm.distributed:
            print(f"contopt rank {comm.rank} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
            print(f"stopping all {comm.size} ranks", file=sys.stderr)
            sys.stderr.flush()
            comm.abort(1)
        raise
