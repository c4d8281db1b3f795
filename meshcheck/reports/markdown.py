"""A Markdown summary for ``$GITHUB_STEP_SUMMARY`` (or a pull-request comment): verdict, table.

Names are data: made printable, then every character Markdown or HTML would read as markup
(``|``, ``*``, ``_``, backticks, brackets, ``<``, ``&``...) is escaped, so a name can neither
break the table nor inject a link, an image or HTML.

A run of clash tests shows a table of its tests (verdict, sides, clearance, statuses that fail,
findings), then a section per test holding what the summary of that test alone would.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from ..outcome import CheckResult
from ..results import clash_groups
from .common import (
    View,
    audit_rows,
    clash_test_settings,
    describe,
    ordered,
    plural,
    pose_text,
    printable,
    resolution,
    run_remainder,
    sections,
    summary,
    summary_line,
    sweep_rows,
    unlisted,
)
from .text import group_lines

#: Rows shown in the table; the rest are counted (a step summary is limited to 1 MiB).
MAX_ROWS = 1000

_MARKUP = re.compile(r"([\\`*_{}\[\]()<>#+\-.!|~=:&\"'$])")


def escape(text: str) -> str:
    """``text`` as literal Markdown inline text on one line.

    Examples
    --------
    >>> escape("a|b_<script>.stl")
    'a\\\\|b\\\\_\\\\<script\\\\>\\\\.stl'

    An ``@`` gets a zero-width space after it, so ``@user`` in a name pings nobody when the
    summary is posted as a pull-request comment:

    >>> escape("@octocat.stl")
    '@&#8203;octocat\\\\.stl'
    """
    return _MARKUP.sub(r"\\\1", printable(text)).replace("@", "@&#8203;")


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    s = summary(result)
    icon = "✅" if s["passed"] else "❌"
    lines = [f"## {icon} meshcheck: {'PASS' if s['passed'] else 'FAIL'}", ""]
    lines.append(summary_line(result))  # names no part: no markup to fear
    lines.append("")
    view = view or View()
    if result.tests:
        lines += _tests_lines(result, view)
        result = run_remainder(result)
        lines += _resolved_lines(result)
    else:
        lines += _findings_lines(result, view)
    lines += _sweep_lines(result)
    lines += _audit_lines(result)
    for pose in result.poses:
        lines += [f"Pose of {escape(pose.path)}: {escape(pose.text())}", ""]
    if result.settings.config_path:
        lines += [f"Configuration: {escape(result.settings.config_path)}", ""]
    if result.warnings:
        lines.append("Warnings:")
        lines.append("")
        lines += [f"- {escape(w)}" for w in result.warnings]
        lines.append("")
    return "\n".join(lines)


def _tests_lines(result: CheckResult, view: View) -> list[str]:
    """A run of clash tests: the table of its tests, then a section per test (its heading, its
    summary line, and its findings as the summary of that test alone shows them)."""
    lines = ["| | Test | Sides | Clearance | Fails on | Findings |", "|---|---|---|---|---|---|"]
    parts = sections(result)
    for section in parts:
        test = section.test
        clearance = "" if test.clearance is None else f"{test.clearance:g}"
        cells = [
            "✅" if section.passed else "❌",
            escape(test.name),
            escape(test.describe()),
            clearance,
            ", ".join(str(s) for s in test.fail_on) or "nothing",
            str(len(section.findings)),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    for section in parts:
        icon = "✅" if section.passed else "❌"
        verdict = "PASS" if section.passed else "FAIL"
        lines += [f"### {icon} {escape(section.test.name)}: {verdict}", ""]
        lines += [escape(clash_test_settings(section.test)), ""]
        lines += [summary_line(section), ""]
        lines += _findings_lines(section, view)
    return lines


def _findings_lines(result: CheckResult, view: View) -> list[str]:
    """The findings' table, clash groups, what the view left out, and the resolved findings."""
    lines: list[str] = []
    rows = [f for f in ordered(result) if view.shows(result, f)]
    if rows:
        has_baseline = result.baseline is not None
        header = ["", "Status", "Part A", "Part B", "Detail", "ID"]
        if has_baseline:
            header.insert(2, "Baseline")
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|" + "---|" * len(header))
        tol = resolution(result)
        for f in rows[:MAX_ROWS]:
            mark = "❌" if result.is_failing(f) else "☑️" if f.is_approved else "⚠️"
            detail = describe(f, tol)
            if f.is_approved:
                detail += f"  approved: {escape(f.approval_reason)}"
            cells = [mark, str(f.status), escape(f.a), escape(f.b), detail, f"`{f.id}`"]
            if has_baseline:
                cells.insert(2, result.baseline_state(f) or "")
            lines.append("| " + " | ".join(cells) + " |")
        if len(rows) > MAX_ROWS:
            more = plural(len(rows) - MAX_ROWS, "more finding")
            lines += ["", f"... and {more} (see the report)"]
        lines.append("")
    elif not result.findings:
        lines += ["No findings.", ""]
    groups = clash_groups(rows)
    if groups:
        lines += ["Clash groups:", ""]
        for g in groups:
            head, members = group_lines(g, escape)
            lines.append(f"- `{g.id}` {head}")
            lines += [f"  - `{finding_id}` {names}" for finding_id, names in members]
        lines.append("")
    note = unlisted(result, view, len(rows))
    if note:
        lines += [note, ""]
    return lines + _resolved_lines(result)


