"""The text report: a table that fits the terminal (100 columns without one), each finding's
detail under its row, the clash groups (a line per group, its findings below), a summary.

Part names are shown after the directory prefix every part shares (named once above the table),
cut in the middle when they still do not fit; the JSON report keeps them whole.
"""

from __future__ import annotations

import shutil
import textwrap
from collections.abc import Sequence

from ..outcome import CheckResult
from ..results import clash_groups
from .common import (
    View,
    describe,
    ordered,
    pose_text,
    printable,
    resolution,
    summary_line,
    sweep_rows,
    unlisted,
)

WIDTH = 100
_ID_WIDTH = 12
_INDENT = " " * (_ID_WIDTH + 2)


def shared_prefix(names: list[str]) -> str:
    """The directory prefix (ending in ``/``) all ``names`` share, or ``""``.

    Examples
    --------
    >>> shared_prefix(["asm/frame.stl", "asm/sub/pin.stl"])
    'asm/'
    >>> shared_prefix(["asm/frame.stl"]), shared_prefix(["a/x.stl", "b/y.stl"])
    ('asm/', '')
    """
    if not names:
        return ""
    low, high = min(names), max(names)
    common = 0
    while common < min(len(low), len(high)) and low[common] == high[common]:
        common += 1
    return low[: low.rfind("/", 0, common) + 1]


def shorten(text: str, width: int) -> str:
    """``text`` cut in the middle to ``width`` characters with ``...``."""
    if len(text) <= width:
        return text
    keep = max(width - 3, 2)
    head = keep // 2
    return text[:head] + "..." + text[len(text) - (keep - head) :]


def shorten_all(names: Sequence[str], width: int) -> dict[str, str]:
    """Each of ``names`` cut to ``width``, two different names never cut to the same text.

    A name whose middle cut collides with another's keeps where it differs from those others
    (the first and the last differing character, their path components whole when they fit),
    then as much of its file name and start as fits, each cut run shown as ``...``; a name that
    cannot be told apart within ``width`` is shown whole.

    Examples
    --------
    >>> cut = shorten_all(["sub/gearbox/left/cap_screw.stl", "sub/gearbox/right/cap_screw.stl"], 24)
    >>> cut["sub/gearbox/left/cap_screw.stl"], cut["sub/gearbox/right/cap_screw.stl"]
    ('...left/cap_...rew.stl', '...right/cap...rew.stl')
    """
    distinct = sorted(set(names))
    out = {n: shorten(n, width) for n in distinct}
    needed: dict[str, set[int]] = {n: set() for n in distinct}
    for _ in range(4):  # each round keeps more of the names that still look alike
        by_text: dict[str, list[str]] = {}
        for n in distinct:
            by_text.setdefault(out[n], []).append(n)
        groups = [g for g in by_text.values() if len(g) > 1]
        if not groups:
            return out
        for group in groups:
            for n in group:
                for m in group:
                    if m != n:
                        needed[n].update(_differing(n, m))
                out[n] = _keep(n, width, needed[n])
    texts = [out[n] for n in distinct]
    if len(set(texts)) < len(texts):  # still ambiguous: the whole names, never a wrong one
        seen: dict[str, int] = {}
        for t in texts:
            seen[t] = seen.get(t, 0) + 1
        out = {n: (n if seen[out[n]] > 1 else out[n]) for n in distinct}
    return out


def _differing(a: str, b: str) -> set[int]:
    """Where ``a`` first differs from ``b`` reading from the start, and reading from the end."""
    first = 0
    while first < min(len(a), len(b)) and a[first] == b[first]:
        first += 1
    last = 0
    while last < min(len(a), len(b)) - first and a[-1 - last] == b[-1 - last]:
        last += 1
    end = max(len(a) - last, first + 1)
    return {min(first, len(a) - 1), min(end, len(a)) - 1}


def _render(name: str, kept: set[int]) -> str:
    out, gap = [], False
    for k, ch in enumerate(name):
        if k in kept:
            out.append(ch)
            gap = False
        elif not gap:
            out.append("...")
            gap = True
    return "".join(out)


def _keep(name: str, width: int, needed: set[int]) -> str:
    """``name`` within ``width``, the ``needed`` positions kept and every cut run shown as
    ``...``; then as much of the end (the file name) and the start as fits. The whole name when
    the needed positions alone do not fit."""
    if len(name) <= width:
        return name
    kept = set(needed)
    if len(_render(name, kept)) > width:
        return name
    whole = set(kept)  # the path components holding the differences, whole, when they fit
    for k in needed:
        start, end = name.rfind("/", 0, k) + 1, name.find("/", k)
        whole.update(range(start, len(name) if end < 0 else end))
    if len(_render(name, whole)) <= width:
        kept = whole
    # the file name first, then outward from the kept runs (fewer cuts), ends before middles
    base = name.rfind("/") + 1
    order = sorted(
        range(len(name)),
        key=lambda k: (k < base, min(abs(k - j) for j in {*needed, 0, len(name) - 1}), -k),
    )
    for k in order:
        if k not in kept:
            kept.add(k)
            if len(_render(name, kept)) > width:
                kept.discard(k)
    return _render(name, kept)


