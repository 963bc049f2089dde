"""What a run reports while it works, and how a terminal shows it.

Runners report through a ``progress(message)`` callable. A message is either
a line worth keeping (a stage, an event, an outcome) or a :class:`Status`: the
state of a long loop (a step, an iteration), which the next status replaces.
:class:`Console` prints lines as they come and keeps the status on one line
of a terminal, with the time left where the loop knows how far it has got.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

Progress = Callable[[str], None]


class Status(str):
    """A progress message that describes the current state of a loop.

    ``fraction`` is how far the loop has got (0 to 1) when it can tell, else None.
    """

    fraction: float | None

    def __new__(cls, text: str, fraction: float | None = None):
        obj = super().__new__(cls, text)
        obj.fraction = None if fraction is None else min(max(float(fraction), 0.0), 1.0)
        return obj


def quiet(message: str) -> None:
    """A progress callable that shows nothing."""


def tee(*targets: Progress) -> Progress:
    """A progress callable that passes every message to each of ``targets``."""
    return lambda message: [t(message) for t in targets] and None


def indented(progress: Progress, prefix: str = "  ") -> Progress:
    """A progress callable that indents every message, a status staying a status."""
    def say(message: str) -> None:
        text = prefix + message
        progress(Status(text, message.fraction) if isinstance(message, Status) else text)
    return say


def time_left(elapsed: float, fraction: float | None) -> float | None:
    """Linear estimate of the time still needed, or None when the fraction says nothing yet."""
    if fraction is None or fraction <= 0.0 or elapsed <= 0.0:
        return None
    return elapsed * (1.0 - fraction) / fraction


class Console:
    """Progress on a terminal stream.

    Parameters
    ----------
    verbosity : {0, 1, 2}
        0: nothing; 1: lines, and the status kept on one line of a terminal
        (on a stream that is no terminal, a status at most every
        ``interval`` seconds); 2: every message on a line of its own.
    stream : text stream (default ``sys.stderr``)
    interval : float
        Seconds between statuses printed to a stream that is no terminal.
    """

    def __init__(self, verbosity: int = 1, stream=None, interval: float = 5.0):
        self.verbosity = verbosity
        self.stream = stream if stream is not None else sys.stderr
        self.interval = interval
        self.live = bool(getattr(self.stream, "isatty", lambda: False)())
        self._status_shown = False
        self._last_print = -float("inf")
        self._loop_start = None
        self._last_fraction = None

    def _estimate(self, status: Status) -> str:
        now = time.perf_counter()
        f = status.fraction
        if f is None:
            return ""
        if self._loop_start is None or (self._last_fraction is not None and f < self._last_fraction):
            self._loop_start = now  # a new loop: its own clock
        self._last_fraction = f
        left = time_left(now - self._loop_start, f)
        return f"  {100 * f:.0f} %" + (f", about {left:.0f} s left" if left is not None else "")

    def __call__(self, message: str) -> None:
        if self.verbosity <= 0:
            return
        if isinstance(message, Status) and self.verbosity == 1:
            text = message + self._estimate(message)
            if self.live:
                self.stream.write("\r\033[K" + text)
                self._status_shown = True
            elif time.perf_counter() - self._last_print >= self.interval:
                self.stream.write(text + "\n")
                self._last_print = time.perf_counter()
            self.stream.flush()
            return
        if self._status_shown:
            self.stream.write("\r\033[K")  # the line replaces the status
            self._status_shown = False
        self.stream.write(str(message) + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End a status line left on a terminal."""
        if self._status_shown:
            self.stream.write("\n")
            self.stream.flush()
            self._status_shown = False
