"""Progress for long work (build, evaluate, demo, rollout): ``tqdm`` bars and plain heartbeats.

``bar`` shows one ``tqdm`` bar on stderr, only where asked for (``enabled``) and only when stderr
is a terminal (tqdm's ``disable=None``): logs, pipes and tests get no bar.

``Heartbeat`` is for work that runs for minutes (the demo): plain lines on stderr, terminal or
not, so that logs and CI show progress too. Each step of the work is announced with ``step``
(what it does, its place in the stage, an estimate of its seconds and of the rest of the stage
and of the stages after it, from work counts and rates the caller measured); a background
thread prints ``still <doing X>, N s elapsed, ~M s left (estimate)`` whenever no line was
printed for ``every`` seconds, also while one long call (a compile, a build) cannot report from
inside. A ``bar`` iterated while a heartbeat runs reports its items to it (``done/total``), and
the heartbeat's estimate of the current step then follows their measured rate.
"""

from __future__ import annotations

import contextvars
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import TypeVar

from tqdm import tqdm

T = TypeVar("T")

HEARTBEAT_EVERY_S = 20.0
"""Longest silence of a ``Heartbeat``, seconds (the demo promises a line at least every 30 s)."""

_ACTIVE: contextvars.ContextVar[Heartbeat | None] = contextvars.ContextVar(
    "jaxproj_heartbeat", default=None
)


def bar(
    items: Iterable[T], desc: str, *, enabled: bool = True, total: int | None = None
) -> Iterator[T]:
    """Iterate ``items`` behind a progress bar labelled ``desc`` (see the module doc); under a
    running ``Heartbeat``, each finished item is reported to it as well."""
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    it = tqdm(items, desc=desc, total=total, disable=None if enabled else True, leave=False)
    beat = _ACTIVE.get()
    if beat is None:
        return iter(it)
    return _reporting(it, beat, desc, total)


def _reporting(it: Iterable[T], beat: Heartbeat, desc: str, total: int | None) -> Iterator[T]:
    beat.items(desc, 0, total)
    for i, x in enumerate(it):
        yield x
        beat.items(desc, i + 1, total)


