"""What every format shares: safe names, the summary, figures rounded to one resolution.

Part names come from files (paths, glTF node names, 3MF object names): they may hold newlines,
terminal escapes, bidirectional overrides or bytes that are not UTF-8. ``printable`` is the one
place they are made safe to show; every format that prints a name as text goes through it.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

from ..config import ClashTest
from ..outcome import CheckResult
from ..results import (
    FINDING_STATUSES,
    AuditedPair,
    Finding,
    PairSweep,
    RobotSweep,
    SrdfAudit,
    SweepStatus,
    Verdict,
)

_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def printable(text: str) -> str:
    """``text`` with every character that is not printable written as a visible escape.

    Control characters (C0, DEL, C1: newlines, ``ESC``), format characters (bidirectional
    overrides, zero-width), line and paragraph separators and other non-printing code points become
    ``\\n``, ``\\x1b``, ``\\u202e``...; a byte that was not UTF-8 in a file name (kept by Python as
    a lone surrogate) becomes ``\\xNN``. The result is one line that moves no cursor and encodes
    as UTF-8. Backslashes are kept as they are, so Windows paths stay readable.

    Examples
    --------
    >>> printable("x\\nPASS: 2 parts\\x1b[2J.stl")
    'x\\\\nPASS: 2 parts\\\\x1b[2J.stl'
    >>> printable("caf\\udce9.stl")
    'caf\\\\xe9.stl'
    >>> printable("plain name (1).stl")
    'plain name (1).stl'

    A CI runner's command syntax in a name (``##[error]``, Azure's ``##vso[``) is escaped too, so
    a part name can never issue a runner command from a log line:

    >>> printable("##[error]FORGED.stl")
    '#\\\\x23[error]FORGED.stl'
    """
    if "##" in text:
        text = _RUNNER_COMMAND.sub("#\\\\x23", text)
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else _escape(ch) for ch in text)


#: The start of a runner command in a log line: GitHub's old ``##[error]`` syntax, Azure's
#: ``##vso[``.
_RUNNER_COMMAND = re.compile(r"##(?=\[|vso\[)", re.IGNORECASE)


def _escape(ch: str) -> str:
    if ch in _NAMED:
        return _NAMED[ch]
    code = ord(ch)
    if 0xDC80 <= code <= 0xDCFF:  # os.fsdecode's surrogateescape: the original byte
        return f"\\x{code - 0xDC00:02x}"
    if code < 0x100:
        return f"\\x{code:02x}"
    if code < 0x10000:
        return f"\\u{code:04x}"
    return f"\\U{code:08x}"


def plural(count: int, noun: str) -> str:
    """``1 part``, ``2 parts``."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


_TOLERANCE_RULE = (
    "per pair: max(1e-5 x the smaller part's bounding-box diagonal, "
    "8 x 2^-23 x the largest coordinate of its parts stored in float32)"
)


def summary(result: CheckResult) -> dict:
    """Counts by status, approved findings, the settings that decide, and whether the run passes.

    The keys named by a status (``interference``, ``touching``, ``clearance``) count unapproved
    findings; ``required_clearance`` is the --clearance setting (None when not set);
    ``tolerance`` is the one the user set, None when each pair had its own (then every finding
    carries the tolerance that decided it); ``config`` the configuration file used, if any.
    With a baseline, ``baseline`` names its file and ``new``, ``active`` and ``resolved`` count
    the findings against it; ``fail_on_new`` says whether only new findings fail. ``pose`` is
    the joint values each robot (and ``[[joint]]`` mechanism) was checked at, by its URDF (or
    configuration file): ``{PATH: {joint: value}}``, every joint a pose sets; None without one.
    With an SRDF audit, ``wrongly_disabled`` counts its entries that disable a collision. A run
    of clash tests counts the findings of all its tests, and adds ``tests`` (how many) and
    ``failed_tests`` (their names); its ``tolerance``, ``required_clearance`` and ``fail_on``
    are the defaults its tests started from.
    """
    counts = {str(status): result.count(status) for status in FINDING_STATUSES}
    doc = {
        "parts": len(result.parts),
        "pairs_checked": len(result.checked_pairs),
        **counts,
        "approved": sum(1 for f in result.findings if f.is_approved),
        "failed": sum(1 for f in result.findings if result.is_failing(f)),
        "failed_in_motion": len(result.failing_sweeps),
        "fail_on": [str(s) for s in result.fail_on],
        "fail_on_new": result.settings.fail_on_new,
        "tolerance": result.tolerance,
        "tolerance_rule": "given" if result.tolerance is not None else _TOLERANCE_RULE,
        "required_clearance": result.clearance,
        "units": result.units,
        "config": result.settings.config_path,
        "pose": {p.path: p.to_dict() for p in result.poses} if result.poses else None,
        "warnings": list(result.warnings),
        "passed": result.passed,
    }
    if result.sweeps or result.audit is not None:  # the work budget link pairs were swept in
        doc["sweep_budget"] = result.settings.motion.budget
    if result.audit is not None:
        doc["wrongly_disabled"] = sum(p.is_wrong for p in result.audit.pairs)
    if result.baseline is not None:
        states = [result.baseline_state(f) for f in result.findings]
        doc["baseline"] = result.baseline.path
        doc["new"] = states.count("new")
        doc["active"] = states.count("active")
        doc["resolved"] = len(result.baseline.resolved(result.findings))
    if result.tests:
        doc["tests"] = len(result.tests)
        doc["failed_tests"] = result.failed_tests
    return doc


