"""Results -> text, JSON, JUnit XML or GitHub annotations, and the exit status, decided here once.

Every format shows each finding's stable ID (``Finding.id``: 12 hex digits from the sorted part
names and the two meshes' content), so a CI history can follow one finding across runs.
"""

from __future__ import annotations

import json
from collections.abc import Collection

from .errors import ExitStatus
from .results import CLEARANCE, INTERFERENCE, STATUSES, TOUCHING, CheckResult, Finding

FORMATS = ("text", "json", "junit", "github")


def default_fail_on(result: CheckResult) -> tuple[str, ...]:
    """Interference always fails the run; clearance violations too when a clearance is set."""
    return (INTERFERENCE, CLEARANCE) if result.clearance is not None else (INTERFERENCE,)


def resolve_fail_on(result: CheckResult, fail_on: Collection[str] | None) -> tuple[str, ...]:
    """``fail_on`` as a tuple, or the default for ``result`` when it is None."""
    return default_fail_on(result) if fail_on is None else tuple(fail_on)


def is_failing(finding: Finding, fail_on: Collection[str]) -> bool:
    """True when ``finding`` fails the run: its status is in ``fail_on`` and it is not approved."""
    return finding.status in fail_on and finding.approved is None


def exit_status(result: CheckResult, *, fail_on: Collection[str] | None = None) -> ExitStatus:
    """``FAILED`` when an unapproved finding has a status in ``fail_on``, else ``OK``."""
    fail_on = resolve_fail_on(result, fail_on)
    failed = any(is_failing(f, fail_on) for f in result.findings)
    return ExitStatus.FAILED if failed else ExitStatus.OK


def summary(result: CheckResult, *, fail_on: Collection[str] | None = None) -> dict:
    """Counts by status, approved findings, and whether the run passes.

    The keys named by a status (``interference``, ``touching``, ``clearance``) count unapproved
    findings; ``required_clearance`` is the --clearance setting (None when not set).
    """
    fail_on = resolve_fail_on(result, fail_on)
    counts = {status: result.count(status) for status in STATUSES}
    return {
        "parts": len(result.parts),
        "pairs_checked": result.pairs_checked,
        **counts,
        "approved": sum(1 for f in result.findings if f.approved is not None),
        "failed": sum(1 for f in result.findings if is_failing(f, fail_on)),
        "fail_on": list(fail_on),
        "tolerance": result.tolerance,
        "required_clearance": result.clearance,
        "warnings": list(result.warnings),
        "passed": exit_status(result, fail_on=fail_on) == ExitStatus.OK,
    }


