"""The text report: a table that fits 100 columns, each finding's detail under its row, a summary.

Part names are shown after the directory prefix every part shares (named once above the table),
cut in the middle when they still do not fit; the JSON report keeps them whole.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

from ..results import CheckResult
from .common import describe, printable, resolution, summary_line

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


def render(result: CheckResult, *, inputs: Sequence[str] = ()) -> str:
    """The table of findings, resolved baseline findings, the configuration file, the summary."""
    prefix = shared_prefix([p.name for p in result.parts])
    has_baseline = result.baseline is not None

    def short(name: str) -> str:
        return printable(name[len(prefix) :] if name.startswith(prefix) else name)

    rows = []
    for f in result.findings:
        status = str(f.status) + (" (approved)" if f.is_approved else "")
        a, b = short(f.a), short(f.b)
        state = result.baseline_state(f) or ""
        detail = describe(f, resolution(result, f))
        if f.is_approved:
            detail += f"  approved: {printable(f.approval_reason)}"
        rows.append((f.id, status, state, a, b, detail))

    lines = []
    if prefix and rows:
        lines.append(f"parts below {printable(prefix)}")
    if rows:
        header = ("ID", "STATUS", "BASELINE", "PART A", "PART B", "")
        status_width = max(len(r[1]) for r in (header, *rows))
        state_width = max(len(r[2]) for r in (header, *rows)) if has_baseline else 0
        fixed = _ID_WIDTH + 2 + status_width + 2 + (state_width + 2 if has_baseline else 0) + 2
        name_width = max((WIDTH - fixed) // 2, 12)
        a_width = min(name_width, max(len(r[3]) for r in (header, *rows)))
        for r in (header, *rows):
            cells = [r[0].ljust(_ID_WIDTH), r[1].ljust(status_width)]
            if has_baseline:
                cells.append(r[2].ljust(state_width))
            cells += [shorten(r[3], name_width).ljust(a_width), shorten(r[4], name_width)]
            lines.append("  ".join(cells).rstrip())
            if r[5]:
                lines.extend(
                    textwrap.wrap(
                        r[5],
                        WIDTH,
                        initial_indent=_INDENT,
                        subsequent_indent=_INDENT,
                        break_on_hyphens=False,
                    )
                )
    if has_baseline:
        for r in result.baseline.resolved(result.findings):
            text = f"resolved {r.id}  {r.status}  {short(r.a)} and {short(r.b)}"
            lines.extend(textwrap.wrap(text, WIDTH, subsequent_indent=_INDENT))
    if result.settings.config_path:
        lines.extend(
            textwrap.wrap(
                f"configuration: {printable(result.settings.config_path)}",
                WIDTH,
                subsequent_indent="  ",
                break_on_hyphens=False,
            )
        )
    lines.append(summary_line(result))
    return "\n".join(lines) + "\n"
