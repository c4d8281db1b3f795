"""Results -> text or JSON, and the exit status, decided here once."""

from __future__ import annotations

import json
from collections.abc import Collection

from .errors import ExitStatus
from .results import CLEARANCE, INTERFERENCE, STATUSES, TOUCHING, CheckResult

FORMATS = ("text", "json")


def default_fail_on(result: CheckResult) -> tuple[str, ...]:
    """Interference always fails the run; clearance violations too when a clearance was asked for."""
    return (INTERFERENCE, CLEARANCE) if result.clearance is not None else (INTERFERENCE,)


def exit_status(result: CheckResult, *, fail_on: Collection[str] | None = None) -> ExitStatus:
    """``FAILED`` when an unapproved finding has a status in ``fail_on``, else ``OK``."""
    fail_on = default_fail_on(result) if fail_on is None else fail_on
    failed = any(f.status in fail_on and f.approved is None for f in result.findings)
    return ExitStatus.FAILED if failed else ExitStatus.OK


def summary(result: CheckResult, *, fail_on: Collection[str] | None = None) -> dict:
    """Counts by status, approved findings, and whether the run passes."""
    counts = {status: result.count(status) for status in STATUSES}
    return {
        "parts": len(result.parts),
        "pairs_checked": result.pairs_checked,
        **counts,
        "approved": sum(1 for f in result.findings if f.approved is not None),
        "tolerance": result.tolerance,
        "clearance": result.clearance,
        "passed": exit_status(result, fail_on=fail_on) == ExitStatus.OK,
    }


def render(result: CheckResult, fmt: str = "text", *, fail_on: Collection[str] | None = None) -> str:
    """Render ``result`` in ``fmt`` (one of ``FORMATS``), ending with a newline."""
    if fmt == "json":
        return render_json(result, fail_on=fail_on)
    return render_text(result, fail_on=fail_on)


def render_json(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    doc = {
        "results": [f.to_dict() for f in result.findings],
        "parts": [p.to_dict() for p in result.parts],
        "summary": summary(result, fail_on=fail_on),
    }
    return json.dumps(doc, indent=2, sort_keys=False) + "\n"


def render_text(result: CheckResult, *, fail_on: Collection[str] | None = None) -> str:
    rows = []
    for f in result.findings:
        status = f.status + (" (approved)" if f.approved else "")
        detail = f"distance {f.distance:.6g}"
        if f.depth is not None:
            detail = f"depth {f.depth:.6g}"
        if f.volume is not None:
            detail += f"  volume {f.volume:.6g}"
        if f.is_surface_only:
            detail += "  (surface only)"
        if f.location is not None:
            c = f.location.centroid
            detail += f"  at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g})"
        rows.append((status, f.a, f.b, detail))
    lines = []
    if rows:
        header = ("STATUS", "PART A", "PART B", "DETAIL")
        widths = [max(len(r[k]) for r in [header, *rows]) for k in range(3)]
        for r in [header, *rows]:
            lines.append("  ".join(r[k].ljust(widths[k]) for k in range(3)) + "  " + r[3])
    s = summary(result, fail_on=fail_on)
    verdict = "PASS" if s["passed"] else "FAIL"
    parts = [f"{s[INTERFERENCE]} interference", f"{s[TOUCHING]} touching"]
    if result.clearance is not None:
        parts.append(f"{s[CLEARANCE]} clearance (< {result.clearance:g})")
    if s["approved"]:
        parts.append(f"{s['approved']} approved")
    lines.append(
        f"{verdict}: {len(result.parts)} parts, {', '.join(parts)} "
        f"(tolerance {result.tolerance:.3g})"
    )
    return "\n".join(lines) + "\n"
