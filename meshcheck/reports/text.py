"""The text report: a table that fits the terminal (80 columns without one), each finding's
detail under its row, the clash groups (a line per group, its findings below), a summary.

Every line fits the width. Part names are shown after the directory prefix every part shares
(named once above the table), cut in the middle when they still do not fit, the same cut
wherever a name appears (table, groups, baseline, sweep); the JSON report keeps them whole. The
summary and group lines wrap between their comma-separated pieces, never inside one.

A run of clash tests has a section per test: a line naming the test, its sides and settings,
then the report of that test alone (its table, groups and summary line); then the run's sweep and
configuration lines, and its summary line (how many tests fail) last.
"""

from __future__ import annotations

import shutil
import textwrap
from collections.abc import Sequence

from ..outcome import CheckResult
from ..results import clash_groups
from .common import (
    View,
    audit_rows,
    clash_test_line,
    describe,
    ordered,
    pose_text,
    printable,
    resolution,
    run_remainder,
    sections,
    shared_prefix,
    summary_chunks,
    sweep_rows,
    tolerance_text,
    unlisted,
)

WIDTH = 80
_ID_WIDTH = 12
_INDENT = " " * (_ID_WIDTH + 2)


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
    if result.tests:
        return _render_tests(result, view)
    width = view.width
    prefix = shared_prefix([p.name for p in result.parts])
    has_baseline = result.baseline is not None
    shown = [f for f in ordered(result) if view.shows(result, f)]
    resolved = result.baseline.resolved(result.findings) if has_baseline else []
    swept = [row for row in sweep_rows(result) if row[2] or not view.is_quiet]
    audited = [row for row in audit_rows(result) if row[1] or not view.is_quiet]

    def below(name: str) -> str:
        return printable(name[len(prefix) :] if name.startswith(prefix) else name)

    rows = []
    tolerance = resolution(result)
    for f in shown:
        status = str(f.status) + (" (approved)" if f.is_approved else "")
        state = result.baseline_state(f) or ""
        detail = describe(f, tolerance)
        if f.is_approved:
            detail += f"  approved: {printable(f.approval_reason)}"
        rows.append((f.id, status, state, below(f.a), below(f.b), detail))
    names = [n for f in shown for n in (f.a, f.b)] + [n for r in resolved for n in (r.a, r.b)]
    names += [n for robot, pair, _ in swept for n in (robot, pair.a, pair.b)]
    if result.audit is not None:
        names += [n for pair, _ in audited for n in (pair.a, pair.b)] + [result.audit.path]
    names += [pose.path for pose in result.poses]
    name_width = _name_width(rows, width=width, has_baseline=has_baseline)
    cut = shorten_all(sorted({below(n) for n in names}), name_width)

    def short(name: str) -> str:
        return cut[below(name)]

    def wrap(text: str, indent: str) -> list[str]:
        return textwrap.wrap(text, width, subsequent_indent=indent, break_on_hyphens=False) or [
            text
        ]

    lines = []
    if prefix and rows:
        lines.extend(wrap(f"parts below {printable(prefix)}", "  "))
    if rows:
        lines.extend(_table(rows, cut, width=width, has_baseline=has_baseline))
    for group in clash_groups(shown):
        head, rows_below = group_lines(group, short)
        lines.extend(_pack([f"group {group.id} ", *_pieces(head)], width, _INDENT))
        for finding_id, pair_names in rows_below:
            lines.extend(wrap(f"  {finding_id}  {pair_names}", _INDENT))
    note = unlisted(result, view, len(shown))
    if note:
        lines.extend(wrap(note, "  "))
    if not view.is_quiet:
        for r in resolved:
            lines.extend(
                wrap(f"resolved {r.id}  {r.status}  {short(r.a)} and {short(r.b)}", _INDENT)
            )
    for robot, pair, fails in swept:  # --sweep: failing pairs even when quiet
        adjacent = " (adjacent)" if pair.is_adjacent else ""
        mark = "FAIL " if fails else ""
        text = f"{mark}sweep {pair.status}{adjacent}  {short(robot)}: {short(pair.a)} / "
        text += f"{short(pair.b)}  {printable(pose_text(pair))}"
        if pair.approval_reason is not None:
            text += f" (approved: {printable(pair.approval_reason)})"
        lines.extend(wrap(text, _INDENT))
    for robot in result.sweeps:  # each robot's counts, and the work against the budget
        lines.extend(wrap(f"sweep {printable(robot.summary())}", _INDENT))
    if result.audit is not None:  # --audit-srdf: the entries not proven, failing ones even quiet
        audit = result.audit
        for pair, fails in audited:
            mark = "FAIL " if fails else ""
            text = f"{mark}srdf {pair.status} ({printable(pair.reason or 'no reason')})  "
            text += f"{short(audit.path)}:{pair.line}: {short(pair.a)} / {short(pair.b)}  "
            text += printable(pose_text(pair.sweep))
            lines.extend(wrap(text, _INDENT))
        if not view.is_quiet:
            lines.extend(wrap(f"srdf {printable(audit.summary())}", "  "))
    for pose in result.poses:  # the pose the report was made at, even when quiet
        lines.extend(wrap(f"pose {short(pose.path)}: {printable(pose.text())}", "  "))
    if result.settings.config_path:
        lines.extend(wrap(f"configuration: {printable(result.settings.config_path)}", "  "))
    lines.extend(summary_lines(result, width))
    return "\n".join(lines) + "\n"


