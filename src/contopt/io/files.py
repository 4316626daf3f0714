"""Files written whole or not at all, and write errors that name the file.

Every result file is written under a temporary name in its own folder
(``.<stem>.tmp<suffix>``, hidden, with the same suffix so that writers that
infer the format from it still work) and renamed into place, so a reader, a
crash or ``kill -9`` sees the old file or the new one, never half of one. When
the write fails (a full disk, no permission) the temporary is removed and an
:class:`~contopt.errors.OutputError` names the file and the reason.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from contopt.errors import OutputError


def temporary_name(path: str | os.PathLike) -> Path:
    """The hidden temporary that :func:`write_atomically` writes before renaming it to ``path``."""
    path = Path(path)
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


def output_error(path: str | os.PathLike, err: OSError) -> OutputError:
    """An :class:`OutputError` "cannot write PATH: REASON" for the OSError ``err``."""
    if isinstance(err, OutputError):
        return err
    reason = err.strerror or str(err) or type(err).__name__
    return OutputError(f"cannot write {path}: {reason}", getattr(err, "errno", None))


def _remove(path: Path) -> None:
    try:
        path.unlink()
    except FileNotFoundError:
        pass
    except OSError:  # nothing more can be done about a temporary that cannot be removed
        pass


def write_atomically(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` to write the temporary of ``path`` (what it returns is ignored), then rename it to ``path``.

    Raises :class:`OutputError` (temporary removed) when ``write`` or the rename fails with an
    OSError; other exceptions pass unchanged, also after removing the temporary.
    """
    path = Path(path)
    tmp = temporary_name(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as err:
        _remove(tmp)
        raise output_error(path, err) from err
    except BaseException:
        _remove(tmp)
        raise
    return path


def write_bytes_durably(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and flushed to the disk (``fsync``) before the rename."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())

    return write_atomically(path, write)