def duration(seconds: float) -> str:
    """``seconds`` in words a log reader takes in at a glance: ``"45 s"``, ``"3 min 05 s"``."""
    s = max(0, int(round(seconds)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


def rate_left(elapsed: float, done: float, total: float) -> float | None:
    """Seconds left of ``total`` units at the rate measured so far (``done`` units in
    ``elapsed`` s); ``None`` before any unit is done."""
    if done <= 0 or total <= 0:
        return None
    return max(0.0, elapsed / done * (total - done))


@dataclass
class _Step:
    label: str
    what: str
    started: float
    expected_s: float | None
    stage_rest_s: float | None
    later_s: float | None
    later_partial: bool = False
    items_desc: str = ""
    items_done: int = 0
    items_total: int | None = None
    items_started: float = 0.0


class Heartbeat:
    """Plain progress lines for long work, from the caller and from a background thread.

    Use as a context manager (starts and stops the thread; while it runs, ``bar`` reports to
    it). ``clock`` and ``emit`` are for tests (a fake clock, a list's ``append``); ``start``
    False keeps the thread off (a test calls ``beat`` itself).

    Args:
      every: seconds of silence after which the thread prints a line (``<= 30``).
      clock: monotonic seconds.
      emit: where a line goes (default: stderr, flushed).
      start: run the background thread inside ``with``.
    """

    def __init__(
        self,
        *,
        every: float = HEARTBEAT_EVERY_S,
        clock: Callable[[], float] = time.monotonic,
        emit: Callable[[str], None] | None = None,
        start: bool = True,
    ) -> None:
        if not 0 < every <= 30:
            raise ValueError(f"every={every} must be in (0, 30] s")
        self.every = every
        self.clock = clock
        self.emit_line = emit or _stderr
        self.start_thread = start
        self.began = clock()
        self.last_line = self.began
        self.current: _Step | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._token: contextvars.Token | None = None

    # -- the caller's side -------------------------------------------------------------------
    def step(
        self,
        label: str,
        what: str,
        *,
        expected_s: float | None = None,
        stage_rest_s: float | None = None,
        later_s: float | None = None,
        later_partial: bool = False,
    ) -> None:
        """Start a step and print its first line.

        Args:
          label: where it is, e.g. ``"[4/5] 2/6"`` (stage, step of the stage).
          what: what it does, as the rest of ``"still <what>"`` (``"building the 961-landmark
            model"``).
          expected_s: the step's own estimate (work count x a measured rate), or ``None``.
          stage_rest_s: the estimate of the stage's steps after this one (0: none left).
          later_s: the estimate of the stages after this one (0: none left).
          later_partial: ``later_s`` leaves out work whose rate is not measured yet (the line
            says "at least").
        """
        now = self.clock()
        with self._lock:
            self.current = _Step(label, what, now, expected_s, stage_rest_s, later_s, later_partial)
            line = self._line(now, first=True)
        self._say(line, now)

    def items(self, desc: str, done: int, total: int | None) -> None:
        """``done`` of ``total`` items of the current step are finished (``bar`` calls it)."""
        now = self.clock()
        with self._lock:
            s = self.current
            if s is None:
                return
            if desc != s.items_desc or done == 0:
                s.items_desc, s.items_started = desc, now
            s.items_done, s.items_total = done, total

    def line(self) -> str:
        """The current status line (what the thread prints)."""
        with self._lock:
            return self._line(self.clock(), first=False)

    def beat(self) -> None:
        """Print the status line if nothing was printed for ``every`` seconds."""
        now = self.clock()
        if now - self.last_line >= self.every and self.current is not None:
            self._say(self.line(), now)

    def say(self, text: str) -> None:
        """Print a line of the caller's (a stage's result); it counts as a heartbeat."""
        self._say(text, self.clock())

    # -- estimates ---------------------------------------------------------------------------
    def step_left(self, now: float) -> float | None:
        """Seconds left in the current step: from its items' measured rate once one is done,
        else from the step's estimate (never below 0), else ``None``."""
        s = self.current
        if s is None:
            return None
        if s.items_total and s.items_done:
            by_rate = rate_left(now - s.items_started, s.items_done, s.items_total)
            if by_rate is not None:
                return by_rate
        if s.expected_s is None:
            return None
        return max(0.0, s.expected_s - (now - s.started))

    def _line(self, now: float, *, first: bool) -> str:
        s = self.current
        assert s is not None
        elapsed = now - s.started
        head = f"{s.label} {s.what}" if first else f"{s.label} still {s.what}"
        parts = [head]
        if s.items_total:
            parts.append(f"{s.items_desc} {s.items_done}/{s.items_total}")
        if not first:
            parts.append(f"{duration(elapsed)} elapsed")
        left = self.step_left(now)
        if left is None:
            parts.append("no estimate yet")
        elif left == 0 and s.expected_s is not None and elapsed > s.expected_s:
            parts.append(f"past its estimate of {duration(s.expected_s)}")
        else:
            parts.append(f"~{duration(left)} left")
        if left is not None and s.stage_rest_s is not None:
            stage = left + s.stage_rest_s
            parts.append(f"stage ~{duration(stage)} left")
            if s.later_s is not None:
                at_least = ">= " if s.later_partial else ""
                parts.append(f"all {at_least}~{duration(stage + s.later_s)} left")
        total = now - self.began
        return ", ".join(parts) + f" (estimates; {duration(total)} in all so far)"

    # -- the thread --------------------------------------------------------------------------
    def _say(self, text: str, now: float) -> None:
        self.last_line = now
        self.emit_line(text)

    def _run(self) -> None:
        tick = min(1.0, self.every / 4)
        while not self._stop.wait(tick):
            self.beat()

    def __enter__(self) -> Heartbeat:
        self._token = _ACTIVE.set(self)
        if self.start_thread:
            self._thread = threading.Thread(target=self._run, name="jaxproj-heartbeat", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._token is not None:
            _ACTIVE.reset(self._token)


def _stderr(text: str) -> None:
    # tqdm.write keeps a bar on a terminal intact; the line goes to stderr either way
    tqdm.write(text, file=sys.stderr)
    sys.stderr.flush()


class Rates:
    """Seconds per unit of work, by kind, measured as the work runs (``"build"``: one model
    build; ``"relaxed_frame"``: one frame projected ...); ``estimate`` turns work counts into
    seconds with them."""

    def __init__(self) -> None:
        self._seen: dict[str, tuple[float, float]] = {}

    def add(self, kind: str, seconds: float, units: float = 1.0) -> None:
        """``units`` of ``kind`` took ``seconds`` (added to what was measured before)."""
        s, u = self._seen.get(kind, (0.0, 0.0))
        self._seen[kind] = (s + max(0.0, seconds), u + units)

    def per_unit(self, kind: str) -> float | None:
        """Measured seconds per unit of ``kind``; ``None`` if none measured yet."""
        s, u = self._seen.get(kind, (0.0, 0.0))
        return s / u if u > 0 else None

    def estimate(self, *work: tuple[str, float]) -> float | None:
        """Seconds for ``(kind, units)`` pieces of work at the measured rates; ``None`` while
        any kind with units is unmeasured."""
        total = 0.0
        for kind, units in work:
            if units <= 0:
                continue
            rate = self.per_unit(kind)
            if rate is None:
                return None
            total += rate * units
        return total