def render(
    result: CheckResult, fmt: str = "text", *, fail_on: Collection[str] | None = None
) -> str:
    """Render ``result`` in ``fmt`` (one of ``FORMATS``), ending with a newline."""
    renderers = {
        "text": render_text,
        "json": render_json,
        "junit": render_junit,
        "github": render_github,
    }
    if fmt not in renderers:
        raise ValueError(f"unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
    return renderers[fmt](result, fail_on=fail_on)


def render_json(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    doc = {
        "results": [f.to_dict() for f in result.findings],
        "parts": [p.to_dict() for p in result.parts],
        "summary": summary(result, fail_on=fail_on),
    }
    return json.dumps(doc, indent=2, sort_keys=False) + "\n"


def describe(finding: Finding) -> str:
    """One-line measurements of a finding: depth or distance, volume, location."""
    detail = f"distance {finding.distance:.6g}"
    if finding.depth is not None:
        detail = f"depth {finding.depth:.6g}"
    if finding.volume is not None:
        detail += f"  volume {finding.volume:.6g}"
    if finding.is_surface_only:
        detail += "  (surface only)"
    if finding.location is not None:
        c = finding.location.centroid
        detail += f"  at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g})"
    return detail


def summary_line(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    """``PASS: 6 parts, 1 interference, ...`` without a newline."""
    s = summary(result, fail_on=fail_on)
    verdict = "PASS" if s["passed"] else "FAIL"
    parts = [f"{s[INTERFERENCE]} interference", f"{s[TOUCHING]} touching"]
    if result.clearance is not None:
        parts.append(f"{s[CLEARANCE]} clearance (< {result.clearance:g})")
    if s["approved"]:
        parts.append(f"{s['approved']} approved")
    return (
        f"{verdict}: {len(result.parts)} parts, {', '.join(parts)} "
        f"(tolerance {result.tolerance:.3g})"
    )


def render_text(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    rows = []
    for f in result.findings:
        status = f.status + (" (approved)" if f.approved else "")
        detail = describe(f) + (f"  approved: {f.approved}" if f.approved else "")
        rows.append((f.id, status, f.a, f.b, detail))
    lines = []
    if rows:
        header = ("ID", "STATUS", "PART A", "PART B", "DETAIL")
        widths = [max(len(r[k]) for r in [header, *rows]) for k in range(4)]
        for r in [header, *rows]:
            lines.append("  ".join(r[k].ljust(widths[k]) for k in range(4)) + "  " + r[4])
    lines.append(summary_line(result, fail_on=fail_on))
    return "\n".join(lines) + "\n"


def render_junit(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    """JUnit XML: one test case per finding, plus one per pair (or part) found clear.

    A finding that fails the run is a ``<failure>``, an approved one is ``<skipped>``, others
    (touching, unrequested clearance) pass with their measurements in ``<system-out>``. When the
    pipeline names the pairs it checked, each clear pair is a passing test case; otherwise each
    part without findings is one. The ``<testsuite>`` carries the counts.
    """
    from xml.etree import ElementTree as ET

    fail_on = resolve_fail_on(result, fail_on)
    paths = {p.name: p.path for p in result.parts}
    cases = []
    for f in result.findings:
        case = ET.Element(
            "testcase",
            classname=f"meshcheck.{f.status}",
            name=f"{f.a} <-> {f.b} [{f.id}]",
            file=paths.get(f.a, f.a.split("#")[0]),
            time="0",
        )
        message = f"{f.status}: {f.a} and {f.b}: {describe(f)}"
        props = ET.SubElement(case, "properties")
        for key, value in (("id", f.id), ("status", f.status), ("a", f.a), ("b", f.b)):
            ET.SubElement(props, "property", name=key, value=value)
        if f.approved is not None:
            ET.SubElement(case, "skipped", message=f"approved: {f.approved}")
        elif is_failing(f, fail_on):
            failure = ET.SubElement(case, "failure", message=message, type=f.status)
            failure.text = json.dumps(f.to_dict(), indent=2)
        else:
            ET.SubElement(case, "system-out").text = message
        cases.append(case)

    found = {(f.a, f.b) for f in result.findings}
    if result.checked_pairs:
        for a, b in sorted({tuple(sorted(p)) for p in result.checked_pairs} - found):
            cases.append(
                ET.Element("testcase", classname="meshcheck.clear", name=f"{a} <-> {b}", time="0")
            )
    else:
        named = {n for pair in found for n in pair}
        for part in result.parts:
            if part.name not in named:
                cases.append(
                    ET.Element(
                        "testcase", classname="meshcheck.clear",
                        name=f"{part.name}: no findings", file=part.path, time="0",
                    )
                )

    failures = sum(1 for c in cases if c.find("failure") is not None)
    skipped = sum(1 for c in cases if c.find("skipped") is not None)
    counts = {
        "tests": str(len(cases)),
        "failures": str(failures),
        "errors": "0",
        "skipped": str(skipped),
        "time": "0",
    }
    root = ET.Element("testsuites", name="meshcheck", **counts)
    suite = ET.SubElement(root, "testsuite", name="meshcheck", **counts)
    props = ET.SubElement(suite, "properties")
    settings = {
        "parts": len(result.parts),
        "pairs_checked": result.pairs_checked,
        "tolerance": result.tolerance,
        "clearance": result.clearance,
        "fail_on": ",".join(fail_on),
    }
    for key, value in settings.items():
        ET.SubElement(props, "property", name=key, value="" if value is None else str(value))
    suite.extend(cases)
    if result.warnings:
        ET.SubElement(suite, "system-err").text = "\n".join(
            f"warning: {w}" for w in result.warnings
        )
    ET.indent(root)
    body = ET.tostring(root, encoding="unicode")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + body + "\n"


def _gh_data(text: str) -> str:
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _gh_property(text: str) -> str:
    return _gh_data(text).replace(":", "%3A").replace(",", "%2C")


def render_github(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    """GitHub Actions workflow commands, then the summary line.

    ``::error`` for each finding that fails the run, ``::notice`` for approved findings and
    touching pairs that do not fail it, ``::warning`` for other findings and input warnings.
    Annotations point at the file of the pair's first part.
    """
    fail_on = resolve_fail_on(result, fail_on)
    paths = {p.name: p.path for p in result.parts}
    lines = []
    for f in result.findings:
        if f.approved is not None:
            level, extra = "notice", f" (approved: {f.approved})"
        elif is_failing(f, fail_on):
            level, extra = "error", ""
        elif f.status == TOUCHING:
            level, extra = "notice", ""  # contact is usually by design: keep it out of warnings
        else:
            level, extra = "warning", ""
        file = paths.get(f.a, f.a.split("#")[0])
        title = f"meshcheck {f.status} [{f.id}]"
        message = f"{f.a} and {f.b}: {f.status}, {describe(f)}{extra}"
        lines.append(
            f"::{level} file={_gh_property(file)},title={_gh_property(title)}::{_gh_data(message)}"
        )
    for w in result.warnings:
        lines.append(f"::warning title=meshcheck input::{_gh_data(w)}")
    lines.append(summary_line(result, fail_on=fail_on))
    return "\n".join(lines) + "\n"
