"""Results -> text, JSON, JUnit XML or GitHub annotations, and the exit status, decided here once.

Every format shows each finding's stable ID (``Finding.id``: 12 hex digits from the sorted part
names and the two meshes' content), so a CI history can follow one finding across runs.
"""

from __future__ import annotations

import json

from .errors import ExitStatus
from .results import FINDING_STATUSES, CheckResult, Finding, Verdict

FORMATS = ("text", "json", "junit", "github")


def exit_status(result: CheckResult) -> ExitStatus:
    """``FAILED`` when an unapproved finding has a status in the run's ``fail_on``, else ``OK``."""
    return ExitStatus.FAILED if result.failed else ExitStatus.OK


def summary(result: CheckResult) -> dict:
    """Counts by status, approved findings, the settings that decide, and whether the run passes.

    The keys named by a status (``interference``, ``touching``, ``clearance``) count unapproved
    findings; ``required_clearance`` is the --clearance setting (None when not set);
    ``tolerance`` is the one the user set, None when each pair had its own (then every finding
    carries the tolerance that decided it).
    """
    counts = {str(status): result.count(status) for status in FINDING_STATUSES}
    return {
        "parts": len(result.parts),
        "pairs_checked": len(result.checked_pairs),
        **counts,
        "approved": sum(1 for f in result.findings if f.is_approved),
        "failed": sum(1 for f in result.findings if result.is_failing(f)),
        "fail_on": [str(s) for s in result.fail_on],
        "tolerance": result.tolerance,
        "tolerance_rule": "given" if result.tolerance is not None else _TOLERANCE_RULE,
        "required_clearance": result.clearance,
        "config": result.settings.config_path,
        "warnings": list(result.warnings),
        "passed": result.passed,
    }


_TOLERANCE_RULE = (
    "per pair: max(1e-5 x the smaller part's bounding-box diagonal, "
    "8 float32 ulps of the pair's largest coordinate)"
)


def render(result: CheckResult, fmt: str = "text") -> str:
    """Render ``result`` in ``fmt`` (one of ``FORMATS``), ending with a newline."""
    renderers = {
        "text": render_text,
        "json": render_json,
        "junit": render_junit,
        "github": render_github,
    }
    if fmt not in renderers:
        raise ValueError(f"unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
    return renderers[fmt](result)


def render_json(result: CheckResult) -> str:
    doc = {
        "results": [f.to_dict() for f in result.findings],
        "parts": [p.to_dict() for p in result.parts],
        "summary": summary(result),
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


def summary_line(result: CheckResult) -> str:
    """``PASS: 6 parts, 1 interference, ...`` without a newline."""
    s = summary(result)
    verdict = "PASS" if s["passed"] else "FAIL"
    parts = [f"{s[Verdict.INTERFERENCE]} interference", f"{s[Verdict.TOUCHING]} touching"]
    if result.clearance is not None:
        parts.append(f"{s[Verdict.CLEARANCE]} clearance (< {result.clearance:g})")
    if s["approved"]:
        parts.append(f"{s['approved']} approved")
    return (
        f"{verdict}: {len(result.parts)} parts, {', '.join(parts)} "
        f"(tolerance {_tolerance_text(result)})"
    )


def _tolerance_text(result: CheckResult) -> str:
    if result.tolerance is not None:
        return f"{result.tolerance:.3g}"
    used = [f.tolerance for f in result.findings if f.tolerance is not None]
    if not used:
        return "per pair"
    low, high = min(used), max(used)
    return f"per pair, {low:.2g}" if low == high else f"per pair, {low:.2g}-{high:.2g}"


def render_text(result: CheckResult) -> str:
    rows = []
    for f in result.findings:
        status = str(f.status) + (" (approved)" if f.approval_reason else "")
        detail = describe(f) + (f"  approved: {f.approval_reason}" if f.approval_reason else "")
        rows.append((f.id, status, f.a, f.b, detail))
    lines = []
    if rows:
        header = ("ID", "STATUS", "PART A", "PART B", "DETAIL")
        widths = [max(len(r[k]) for r in [header, *rows]) for k in range(4)]
        for r in [header, *rows]:
            lines.append("  ".join(r[k].ljust(widths[k]) for k in range(4)) + "  " + r[4])
    lines.append(summary_line(result))
    return "\n".join(lines) + "\n"


def render_junit(result: CheckResult) -> str:
    """JUnit XML: one test case per finding, plus one per pair (or part) found clear.

    A finding that fails the run is a ``<failure>``, an approved one is ``<skipped>``, others
    (touching, unrequested clearance) pass with their measurements in ``<system-out>``. When the
    pipeline names the pairs it checked, each clear pair is a passing test case; otherwise each
    part without findings is one. The ``<testsuite>`` carries the counts.
    """
    from xml.etree import ElementTree as ET

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
        if f.is_approved:
            ET.SubElement(case, "skipped", message=f"approved: {f.approval_reason}")
        elif result.is_failing(f):
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
                        "testcase",
                        classname="meshcheck.clear",
                        name=f"{part.name}: no findings",
                        file=part.path,
                        time="0",
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
        "pairs_checked": len(result.checked_pairs),
        "tolerance": result.tolerance,
        "clearance": result.clearance,
        "fail_on": ",".join(result.fail_on),
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


def render_github(result: CheckResult) -> str:
    """GitHub Actions workflow commands, then the summary line.

    ``::error`` for each finding that fails the run, ``::notice`` for approved findings and
    touching pairs that do not fail it, ``::warning`` for other findings and input warnings.
    Annotations point at the file of the pair's first part.
    """
    paths = {p.name: p.path for p in result.parts}
    lines = []
    for f in result.findings:
        if f.is_approved:
            level, extra = "notice", f" (approved: {f.approval_reason})"
        elif result.is_failing(f):
            level, extra = "error", ""
        elif f.status == Verdict.TOUCHING:
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
    lines.append(summary_line(result))
    return "\n".join(lines) + "\n"
