"""The run log: every progress line of a run, with the time since it started, in ``run.log``.

The log is appended line by line and flushed at once, so a run that is
killed leaves every line it had reported; a resumed run adds its own lines
after a separator.
"""

from __future__ import annotations

import time
from pathlib import Path


class RunLog:
    """Append progress lines to a file; use as a context manager.

    Parameters
    ----------
    path : path-like
        The log file (``run.log`` of the output folder).
    """

    def __init__(self, path):
        self.path = Path(path)
        self._fh = None
        self._t0 = time.perf_counter()

    def __enter__(self) -> RunLog:
        self._fh = open(self.path, "a", encoding="utf-8", buffering=1)
        self._start = self._fh.tell()
        self._created = self._start == 0
        self._fh.write(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
        return self

    def __exit__(self, *exc) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def discard(self) -> None:
        """Take back this run's lines: the log is as the run found it (absent if it was)."""
        self._fh.truncate(self._start)
        self.__exit__()
        if self._created:
            self.path.unlink(missing_ok=True)

    def __call__(self, message: str) -> None:
        if self._fh is not None:
            self._fh.write(f"{time.perf_counter() - self._t0:10.2f} s  {message}\n")
