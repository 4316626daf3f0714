"""What ``contopt run`` shows while it works: stamped lines, a live status line in a terminal,
the iteration lines with the time left."""

from __future__ import annotations

import logging
import sys

from contopt.timing import Stopwatch

#: durations beyond this are shown as "> 99 days" (an ETA to a huge --max-iter says nothing more)
LONGEST = 100 * 86400


def duration(seconds: float) -> str:
    """``12m05s``, ``5h03m``, ``3d04h``; ``> 99 days`` beyond (or for an infinite or undefined time)."""
    if not seconds < LONGEST:  # also nan and inf
        return "> 99 days"
    seconds = int(round(max(seconds, 0.0)))
    d, rem = divmod(seconds, 86400)
    h, rem = divmod(rem, 3600)
    if d:
        return f"{d}d{h:02d}h"
    return f"{h}h{rem // 60:02d}m" if h else f"{rem // 60}m{rem % 60:02d}s"


def progress_line(row: dict, eta: float, max_iter: int) -> str:
    cons = " ".join(f"{v:+.2e}" for v in row["constraints"].values())
    opt = row.get("optimality", float("nan"))
    head = (
        f"it {row['iteration']:3d}/{max_iter}  f {row['objective']:.6g}  g [{cons}]  "
        f"opt {opt:.2e}  Newton {row['newton_iterations']:2d}  "
    )
    if row.get("cases"):  # each load case's objective
        head += "cases [" + " ".join(f"{k} {v:.4g}" for k, v in row["cases"].items()) + "]  "
    if row.get("replayed"):
        return head + "replayed from the checkpoint"
    return head + f"{row['seconds']['iteration']:.1f} s/it  {eta_text(eta)}"


class Progress:
    """What `contopt run` shows while it works: a line per step (the progress log's messages and the
    iteration lines), each with the time since the start. Where the terminal is interactive, a live
    line below them (rich) says what is running now and for how long; elsewhere plain lines only."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stdout
        self.clock = Stopwatch()
        self.console = self.status = None
        if self.stream.isatty():
            from rich.console import Console

            self.console = Console(file=self.stream, highlight=False)
            self.status = self.console.status("starting")
            self.status.start()

    def line(self, text: str, now: str | None = None) -> None:
        stamped = f"[{self.clock.seconds:7.1f} s] {text}"
        if self.console is None:
            print(stamped, file=self.stream, flush=True)
            return
        self.console.print(stamped, markup=False)
        assert self.status is not None  # made with the console
        self.status.update(now or text.strip())

    def stop(self) -> None:
        if self.status is not None:
            self.status.stop()


class ProgressHandler(logging.Handler):
    """The progress log (``contopt.progress``) onto a :class:`Progress`."""

    def __init__(self, progress: Progress):
        super().__init__(logging.INFO)
        self.progress = progress

    def emit(self, record: logging.LogRecord) -> None:
        self.progress.line(record.getMessage())


def eta_text(seconds: float) -> str:
    """``ETA <= 3m05s`` (at most: the run may stop before max_iter), or ``ETA > 99 days``."""
    return f"ETA <= {duration(seconds)}" if seconds < LONGEST else "ETA > 99 days"


def setup_logging(verbose: int) -> None:
    level = logging.WARNING if verbose < 0 else (logging.INFO if verbose == 0 else logging.DEBUG)
    logging.basicConfig(level=level, format="%(message)s", stream=sys.stderr)
    for noisy in ("jax", "absl"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    for handler in logging.getLogger().handlers:
        handler.addFilter(OncePerInterface())


class OncePerInterface(logging.Filter):
    """Lets through the first coarse-side warning of each contact interface (every design's analysis
    measures it again: one line says it)."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        if "which is the coarse side" not in message:
            return True
        label = message.split(":", 1)[0]
        if label in self.seen:
            return False
        self.seen.add(label)
        return True
