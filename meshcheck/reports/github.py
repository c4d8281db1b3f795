"""GitHub Actions workflow commands: an annotation per finding, then the summary line.

``::error`` for each finding that fails the run, ``::notice`` for approved findings and touching
pairs that do not fail it, ``::warning`` for other findings and input warnings. Annotations point
at the file of the pair's first part.

GitHub shows at most ``LIMIT`` annotations of each type from one step and drops the rest without
a word. So each type is sorted most severe first; when there are more than ``LIMIT``, the last
annotation of that type says how many more there are, and those are printed as plain log lines
(``meshcheck: ...``), so nothing is lost.

An audited SRDF entry that disables a collision is an ``::error`` on its line of the SRDF (a
``::warning`` when nothing fails the run); the pose each robot was checked at is a log line
before the summary.

In a run of clash tests each annotation's title and message start with its test's name, and a
log line per test (its name and summary line) comes before the run's summary line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..outcome import CheckResult
from ..results import Finding, Verdict
from .common import (
    View,
    audit_message,
    describe,
    ordered,
    part_file,
    part_files,
    plural,
    pose_lines,
    printable,
    resolution,
    sections,
    summary_line,
    sweep_message,
)

#: Annotations GitHub shows per type (error, warning, notice) from one step.
LIMIT = 10
LEVELS = ("error", "warning", "notice")


def _data(text: str) -> str:
    """A workflow command's message: printable, with ``%`` and line ends escaped."""
    return printable(text).replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _property(text: str) -> str:
    """A workflow command's property value: also ``:`` and ``,`` escaped."""
    return _data(text).replace(":", "%3A").replace(",", "%2C")


def level(result: CheckResult, finding: Finding) -> str:
    if result.is_failing(finding):
        return "error"
    if finding.is_approved or finding.status == Verdict.TOUCHING:
        return "notice"  # contact is usually by design: keep it out of warnings
    return "warning"


@dataclass(frozen=True)
class _Annotation:
    """One workflow command's parts: its properties (escaped), title and message (raw)."""

    properties: str
    title: str
    message: str


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    # most severe first within each level
    annotations: dict[str, list[_Annotation]] = {name: [] for name in LEVELS}
    paths = part_files(result)
    tol = resolution(result)
    for f in ordered(result):
        extra = f" (approved: {f.approval_reason})" if f.is_approved else ""
        state = result.baseline_state(f)
        test = f"{f.test}: " if f.test else ""
        title = f"meshcheck {test}{f.status} [{f.id}]" + (f" {state}" if state else "")
        message = f"{test}{f.a} and {f.b}: {f.status}, {describe(f, tol)}{extra}"
        props = f"file={_property(part_file(paths, f.a))},title={_property(title)}"
        annotations[level(result, f)].append(_Annotation(props, title, message))
    for robot, pair in result.failing_sweeps:
        title = f"meshcheck {pair.verdict} in motion"
        props = f"file={_property(robot.path)},title={_property(title)}"
        annotations["error"].append(_Annotation(props, title, sweep_message(robot, pair)))
    if result.audit is not None:
        for pair in result.audit.pairs:
            if not pair.is_wrong:
                continue
            title = "meshcheck: SRDF disables a collision"
            props = f"file={_property(result.audit.path)},line={pair.line},title={_property(title)}"
            name = "error" if result.is_failing_audit(pair) else "warning"
            message = audit_message(result.audit, pair)
            annotations[name].append(_Annotation(props, title, message))
    for w in result.warnings:
        annotations["warning"].append(_Annotation("title=meshcheck input", "meshcheck input", w))

    lines, overflow = [], []
    for name in LEVELS:
        entries = annotations[name]
        shown = entries if len(entries) <= LIMIT else entries[: LIMIT - 1]
        for a in shown:
            lines.append(f"::{name} {a.properties}::{_data(a.message)}")
        rest = entries[len(shown) :]
        if rest:
            more = f"{plural(len(rest), 'more ' + name)} not annotated (GitHub shows {LIMIT})"
            lines.append(f"::{name} title=meshcheck::{more}: see the log of this step")
            overflow += [f"meshcheck: {name}: {a.title}: {printable(a.message)}" for a in rest]
    if result.baseline is not None:
        for r in result.baseline.resolved(result.findings):
            overflow.append(
                f"meshcheck: resolved since the baseline: {printable(r.a)} and "
                f"{printable(r.b)}: {r.status} [{r.id}]"
            )
    lines += overflow
    lines += [f"meshcheck: {line}" for line in pose_lines(result)]
    for section in sections(result):  # a run of clash tests: each test's summary
        lines.append(f"meshcheck: test {printable(section.test.name)}: {summary_line(section)}")
    lines.append(summary_line(result))
    return "\n".join(lines) + "\n"
