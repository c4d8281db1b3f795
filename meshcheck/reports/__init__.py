"""Results -> reports, one module per format behind one interface, and the exit status.

Each format module has ``render(result) -> str`` (text ending in a newline); ``render`` here picks
one by name. Every format shows each finding's stable ID (``Finding.id``), its baseline state when
there is a baseline, and renders part names (which come from files) as data: ``printable`` for
text, escapes for Markdown, XML and JSON.

``html`` (``reports/html.py``) draws the parts too, so it also takes the bodies
(``CheckResult.bodies``), the inputs and the version.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

from ..results import CheckResult
from .common import (
    describe,
    exit_status,
    printable,
    summary,
    summary_line,
)

FORMATS = ("text", "json", "junit", "github", "sarif", "markdown", "html")


def render(result: CheckResult, fmt: str = "text", *, inputs: Sequence[str] = ()) -> str:
    """Render ``result`` in ``fmt`` (one of ``FORMATS``), ending with a newline.

    ``inputs`` are the paths the user gave (the HTML report lists them).
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
    if fmt == "html":
        return _render_html(result, inputs=inputs)
    return importlib.import_module(f"{__name__}.{fmt}").render(result)


def _render_html(result: CheckResult, *, inputs: Sequence[str]) -> str:
    from importlib import metadata

    from .. import DISTRIBUTION
    from .html import render_html

    try:
        version = metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:  # pragma: no cover
        version = "0"
    return render_html(
        result, result.bodies, units=result.units, inputs=tuple(inputs), version=version
    )


__all__ = [
    "FORMATS",
    "describe",
    "exit_status",
    "printable",
    "render",
    "summary",
    "summary_line",
]
