"""Exceptions a user can meet. Each message names the problem and what to do."""

from __future__ import annotations


class ContoptError(Exception):
    """Base class of every error contopt raises on purpose."""


class MeshError(ContoptError, ValueError):
    """Invalid mesh: inverted/degenerate element, unknown or non-boundary set."""


class ConfigError(ContoptError, ValueError):
    """A bad option or model description (names the key and the allowed values)."""


class OutputError(ContoptError, OSError):
    """A result could not be written (disk full, no permission); the message names the file.

    Whoever writes leaves no temporary behind; the run that catches it adds what was kept.
    ``errno`` is that of the operating system's error (e.g. ``errno.ENOSPC``), or None.
    """

    def __init__(self, message: str, errno: int | None = None):
        super().__init__(message)
        self.errno = errno

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class LinearSolverError(ContoptError, RuntimeError):
    """A sparse factorization or solve failed (singular matrix, missing backend)."""


class UnavailableSolverError(LinearSolverError, ConfigError):
    """The linear solver asked for cannot run here (not installed, or not in a distributed run): a usage
    error, the message names what is available. Still a LinearSolverError for whoever catches those."""


class WorkerError(ContoptError, RuntimeError):
    """A worker process (the load cases' ``case_workers``) ended without its result: killed, or out
    of memory. The message names the worker and what to run instead."""


class ConvergenceError(ContoptError, RuntimeError):
    """Newton could not converge even at the minimum load step.

    Attributes
    ----------
    logs : list of NewtonLog of every attempted step (converged or not)
    last_state : the last converged State (load factor, displacement), never lost
    """

    def __init__(self, message: str, logs=None, last_state=None):
        super().__init__(message)
        self.logs = list(logs or [])
        self.last_state = last_state
