"""The exit statuses of the ``contopt`` command: one table, read by the command, its ``--help`` and the docs.

A script acts on the status: 0 done, 1 a check failed, 2 fix the command or the input, 3 the
analysis or the optimizer failed (change the problem or its options), 130 interrupted (Ctrl-C),
143 terminated (SIGTERM, what ``kill`` and batch schedulers send): 128 + the signal's number, as a
shell reports a process the signal ended, so that a scheduler's accounting reads the same either way.
"""

from __future__ import annotations

import textwrap

from contopt.config import (
    JAX_ADDRESS_SPACE,
    address_space_limit,
    format_gib,
)  # now: under `ulimit -v` a late import may fail
from contopt.errors import (
    ConfigError,
    ContoptError,
    ConvergenceError,
    LinearSolverError,
    MeshError,
    OutputError,
    WorkerError,
)

DONE = 0
CHECK_FAILED = 1
USAGE = 2
FAILED = 3
INTERRUPTED = 130
TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived: raised by the command's handler, so a run ends as on Ctrl-C (what was computed
    is kept, the lock released) and the command exits with :data:`TERMINATED`."""


#: status -> when the command ends with it (`contopt --help` and docs/cli.md show this table)
EXIT_STATUSES = {
    DONE: "done",
    CHECK_FAILED: "a check failed: check-gradient found a relative error above its tolerance",
    USAGE: "usage or input error: an unknown option, case or key, a bad value, a file that cannot be read "
    "or written (a one-line error says which and what to do)",
    FAILED: "the analysis or the optimizer failed (Newton, a linear solve, every trial design), it ran "
    "out of memory (the machine's or ulimit -v) or an unexpected error (a traceback: please report it); "
    "what converged is written",
    INTERRUPTED: "interrupted (Ctrl-C, SIGINT); what was computed is written, `contopt run --resume` continues",
    TERMINATED: "terminated (SIGTERM: kill, a batch scheduler's time limit); as for 130",
}

#: the errors a user causes through the command or the input (checked before FAILED's: a ConfigError wins)
_USAGE = (ConfigError, MeshError, OutputError)
#: the errors of an analysis or an optimizer that could not go on
_FAILED = (ConvergenceError, LinearSolverError, WorkerError)


def exit_status(error: BaseException) -> int:
    """The status the command ends with after ``error`` (one of :data:`EXIT_STATUSES`)."""
    if isinstance(error, Terminated):
        return TERMINATED
    if isinstance(error, KeyboardInterrupt):
        return INTERRUPTED
    if isinstance(error, _USAGE):
        return USAGE
    if not isinstance(error, ContoptError):  # MemoryError among them: decided before numpy is loaded
        return FAILED
    from contopt.optimize.base import EvaluationFailure  # numpy: loaded only once something failed

    if isinstance(error, (*_FAILED, EvaluationFailure)):
        return FAILED
    return USAGE  # any other error contopt raises on purpose names what to change


def out_of_memory(error: BaseException) -> str | None:
    """The one-line message for ``error`` when it is the process running out of memory: a MemoryError,
    an ImportError of a library that could not be mapped under ``ulimit -v``, or a SystemError under a
    limit too small for contopt to start; None otherwise."""
    limit = address_space_limit()
    bound = f"the address-space limit (ulimit -v) of {format_gib(limit)}" if limit else "the memory available"
    if isinstance(error, ImportError):
        text = " ".join(str(error).split())
        if limit is None or not any(s in text.lower() for s in ("map segment", "memory", "mmap")):
            return None  # a missing or broken package: its traceback says which
        what = f"cannot load {error.name or 'a library'} ({text})"
    elif isinstance(error, MemoryError):
        what = "out of memory"
    elif isinstance(error, SystemError) and limit is not None and limit < JAX_ADDRESS_SPACE:
        # the interpreter itself failing (compiling a module's bytecode) under a limit too small to start
        what = f"Python failed ({' '.join(str(error).split())[:120]})"
    else:
        return None
    if limit is not None and limit < JAX_ADDRESS_SPACE:  # too small to start, whatever the problem
        return (
            f"{what} under {bound}: contopt with JAX needs about {format_gib(JAX_ADDRESS_SPACE)} of address "
            "space to start; raise the limit (ulimit -v)"
        )
    return f"{what}: the command needed more than {bound} allows; use a coarser mesh or raise the limit"


def epilog() -> str:
    """The table of statuses as the last lines of ``contopt --help``."""
    rows = (
        textwrap.fill(text, 100, initial_indent=f"  {code:<4d} ", subsequent_indent=" " * 7)
        for code, text in EXIT_STATUSES.items()
    )
    return "exit status:\n" + "\n".join(rows)