def summary_line(result: CheckResult) -> str:
    """``PASS: 6 parts, 1 interference, ...`` without a newline; names no part."""
    return " ".join(summary_chunks(result))


def summary_chunks(result: CheckResult) -> list[str]:
    """The summary line in the pieces a narrow report may wrap it between (each piece whole):
    the verdict with the part count, each count, then the tolerance and unit in parentheses.

    Examples
    --------
    >>> from meshcheck.outcome import CheckResult
    >>> from meshcheck.settings import Settings
    >>> summary_chunks(CheckResult([], [], Settings()))
    ['PASS: 0 parts,', '0 interference,', '0 touching', '(tolerance per pair, mm)']
    """
    s = summary(result)
    verdict = "PASS" if s["passed"] else "FAIL"
    if result.tests:  # the tests and how many fail; each test's section has its counts
        parts = [plural(s["tests"], "test"), f"{len(s['failed_tests'])} failing"]
    else:
        parts = [f"{s[Verdict.INTERFERENCE]} interference", f"{s[Verdict.TOUCHING]} touching"]
        if s[Verdict.DUPLICATE]:
            parts.insert(0, f"{s[Verdict.DUPLICATE]} duplicate")
        if result.clearance is not None:
            parts.append(f"{s[Verdict.CLEARANCE]} clearance (< {result.clearance:g})")
        if s["approved"]:
            parts.append(f"{s['approved']} approved")
    if s["failed_in_motion"]:
        parts.append(f"{s['failed_in_motion']} colliding in motion")
    if result.audit is not None:
        parts.append(f"{s['wrongly_disabled']} wrongly disabled in the SRDF")
    if result.baseline is not None:
        parts.extend([f"{s['new']} new", f"{s['resolved']} resolved"])
    counts = [f"{part}," for part in parts[:-1]] + parts[-1:]
    return [
        f"{verdict}: {plural(len(result.parts), 'part')},",
        *counts,
        f"(tolerance {tolerance_text(result)}, {result.units})",
    ]


def tolerance_text(result: CheckResult) -> str:
    """The given tolerance, or ``per pair`` with the range the findings were decided with;
    ``per test`` for a run of clash tests (each test's section says its own)."""
    if result.tests:
        return "per test"
    if result.tolerance is not None:
        return f"{result.tolerance:.3g}"
    used = [f.tolerance for f in result.findings if f.tolerance is not None]
    if not used:
        return "per pair"
    low, high = min(used), max(used)
    return f"per pair, {low:.2g}" if low == high else f"per pair, {low:.2g}-{high:.2g}"


def resolution(result: CheckResult) -> float | None:
    """The one decimal place every length of a report is printed to, as a length: the given
    tolerance, else the finest tolerance that decided a finding (None: no finding).

    One place for the whole report, so identical clashes print identically whatever tolerance
    each pair had (the float32 floor grows with a copy's distance from the origin), and a small
    part's depth never rounds away beside a large part's.
    """
    if result.tolerance is not None:
        used = [result.tolerance]
    else:
        used = [f.tolerance for f in result.findings if f.tolerance is not None]
    used = [t for t in used if math.isfinite(t) and t > 0]
    return min(used) if used else None


def length(value: float, tolerance: float | None = None) -> str:
    """A length rounded to the decimal place ``tolerance`` resolves (``resolution``); 6
    significant digits without one. Every format that prints a length prints it so.

    Examples
    --------
    >>> length(3.10862e-15, 1e-4), length(40.00001234, 4e-4), length(-1e-9, 1e-5)
    ('0', '40', '0')
    >>> length(0.123456789)
    '0.123457'
    """
    value = float(value)
    if tolerance is None or not math.isfinite(value):
        text = f"{value:.6g}"
    else:
        decimals = min(max(-math.floor(math.log10(tolerance)), 0), 15)
        text = f"{value:.{decimals}f}"
        if "." in text:
            text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def volume(value: float) -> str:
    """A volume, 4 significant digits (its unit is the cube of the report's).

    Examples
    --------
    >>> volume(159.51234), volume(0.000123456)
    ('159.5', '0.0001235')
    """
    return f"{float(value):.4g}"