def terminal_width(*, is_terminal: bool) -> int:
    """Columns for the text table: the terminal's when stdout is one, else ``WIDTH``."""
    if not is_terminal:
        return WIDTH
    return max(shutil.get_terminal_size((WIDTH, 24)).columns, 40)


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    """The table of findings (most severe first), resolved baseline findings, the
    configuration file, the summary; ``view`` picks the rows and the width."""
    view = view or View()
    width = view.width
    prefix = shared_prefix([p.name for p in result.parts])
    has_baseline = result.baseline is not None
    shown = [f for f in ordered(result) if view.shows(result, f)]

    def short(name: str) -> str:
        return printable(name[len(prefix) :] if name.startswith(prefix) else name)

    rows = []
    for f in shown:
        status = str(f.status) + (" (approved)" if f.is_approved else "")
        state = result.baseline_state(f) or ""
        detail = describe(f, resolution(result, f))
        if f.is_approved:
            detail += f"  approved: {printable(f.approval_reason)}"
        rows.append((f.id, status, state, short(f.a), short(f.b), detail))

    def wrap(text: str, indent: str) -> list[str]:
        return textwrap.wrap(text, width, subsequent_indent=indent, break_on_hyphens=False) or [
            text
        ]

    lines = []
    if prefix and rows:
        lines.extend(wrap(f"parts below {printable(prefix)}", "  "))
    if rows:
        lines.extend(_table(rows, width=width, has_baseline=has_baseline))
    for group in clash_groups(shown):
        head, rows_below = group_lines(group, short)
        lines.extend(wrap(f"group {group.id}  {head}", _INDENT))
        for finding_id, names in rows_below:
            lines.extend(wrap(f"  {finding_id}  {names}", _INDENT))
    note = unlisted(result, view, len(shown))
    if note:
        lines.extend(wrap(note, "  "))
    if has_baseline and not view.is_quiet:
        for r in result.baseline.resolved(result.findings):
            lines.extend(
                wrap(f"resolved {r.id}  {r.status}  {short(r.a)} and {short(r.b)}", _INDENT)
            )
    for robot, pair, fails in sweep_rows(result):  # --sweep: failing pairs even when quiet
        if view.is_quiet and not fails:
            continue
        adjacent = " (adjacent)" if pair.is_adjacent else ""
        mark = "FAIL " if fails else ""
        text = f"{mark}sweep {pair.status}{adjacent}  {short(robot)}: {short(pair.a)} / "
        text += f"{short(pair.b)}  {printable(pose_text(pair))}"
        if pair.approval_reason is not None:
            text += f" (approved: {printable(pair.approval_reason)})"
        lines.extend(wrap(text, _INDENT))
    if result.settings.config_path:
        lines.extend(wrap(f"configuration: {printable(result.settings.config_path)}", "  "))
    lines.extend(wrap(summary_line(result), "  "))
    return "\n".join(lines) + "\n"


def group_lines(group, name) -> tuple[str, list[tuple[str, str]]]:
    """A clash group's line (after its ID) and its members' (ID, names), names through ``name``.

    A part group names the shared part and each member's other part; a pattern group says what
    repeats and names both parts of each member.

    Examples
    --------
    >>> from meshcheck.results import ClashGroup, Finding, PairVerdict
    >>> v = PairVerdict("interference", 0.0, depth=1.0)
    >>> g = ClashGroup("0123456789ab", None, v.status, (Finding("a1", "b1", v, id="f1"),
    ...     Finding("a2", "b2", v, id="f2")), kind="pattern")
    >>> head, rows = group_lines(g, str)
    >>> head
    'pattern: 2 interference, copies of two parts at one relative placement'
    >>> rows
    [('f1', 'a1 and b1'), ('f2', 'a2 and b2')]
    """
    count = f"{len(group.members)} {group.status}"
    if group.kind == "pattern":
        head = f"pattern: {count}, copies of two parts at one relative placement"
        return head, [(f.id, f"{name(f.a)} and {name(f.b)}") for f in group.members]
    rows = [(f.id, name(f.b if f.a == group.part else f.a)) for f in group.members]
    return f"{name(group.part)}: {count}", rows


def _table(rows: list[tuple], *, width: int, has_baseline: bool) -> list[str]:
    """The header and a line per row, each row's detail wrapped under it, within ``width``."""
    header = ("ID", "STATUS", "BASELINE", "PART A", "PART B", "")
    status_width = max(len(r[1]) for r in (header, *rows))
    state_width = max(len(r[2]) for r in (header, *rows)) if has_baseline else 0
    fixed = _ID_WIDTH + 2 + status_width + 2 + (state_width + 2 if has_baseline else 0) + 2
    name_width = max((width - fixed) // 2, 12)
    cut = shorten_all([r[k] for r in rows for k in (3, 4)], name_width)
    a_width = min(name_width, max(len(cut.get(r[3], r[3])) for r in (header, *rows)))
    lines = []
    for r in (header, *rows):
        cells = [r[0].ljust(_ID_WIDTH), r[1].ljust(status_width)]
        if has_baseline:
            cells.append(r[2].ljust(state_width))
        cells += [cut.get(r[3], r[3]).ljust(a_width), cut.get(r[4], r[4])]
        lines.append("  ".join(cells).rstrip())
        if r[5]:
            lines.extend(
                textwrap.wrap(
                    r[5],
                    width,
                    initial_indent=_INDENT,
                    subsequent_indent=_INDENT,
                    break_on_hyphens=False,
                )
            )
    return lines
