"""One writer per run directory: an exclusive lock held for the life of a run.

A run takes ``fcntl.flock(LOCK_EX | LOCK_NB)`` on ``DIR/.lock`` before it
touches anything in the directory and keeps it until it returns or raises. The
operating system releases the lock when the process ends in any way (``kill -9``
included), so a stale lock file never blocks a later run, and the file itself is
never removed (removing it would let two runs lock two different files). The
holder writes its PID, host and start time into the file; a second writer reads
them for its error message. Where ``fcntl`` does not exist (Windows) runs are
not locked; on a file system that refuses locks (some network mounts) a run
goes on unlocked after a warning.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import socket
import time
from pathlib import Path
from types import ModuleType

from contopt.errors import ConfigError

fcntl: ModuleType | None  # None where the platform has none: the run directory is not locked there
try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

log = logging.getLogger(__name__)

LOCK_NAME = ".lock"


def _holder(fd: int) -> str:
    """Who holds the lock, as its holder wrote it into the lock file ("PID 123 on host, since ...")."""
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
        pid = int(info["pid"])
    except (OSError, ValueError, KeyError, TypeError):  # the holder has not written it yet
        return "PID unknown"
    where = f" on {info['host']}" if info.get("host") and info["host"] != socket.gethostname() else ""
    since = f", running since {info['started']}" if info.get("started") else ""
    return f"PID {pid}{where}{since}"


class RunLock:
    """The exclusive lock of a run directory (see the module docstring); a context manager.

    ``RunLock(DIR).acquire()`` creates DIR if needed and raises :class:`ConfigError` naming the
    PID of the holder when another process holds it (or when DIR cannot be created).
    """

    def __init__(self, directory: str | os.PathLike):
        self.root = Path(directory)
        self.path = self.root / LOCK_NAME
        self.fd: int | None = None

    def acquire(self) -> RunLock:
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise ConfigError(
                f"cannot write the run directory {self.root}: {err.strerror or err}; choose another --out"
            ) from err
        if fcntl is None:  # pragma: no cover
            self.fd = fd
            return self
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                # a file system without locks (some network mounts): run, but say it is unprotected
                log.warning(
                    "cannot lock %s (%s); another run of this directory would not be stopped",
                    self.path,
                    err.strerror or err,
                )
                self.fd = fd
                return self
            holder = _holder(fd)
            os.close(fd)
            raise ConfigError(
                f"{self.root} is in use by another run ({holder}); wait for it to end, stop it, or choose another --out"
            ) from err
        self.fd = fd
        self._write_holder()
        return self

    def _write_holder(self) -> None:
        """Our PID into the lock file, for the message of a second writer (best effort: a full disk
        must not stop a run that holds its lock)."""
        info = json.dumps(
            {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S")}
        )
        assert self.fd is not None  # acquire calls this once it holds the lock file open
        try:
            os.ftruncate(self.fd, 0)
            os.pwrite(self.fd, info.encode(), 0)
        except OSError as err:
            log.debug("cannot write %s: %s", self.path, err)

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            os.ftruncate(self.fd, 0)  # no stale PID for the next holder's few microseconds before it writes its own
            if fcntl is not None:
                fcntl.flock(self.fd, fcntl.LOCK_UN)
        except OSError as err:
            log.debug("releasing %s: %s", self.path, err)
        finally:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
