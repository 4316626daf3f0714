"""contopt.timing: the one helper that adds a phase's seconds to a tally."""

import time

import pytest

from contopt.timing import Stopwatch, add, timed


class _Tally:
    def __init__(self):
        self.scatter = 1.0


def test_timed_adds_to_a_key_or_an_attribute_also_when_the_block_raises():
    seconds = {"solve": 2.0}
    with timed(seconds, "solve"):
        time.sleep(0.01)
    with timed(seconds, "factorize") as clock:  # a missing key counts from 0
        pass
    assert 2.01 <= seconds["solve"] < 3.0 and 0.0 <= seconds["factorize"] == pytest.approx(clock.seconds, abs=0.1)
    tally = _Tally()
    with pytest.raises(ValueError), timed(tally, "scatter"):
        raise ValueError
    assert tally.scatter >= 1.0
    add(tally, "scatter", 0.5)
    assert tally.scatter >= 1.5


def test_a_stopwatch_reads_the_seconds_since_it_started():
    clock = Stopwatch()
    time.sleep(0.01)
    first = clock.seconds
    assert 0.01 <= first <= clock.seconds
