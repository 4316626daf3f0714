"""Wall-clock seconds of the solver's phases: one helper in place of hand-threaded ``perf_counter`` pairs.

* :func:`timed` adds the seconds a ``with`` block takes to a tally's phase: a dict's key
  (``{"factorize": 0.0, ...}``, a missing key counts from 0) or an object's attribute (a
  :class:`~contopt.assembly.system.Timings`)::

      with timed(seconds, "factorize"):
          factor = factorize(K, linear)

* :class:`Stopwatch` reads the seconds since it started, for a time that is returned or stored
  rather than added (a factorization's ``seconds``, a phase with a sub-phase taken out)::

      clock = Stopwatch()
      ...
      factor.seconds = clock.seconds
"""

from __future__ import annotations

import time
from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
from typing import Any


class Stopwatch:
    """Started at construction; :attr:`seconds` is the wall-clock time since (``time.perf_counter``)."""

    __slots__ = ("start",)

    def __init__(self) -> None:
        self.start = time.perf_counter()

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self.start


def add(tally: MutableMapping[str, float] | Any, phase: str, seconds: float) -> None:
    """Add ``seconds`` to ``tally``'s ``phase``: a mapping's key (from 0 when missing) or an attribute."""
    if isinstance(tally, MutableMapping):
        tally[phase] = tally.get(phase, 0.0) + seconds
    else:
        setattr(tally, phase, getattr(tally, phase) + seconds)


@contextmanager
def timed(tally: MutableMapping[str, float] | Any, phase: str) -> Iterator[Stopwatch]:
    """Add the seconds the ``with`` block takes to ``tally``'s ``phase`` (:func:`add`), also when it
    raises; yields the block's :class:`Stopwatch`."""
    clock = Stopwatch()
    try:
        yield clock
    finally:
        add(tally, phase, clock.seconds)
