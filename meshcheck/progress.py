"""Progress lines on stderr while loading, decomposing and checking, only on a terminal.

Nothing is printed when stderr is not a terminal (CI logs, pipes, tests), and never on stdout,
which carries the report.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """One stage's counter, redrawn in place on stderr at most every 0.1 s.

    Parameters
    ----------
    label : str
        What is being counted, e.g. ``"decomposing"``.
    total : int
        Number of items in the stage.
    stream : file, optional
        Where to draw; default ``sys.stderr``. Nothing is drawn unless it is a terminal.

    Examples
    --------
    >>> import io
    >>> with Progress("loading", 3, stream=io.StringIO()) as bar:
    ...     bar.update(3)
    >>> bar.is_enabled
    False
    """

    def __init__(self, label: str, total: int, *, stream: TextIO | None = None):
        self.label = label
        self.total = int(total)
        self.stream = sys.stderr if stream is None else stream
        try:
            self.is_enabled = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.is_enabled = False
        self._last = 0.0
        self._drawn = False

    def update(self, done: int) -> None:
        """Show ``done`` of ``total`` items finished."""
        if not self.is_enabled:
            return
        now = time.monotonic()
        if done < self.total and now - self._last < 0.1:
            return
        self._last = now
        self.stream.write(f"\r{self.label} {done}/{self.total}")
        self.stream.flush()
        self._drawn = True

    def update_total(self, done: int, total: int) -> None:
        """Show ``done`` of ``total`` items, for stages that learn their total as they go."""
        self.total = int(total)
        self.update(done)

    def close(self) -> None:
        """Clear the line, leaving stderr as it was."""
        if self.is_enabled and self._drawn:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self._drawn = False

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