def _render_tests(result: CheckResult, view: View) -> str:
    """A section per clash test (a line on the test, then the report of that test alone), then
    the run's sweep and configuration lines and its summary."""
    lines = []
    for section in sections(result):
        heading = _pieces_after(clash_test_line(section.test), "; ")
        lines.extend(_pack(heading, view.width, "  "))
        lines.extend(render(section, view=view).splitlines())
        lines.append("")
    rest = run_remainder(result)
    tail = render(rest, view=view).splitlines()
    lines.extend(tail[: len(tail) - len(summary_lines(rest, view.width))])
    lines.extend(summary_lines(result, view.width))
    return "\n".join(lines) + "\n"


def summary_lines(result: CheckResult, width: int) -> list[str]:
    """The summary, its verdict line last: the whole summary line when it fits ``width``; else
    a verdict line of the counts that fit, below a line of the counts that did not, the
    tolerance and the unit.

    Examples
    --------
    >>> from meshcheck.outcome import CheckResult
    >>> from meshcheck.settings import Settings
    >>> for line in summary_lines(CheckResult([], [], Settings(clearance=0.5)), 40):
    ...     print(line)
    0 touching, 0 clearance (< 0.5);
      tolerance per pair; lengths in mm
    PASS: 0 parts, 0 interference
    """
    *counts, settings = summary_chunks(result)
    whole = " ".join([*counts, settings])
    if len(whole) <= width:
        return [whole]
    kept = counts[:1]
    for piece in counts[1:]:
        if len(" ".join([*kept, piece])) > width:
            break
        kept.append(piece)
    moved = [p.rstrip(",") for p in counts[len(kept) :]]
    above = [", ".join(moved)] if moved else []
    above += [f"tolerance {tolerance_text(result)}", f"lengths in {result.units}"]
    verdict = " ".join(kept)
    return [*_pack(_pieces_after("; ".join(above), "; "), width, "  "), verdict.rstrip(",")]


def _pieces(text: str) -> list[str]:
    """``text`` split after each ``, `` (the comma kept): the places a line may wrap."""
    return _pieces_after(text, ", ")


def _pieces_after(text: str, separator: str) -> list[str]:
    """``text`` split after each ``separator`` (its mark kept, the space dropped)."""
    parts = text.split(separator)
    mark = separator.rstrip()
    return [p + mark for p in parts[:-1]] + parts[-1:]


def _pack(pieces: Sequence[str], width: int, indent: str) -> list[str]:
    """``pieces`` joined by spaces into lines of at most ``width``, each piece kept whole on
    one line (lines after the first start with ``indent``); a piece longer than a line is
    wrapped on its own.

    Examples
    --------
    >>> _pack(["FAIL: 6 parts,", "1 interference,", "4 touching", "(mm)"], 32, "  ")
    ['FAIL: 6 parts, 1 interference,', '  4 touching (mm)']
    """
    lines: list[str] = []
    line = ""
    for piece in pieces:
        joined = f"{line} {piece}" if line else piece
        if len(joined) <= width or not line.strip():
            line = joined
            continue
        lines.append(line)
        line = indent + piece
    lines.append(line)
    out = []
    for line in lines:  # a piece too long for any line: wrapped inside it, as a last resort
        rest = textwrap.wrap(line, width, subsequent_indent=indent, break_on_hyphens=False)
        out.extend(rest or [line])
    return out


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


def _name_width(rows: list[tuple], *, width: int, has_baseline: bool) -> int:
    """Columns each of the table's two name columns may take."""
    header = ("ID", "STATUS", "BASELINE")
    status_width = max(len(r[1]) for r in (header, *rows))
    state_width = max(len(r[2]) for r in (header, *rows)) if has_baseline else 0
    fixed = _ID_WIDTH + 2 + status_width + 2 + (state_width + 2 if has_baseline else 0) + 2
    return max((width - fixed) // 2, 12)


def _table(rows: list[tuple], cut: dict, *, width: int, has_baseline: bool) -> list[str]:
    """The header and a line per row (names as ``cut`` shows them), each row's detail wrapped
    under it, within ``width``."""
    header = ("ID", "STATUS", "BASELINE", "PART A", "PART B", "")
    status_width = max(len(r[1]) for r in (header, *rows))
    state_width = max(len(r[2]) for r in (header, *rows)) if has_baseline else 0
    name_width = _name_width(rows, width=width, has_baseline=has_baseline)
    a_width = min(name_width, max(len(cut.get(r[3], r[3])) for r in (header, *rows)))
    lines = []
    for r in (header, *rows):
        cells = [r[0].ljust(_ID_WIDTH), r[1].ljust(status_width)]
        if has_baseline:
            cells.append(r[2].ljust(state_width))
        cells += [cut.get(r[3], r[3]).ljust(a_width), cut.get(r[4], r[4])]
        row = "  ".join(cells).rstrip()
        if len(row) > width:  # names no cut could tell apart, shown whole: wrapped
            lines.extend(textwrap.wrap(row, width, subsequent_indent=_INDENT))
        else:
            lines.append(row)
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