def _resolved_lines(result: CheckResult) -> list[str]:
    """The baseline's findings this result no longer has."""
    lines: list[str] = []
    if result.baseline is not None:
        resolved = result.baseline.resolved(result.findings)
        if resolved:
            lines.append(f"Resolved since the baseline ({len(resolved)}):")
            lines.append("")
            for r in resolved[:MAX_ROWS]:
                lines.append(f"- {r.status}: {escape(r.a)} and {escape(r.b)} `{r.id}`")
            lines.append("")
    return lines


def _sweep_lines(result: CheckResult) -> list[str]:
    """The sweep's link pairs that are not proven never, with their witness poses, those that
    fail the run (``CheckResult.failing_sweeps``) first and marked."""
    rows = sweep_rows(result)
    if not rows:
        return []
    lines = ["Sweep (link pairs not proven apart over the joint ranges):", ""]
    lines += ["| Class | Robot | Link A | Link B | Witness |", "|---|---|---|---|---|"]
    for robot, pair, fails in rows[:MAX_ROWS]:
        status = (
            ("FAIL " if fails else "") + pair.status + (" (adjacent)" if pair.is_adjacent else "")
        )
        witness = pose_text(pair)
        if pair.approval_reason is not None:
            witness += f" (approved: {pair.approval_reason})"
        cells = [status, escape(robot), escape(pair.a), escape(pair.b), escape(witness)]
        lines.append("| " + " | ".join(cells) + " |")
    if len(rows) > MAX_ROWS:
        lines += ["", f"... and {plural(len(rows) - MAX_ROWS, 'more pair')} (see the report)"]
    return [*lines, ""]


def _audit_lines(result: CheckResult) -> list[str]:
    """The audited SRDF entries not proven never, with their witness poses, those that fail
    the run first and marked; then the audit's counts."""
    if result.audit is None:
        return []
    audit = result.audit
    lines = ["SRDF audit:", ""]
    rows = audit_rows(result)
    if rows:
        lines += [
            "| Class | Reason | Line | Link A | Link B | Witness |",
            "|---|---|---|---|---|---|",
        ]
        for pair, fails in rows[:MAX_ROWS]:
            status = ("FAIL " if fails else "") + pair.status
            cells = [
                status,
                escape(pair.reason or "no reason"),
                str(pair.line),
                escape(pair.a),
                escape(pair.b),
                escape(pose_text(pair.sweep)),
            ]
            lines.append("| " + " | ".join(cells) + " |")
        if len(rows) > MAX_ROWS:
            left = len(rows) - MAX_ROWS
            lines += [
                "",
                f"... and {left} more {'entry' if left == 1 else 'entries'} (see the report)",
            ]
        lines.append("")
    return [*lines, escape(audit.summary()), ""]