def figures(finding: Finding, tolerance: float | None) -> dict[str, str | None]:
    """A finding's ``distance``, ``depth`` and ``volume`` as every report prints them (None when
    the finding has no such figure), lengths to ``tolerance`` (``resolution``)."""
    return {
        "distance": length(finding.distance, tolerance),
        "depth": None if finding.depth is None else length(finding.depth, tolerance),
        "volume": None if finding.volume is None else volume(finding.volume),
    }


#: Copies a duplicate finding's one-line description names (the JSON report lists them all).
_MEMBERS_SHOWN = 4


def describe(finding: Finding, tolerance: float | None = None) -> str:
    """One-line measurements of a finding: depth or distance, volume, location.

    Lengths are rounded to what ``tolerance`` (the report's ``resolution``) can resolve.
    """
    shown = figures(finding, tolerance)
    detail = f"distance {shown['distance']}"
    if finding.status == Verdict.DUPLICATE:
        names = [printable(n) for n in finding.members]
        copies = ", ".join(names[:_MEMBERS_SHOWN])
        if len(names) > _MEMBERS_SHOWN:
            copies += f" and {len(names) - _MEMBERS_SHOWN} more"
        detail = f"{len(names)} copies at the same spot: {copies}"
    if finding.depth is not None:
        detail = f"depth {shown['depth']}"
    if finding.volume is not None:
        detail += f"  volume {shown['volume']}"
    if finding.is_surface_only:
        detail += "  (surface only)"
    if finding.location is not None:
        c = [length(x, tolerance) for x in finding.location.centroid]
        detail += f"  at ({c[0]}, {c[1]}, {c[2]})"
    if finding.elements:
        detail += "  collision elements: " + printable(elements_text(finding))
    return detail


def elements_text(finding: Finding) -> str:
    """The collision elements a finding involves (``Finding.elements``), as ``base/0,
    base/1 (post)``; ``""`` without."""
    return ", ".join(e.label() for e in finding.elements)


