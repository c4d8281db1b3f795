"""Progress on stderr: a redrawn line on a terminal, a few log lines without one, nothing for
quick stages, and the line reaches its total before it clears."""

from __future__ import annotations

import io
import time

from meshcheck.progress import Progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_quick_stage_without_a_terminal_prints_nothing():
    pipe = io.StringIO()
    with Progress("checking", 5, stream=pipe) as bar:
        bar.update(5)
    assert pipe.getvalue() == ""


def test_a_busy_stage_without_a_terminal_says_so_without_spamming():
    pipe = io.StringIO()
    with Progress("decomposing", 4, stream=pipe, quiet_seconds=0.1, log_interval=0.4) as bar:
        bar.update(1)
        time.sleep(1.0)  # silent work, e.g. compiling: lines at ~0.1 s, ~0.5 s, ~0.9 s
        bar.update(3)
    lines = pipe.getvalue().splitlines()
    assert lines[0].startswith("meshcheck: decomposing 1/4 ... 0 s")
    assert 2 <= len(lines) - 1 <= 4  # at most one line per interval while busy
    assert lines[-1].startswith("meshcheck: decomposing 4/4 done in ")
    assert all(line.startswith("meshcheck: ") for line in lines)
    assert "\r" not in pipe.getvalue()


def test_an_interrupted_stage_does_not_claim_it_finished():
    pipe = io.StringIO()
    try:
        with Progress("checking", 4, stream=pipe, quiet_seconds=0.05) as bar:
            bar.update(1)
            time.sleep(0.3)
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        pass
    assert pipe.getvalue().splitlines()[-1].startswith("meshcheck: checking 1/4 stopped in ")


def test_the_terminal_line_appears_at_once_and_reaches_its_total_before_it_clears():
    tty = _Terminal()
    with Progress("decomposing", 3, stream=tty) as bar:
        assert tty.getvalue() == "\rdecomposing 0/3\033[K"
        bar.update(1)  # copies of one mesh share its decomposition: the count stops short
    out = tty.getvalue()
    assert out.endswith("\rdecomposing 3/3\r\033[K")


def test_a_stage_of_unknown_size_says_what_it_does():
    tty = _Terminal()
    with Progress("starting", 0, stream=tty):
        assert tty.getvalue() == "\rstarting...\033[K"
    assert tty.getvalue().endswith("\r\033[K")


def test_a_busy_stage_says_how_long_and_what_it_waits_on_in_logs_and_on_a_terminal():
    pipe, tty = io.StringIO(), _Terminal()
    for stream in (pipe, tty):
        with Progress(
            "decomposing", 2, stream=stream, quiet_seconds=0.1, detail=lambda: "base_link"
        ) as bar:
            time.sleep(1.3)
            bar.note("base_link: convex decomposition took over 0.5 s; its hull stands in")
    logged = pipe.getvalue().splitlines()
    assert logged[0].startswith("meshcheck: decomposing 0/2 ... 0 s, waiting on base_link")
    assert (
        "meshcheck: base_link: convex decomposition took over 0.5 s; its hull stands in" in logged
    )
    drawn = tty.getvalue()
    assert "\rdecomposing 0/2, 1 s, waiting on base_link\033[K" in drawn
    assert "\r\033[Kmeshcheck: base_link: convex decomposition took over 0.5 s" in drawn
    assert drawn.endswith("\r\033[K")
