"""``jaxproj._internal.progress``: the heartbeat's lines and estimates, on a fake clock."""

import threading

import pytest

from jaxproj._internal.progress import Heartbeat, Rates, bar, duration, rate_left


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def _beat(every: float = 20.0) -> tuple[Heartbeat, Clock, list[str]]:
    clock, lines = Clock(), []
    return Heartbeat(every=every, clock=clock, emit=lines.append, start=False), clock, lines


def test_duration_and_rate():
    assert [duration(x) for x in (0.4, 45, 185, 7260)] == [
        "0 s",
        "45 s",
        "3 min 05 s",
        "2 h 01 min",
    ]
    assert rate_left(30.0, 3, 12) == pytest.approx(90.0)  # 10 s per unit, 9 units left
    assert rate_left(30.0, 0, 12) is None


def test_rates_turn_work_counts_into_seconds():
    r = Rates()
    assert r.estimate(("build", 2)) is None  # nothing measured: no estimate
    r.add("build", 60.0)
    r.add("build", 40.0)
    r.add("frame:relaxed", 2.0, 1000)
    assert r.estimate(("build", 3), ("frame:relaxed", 500)) == pytest.approx(151.0)
    assert r.estimate(("build", 1), ("frame:full", 10)) is None
    assert r.estimate(("frame:full", 0)) == 0.0  # no work of an unmeasured kind


def test_a_silent_step_gets_a_line_every_interval_with_its_estimate():
    beat, clock, lines = _beat()
    with beat:
        beat.step("[4/5] 2/5", "building the 961-landmark model", expected_s=100.0,
                  stage_rest_s=50.0, later_s=30.0)  # fmt: skip
        assert lines == [
            "[4/5] 2/5 building the 961-landmark model, ~1 min 40 s left, stage ~2 min 30 s "
            "left, all ~3 min 00 s left (estimates; 0 s in all so far)"
        ]
        clock.t += 19.0
        beat.beat()
        assert len(lines) == 1  # not yet silent for 20 s
        clock.t += 1.0
        beat.beat()
        assert lines[-1] == (
            "[4/5] 2/5 still building the 961-landmark model, 20 s elapsed, ~1 min 20 s left, "
            "stage ~2 min 10 s left, all ~2 min 40 s left (estimates; 20 s in all so far)"
        )
        clock.t += 120.0  # past the estimate: it says so instead of a negative time
        beat.beat()
        assert "140 s" not in lines[-1] and "past its estimate of 1 min 40 s" in lines[-1]
        assert len(lines) == 3


def test_items_of_a_bar_set_the_rate_and_done_total():
    beat, clock, lines = _beat()
    with beat:
        beat.step("[2/5] 1/4", "evaluating 5 methods", stage_rest_s=10.0, later_s=100.0,
                  later_partial=True)  # fmt: skip
        assert "no estimate yet" in lines[-1]  # nothing measured, no step estimate
        for x in bar(["a", "b", "c", "d", "e"], "methods", enabled=False):
            if x == "c":  # two items done in 60 s: 30 s each, three left
                assert beat.line() == (
                    "[2/5] 1/4 still evaluating 5 methods, methods 2/5, 1 min 00 s elapsed, "
                    "~1 min 30 s left, stage ~1 min 40 s left, all >= ~3 min 20 s left "
                    "(estimates; 1 min 00 s in all so far)"
                )
            clock.t += 30.0
    assert beat.current is not None and beat.current.items_done == 5


def test_the_thread_prints_while_the_caller_is_busy():
    lines: list[str] = []
    seen = threading.Event()

    def emit(text: str) -> None:
        lines.append(text)
        if len(lines) >= 2:
            seen.set()

    with Heartbeat(every=0.05, emit=emit) as beat:
        beat.step("[1/5] 1/1", "compiling", expected_s=1.0)
        assert seen.wait(10.0)  # the caller blocks; the background thread speaks
    assert lines[1].startswith("[1/5] 1/1 still compiling, 0 s elapsed, ~")


def test_interval_must_stay_within_30_s():
    with pytest.raises(ValueError, match="every"):
        Heartbeat(every=31.0)