def shared_prefix(names: list[str]) -> str:
    """The directory prefix (ending in ``/``) all ``names`` share, or ``""``: the text and HTML
    reports show part names below it, naming it once.

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


def part_file(paths: dict[str, str], name: str) -> str:
    """The file a part came from (``PATH`` of ``PATH#NODE``), from ``part_files(result)``."""
    return paths.get(name, name.split("#")[0])


def part_files(result: CheckResult) -> dict[str, str]:
    """Part name -> the file it came from."""
    return {p.name: p.path for p in result.parts}


@dataclass(frozen=True)
class View:
    """How much of a result a person-facing report shows; machine formats show everything.

    Attributes
    ----------
    width : int
        Columns the text report fits (the terminal's, or 80 without one).
    is_quiet : bool
        Only the findings that fail the run, and the summary.
    is_touching_listed : bool
        False leaves touching findings out of the table; the summary still counts them.
    """

    width: int = 80
    is_quiet: bool = False
    is_touching_listed: bool = True

    def shows(self, result: CheckResult, finding: Finding) -> bool:
        """True when ``finding`` has a row under this view."""
        if self.is_quiet and not result.is_failing(finding):
            return False
        return self.is_touching_listed or finding.status != Verdict.TOUCHING


def severity(result: CheckResult, finding: Finding) -> tuple:
    """Sort key, most severe first: failing findings, then unapproved, then approved; within
    each, interference (deepest first), clearance (closest first), touching; then by names."""
    rank = 0 if result.is_failing(finding) else 1 if not finding.is_approved else 2
    status = FINDING_STATUSES.index(finding.status)
    if finding.status == Verdict.INTERFERENCE:
        # unknown depth (surface only) after the measured ones
        measure = -finding.depth if finding.depth is not None else 0.0
    elif finding.status == Verdict.CLEARANCE:
        measure = finding.distance
    else:
        measure = 0.0
    return rank, status, measure, finding.a, finding.b


def unlisted(result: CheckResult, view: View, listed: int) -> str | None:
    """``200 touching findings not listed (--hide-touching)``: what a view left out, or None."""
    left = len(result.findings) - listed
    if left <= 0:
        return None
    why = "--quiet" if view.is_quiet else "--hide-touching"
    kind = "finding" if view.is_quiet else "touching finding"
    return f"{plural(left, kind)} not listed ({why}; counted in the summary)"


def ordered(result: CheckResult) -> list[Finding]:
    """The result's findings most severe first (``severity``): the order of every format."""
    return sorted(result.findings, key=lambda f: severity(result, f))


def sweep_rows(result: CheckResult) -> list[tuple[str, object, bool]]:
    """(robot path, pair, whether it fails the run) of every swept link pair that is not
    proven ``never``: those that fail first (``CheckResult.is_failing_sweep``), then robot by
    robot in link-name order. What the reports list of a sweep."""
    rows = [
        (r.path, p, result.is_failing_sweep(r, p))
        for r in result.sweeps
        for p in r.pairs
        if p.status != SweepStatus.NEVER
    ]
    return sorted(rows, key=lambda row: not row[2])  # stable: robot and link order within


def sweep_message(robot: RobotSweep, pair: PairSweep) -> str:
    """One line on a swept pair that collides: ``MECHANISM: a / b: interference at --pose
    hinge=0.3`` (names printable), ``(approved: reason)`` when an approval rule covers it."""
    text = f"{printable(robot.path)}: {printable(pair.a)} / {printable(pair.b)}: "
    text += printable(pose_text(pair))
    if pair.approval_reason is not None:
        text += f" (approved: {printable(pair.approval_reason)})"
    return text


def pose_text(pair: PairSweep) -> str:
    """How a swept pair collides, the witness as ``--pose`` takes it: ``interference at --pose
    hinge=0.300216643``; the status alone without a witness."""
    if pair.status == SweepStatus.SOMETIMES and pair.witness:
        values = ",".join(f"{name}={value:.9g}" for name, value in pair.witness.items())
        return f"{pair.verdict} at --pose {values}"
    if pair.status == SweepStatus.ALWAYS and pair.verdict:
        return f"{pair.verdict} at every pose"
    return "neither proven apart nor seen colliding" if pair.status == SweepStatus.UNDECIDED else ""


def pose_lines(result: CheckResult) -> list[str]:
    """``pose ROBOT: elbow=2.7925268,shoulder=1.5 (other joints at 0)``: the joint values each
    robot (and ``[[joint]]`` mechanism) of the run was checked at (``RobotPose.text``), names
    printable. What every person-facing format says of the pose."""
    return [f"pose {printable(p.path)}: {printable(p.text())}" for p in result.poses]


def audit_rows(result: CheckResult) -> list[tuple[AuditedPair, bool]]:
    """(entry, whether it fails the run) of every audited SRDF entry not proven never: those
    that fail first (``CheckResult.is_failing_audit``), then in file order. What the reports
    list of an audit."""
    if result.audit is None:
        return []
    rows = [
        (p, result.is_failing_audit(p)) for p in result.audit.pairs if p.status != SweepStatus.NEVER
    ]
    return sorted(rows, key=lambda row: not row[1])


def audit_message(audit: SrdfAudit, pair: AuditedPair) -> str:
    """One line on an audited entry: ``SRDF:LINE: a / b (Never): interference at --pose ...``,
    its verdict as ``pose_text`` gives it (names printable)."""
    text = f"{printable(audit.path)}:{pair.line}: {printable(pair.a)} / {printable(pair.b)} "
    verdict = pose_text(pair.sweep) or "proven never in contact over the joint ranges"
    text += f"({printable(pair.reason or 'no reason')}): {printable(verdict)}"
    if pair.status == SweepStatus.ALWAYS:
        text += "; disabling is right" + (", as Always" if pair.reason.lower() == "never" else "")
    return text


def clash_test_line(test: ClashTest) -> str:
    """A clash test in one line: ``test NAME: A against B; clearance C; tolerance T; fails on
    STATUSES`` (patterns and the name printable)."""
    return printable(f"test {test.name}: ") + clash_test_settings(test)


def clash_test_settings(test: ClashTest) -> str:
    """A clash test's sides and settings: ``A against B; clearance C; tolerance T; fails on
    STATUSES`` (patterns printable)."""
    clearance = "no clearance" if test.clearance is None else f"clearance {test.clearance:g}"
    tolerance = "per pair" if test.tolerance is None else f"{test.tolerance:.3g}"
    fails = ", ".join(str(s) for s in test.fail_on) or "nothing"
    return printable(f"{test.describe()}; {clearance}; tolerance {tolerance}; fails on {fails}")


def sections(result: CheckResult) -> list[CheckResult]:
    """Each clash test's own result (``CheckResult.for_test``), in the run's order; the
    sections of a report of a run of clash tests."""
    return [result.for_test(t.name) for t in result.tests]


def run_remainder(result: CheckResult) -> CheckResult:
    """What a run of clash tests has beside its tests' findings, as a result of no finding and
    no test: its sweeps, warnings, configuration file, and the baseline's findings of tests the
    run no longer has (all resolved); the part of a report after the sections."""
    settings = dataclasses.replace(result.settings, tests=())
    baseline = result.baseline
    if baseline is not None:
        baseline = baseline.other_than([t.name for t in result.tests])
    return dataclasses.replace(
        result, findings=[], settings=settings, baseline=baseline, test_pairs={}, checked_pairs=[]
    )
