"""What meshcheck is doing, on stderr: a line redrawn in place on a terminal, a few log lines
without one.

- On a terminal, each stage draws ``label done/total`` at once and redraws it as items finish (at
  most every 0.1 s); a stage that completes shows its total before the line is cleared. A stage
  still busy after ``QUIET_SECONDS`` also shows how long it has run and what it is waiting on
  (``decomposing 0/2, 14 s, waiting on base_link``), redrawn every second.
- Without a terminal (CI logs, pipes), a stage that is still running after ``QUIET_SECONDS`` gets
  one line, ``meshcheck: label done/total ... N s, waiting on PART``, then at most one more every
  ``LOG_INTERVAL`` seconds, and a closing ``... done in N s`` line. Quick stages print nothing, so
  a quick run's stderr stays empty; a slow first run (CoACD, a hard pair) is never silent for long.
- ``note`` prints a performance note (a decomposition cut short) as its own line. Notes are about
  how the run went, so they go here and never into a report.

Never on stdout, which carries the report.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

#: A stage busy this long without a terminal gets a line saying what it is doing.
QUIET_SECONDS = 2.0
#: ... and at most one more line every this many seconds while it keeps running.
LOG_INTERVAL = 15.0
#: On a terminal, a busy stage's line is redrawn this often (its elapsed time moves).
REDRAW_SECONDS = 1.0


class Progress:
    """One stage's counter on stderr.

    Parameters
    ----------
    label : str
        What is being done, e.g. ``"decomposing"``.
    total : int
        Number of items in the stage; 0 when not known (yet).
    stream : file, optional
        Where to write; default ``sys.stderr``.
    quiet_seconds, log_interval : float
        Without a terminal: the first line after this long, further lines at most this often.
        On a terminal: elapsed time and ``detail`` are shown after ``quiet_seconds``.
    detail : callable, optional
        Returns what the stage is waiting on now (part names), or ``""``; called from a
        background thread, so it must only read.

    Examples
    --------
    >>> import io
    >>> with Progress("loading", 3, stream=io.StringIO()) as bar:
    ...     bar.update(3)
    >>> bar.is_terminal
    False
    """

    def __init__(
        self,
        label: str,
        total: int,
        *,
        stream: TextIO | None = None,
        quiet_seconds: float = QUIET_SECONDS,
        log_interval: float = LOG_INTERVAL,
        detail: Callable[[], str] | None = None,
    ):
        self.label = label
        self.detail = detail
        self._quiet_seconds = quiet_seconds
        self.total = int(total)
        self.done = 0
        self.stream = sys.stderr if stream is None else stream
        try:
            self.is_terminal = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.is_terminal = False
        self.is_enabled = self.is_terminal  # kept for callers of the terminal-only version
        self._started = time.monotonic()
        self._last = 0.0
        self._drawn = False
        self._logged = False
        self._lock = threading.Lock()
        self._closed = threading.Event()
        if self.is_terminal:
            self._draw()
            target, args = self._redraw_while_running, (quiet_seconds,)
        else:
            target, args = self._log_while_running, (quiet_seconds, log_interval)
        self._ticker = threading.Thread(
            target=target, args=args, name=f"meshcheck-progress-{label}", daemon=True
        )
        self._ticker.start()

    def update(self, done: int) -> None:
        """Show ``done`` of ``total`` items finished."""
        self.done = int(done)
        if not self.is_terminal:
            return
        now = time.monotonic()
        if self.done < self.total and now - self._last < 0.1:
            return
        self._draw()

    def update_total(self, done: int, total: int) -> None:
        """Show ``done`` of ``total`` items, for stages that learn their total as they go."""
        self.total = int(total)
        self.update(done)

    def close(self, *, is_complete: bool = True) -> None:
        """End the stage: on a terminal show the total (when complete) and clear the line."""
        if self._closed.is_set():
            return
        self._closed.set()
        if self._ticker is not None:
            self._ticker.join()
        with self._lock:
            if self.is_terminal and self._drawn:
                if is_complete and self.total:
                    self.done = max(self.done, self.total)
                    self._write(f"\r{self._status()}")
                self._write("\r\033[K")
                self._drawn = False
            elif self._logged:
                seconds = time.monotonic() - self._started
                state = "done" if is_complete else "stopped"
                if is_complete and self.total:
                    self.done = max(self.done, self.total)
                self._write(f"meshcheck: {self._status()} {state} in {seconds:.0f} s\n")

    def note(self, text: str) -> None:
        """Print ``text`` as its own line (``meshcheck: text``), above a terminal's bar."""
        with self._lock:
            if self.is_terminal and self._drawn:
                self._write(f"\r\033[Kmeshcheck: {text}\n\r{self._status()}\033[K")
            else:
                self._write(f"meshcheck: {text}\n")

    def _status(self) -> str:
        return f"{self.label} {self.done}/{self.total}" if self.total else f"{self.label}..."

    def _busy(self) -> str:
        """Elapsed seconds and what the stage waits on, for a stage running a while."""
        seconds = time.monotonic() - self._started
        text = f"{seconds:.0f} s"
        try:
            waiting = self.detail() if self.detail is not None else ""
        except Exception:  # a progress line is not worth failing the run for
            waiting = ""
        return f"{text}, waiting on {waiting}" if waiting else text

    def _draw(self) -> None:
        with self._lock:
            if self._closed.is_set():
                return
            self._last = time.monotonic()
            status = self._status()
            if self._last - self._started >= self._quiet_seconds:
                status = f"{status}, {self._busy()}"
            self._write(f"\r{status}\033[K")
            self._drawn = True

    def _redraw_while_running(self, quiet_seconds: float) -> None:
        wait = quiet_seconds
        while not self._closed.wait(wait):
            self._draw()
            wait = REDRAW_SECONDS

    def _log_while_running(self, quiet_seconds: float, log_interval: float) -> None:
        wait = quiet_seconds
        while not self._closed.wait(wait):
            with self._lock:
                if self._closed.is_set():
                    return
                status = self._status()
                dots = "" if status.endswith("...") else " ..."
                self._write(f"meshcheck: {status}{dots} {self._busy()}\n")
                self._logged = True
            wait = log_interval

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # stderr closed: progress is not worth failing for
            pass

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(is_complete=exc_type is None)
