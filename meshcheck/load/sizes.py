"""Sizes that betray a wrong unit: a file implausibly large or small for mechanical parts, and
files whose sizes differ as a metre file among millimetre ones does. Each warning suggests the
``--units FILE=UNIT`` that would make the file plausible."""

from __future__ import annotations

from .. import units as units_
from ..mesh import warn

#: Files whose bounding-box diagonals differ by this factor or more get a "mixed units?" warning:
#: a metre file among millimetre ones is 1000 times off, and parts of one machine rarely differ
#: by more than a few hundred times (a 1 m frame and its 2 mm pins).
MIXED_UNITS_RATIO = 500.0
#: ... and by this factor or more when the two files are read in different units (a glTF, in
#: metres by its specification, beside a millimetre STL): a glTF exported in millimetres is 1000
#: times too large, and comes out 100 to 500 times the size of a part a few times larger.
MIXED_DECLARED_RATIO = 100.0
#: A file this many metres across or more warns: mechanical assemblies are not hundreds of
#: metres across (a 0.74 m engine in a millimetre glTF reads as 743 m).
LARGE_METRES = 100.0
#: A file this many metres across or less warns: a part of micrometres is a file in metres (or
#: inches) read in millimetres (a 20 mm bolt written in metres reads as 0.02 mm).
SMALL_METRES = 1e-4
#: Units a size warning may suggest, in this order: the first that makes the file between
#: ``PLAUSIBLE_METRES`` across.
SUGGESTED_UNITS = ("mm", "m", "in", "cm")
PLAUSIBLE_METRES = (1e-3, 10.0)


def warn_sizes(sizes: list[tuple[float, str, str]], report: str, given: dict) -> None:
    """Warn about files of implausible size (``LARGE_METRES``, ``SMALL_METRES``), then about
    mixed units (``warn_mixed_units``); never about a file whose unit the user gave.

    Parameters
    ----------
    sizes : list of (float, str, str)
        Each file's diagonal (report units), path, and the unit its lengths were read in.
    """
    warned = set()
    for diagonal, path, unit in sizes:
        metres = diagonal * units_.METRES[report]
        if path in given or diagonal <= 0.0 or SMALL_METRES < metres < LARGE_METRES:
            continue
        what = "hundreds of metres" if metres >= LARGE_METRES else "micrometres"
        message = (
            f"is {diagonal:.4g} {report} across, read in {unit}: {what} across is implausible "
            "for mechanical parts"
        )
        warn(path, message + _suggestion(path, metres, unit))
        warned.add(path)
    warn_mixed_units([s for s in sizes if s[1] not in warned and s[1] not in given], report)


def _suggestion(path: str, metres: float, unit: str) -> str:
    """``; if it is in mm, give --units PATH=mm``: the first of ``SUGGESTED_UNITS`` that makes
    a file of ``metres`` read in ``unit`` plausible, or ``""``."""
    low, high = PLAUSIBLE_METRES
    for other in SUGGESTED_UNITS:
        size = metres * units_.METRES[other] / units_.METRES[unit]
        if other != unit and low <= size <= high:
            return f"; if the file is in {other}, give --units {path}={other}"
    return ""


def warn_mixed_units(sizes: list[tuple[float, str, str]], report: str) -> None:
    """Warn when the largest file is ``MIXED_UNITS_RATIO`` times the smallest or more
    (``MIXED_DECLARED_RATIO`` when the two are read in different units)."""
    sizes = [s for s in sizes if s[0] > 0.0]
    if len(sizes) < 2:
        return
    small, big = min(sizes), max(sizes)
    ratio = MIXED_UNITS_RATIO if small[2] == big[2] else MIXED_DECLARED_RATIO
    if big[0] >= ratio * small[0]:
        units = f"read in {big[2]} and {small[2]}" if small[2] != big[2] else f"both {big[2]}"
        warn(
            big[1],
            f"is {big[0] / small[0]:.0f} times the size of {small[1]} "
            f"({big[0]:.4g} against {small[0]:.4g} {report} across, {units}): mixed units? "
            "(files that declare no unit are read in --units, default mm; give a file's own "
            "unit with --units FILE=UNIT)",
        )
