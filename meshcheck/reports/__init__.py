"""Results -> reports: one module per format behind one interface, and the exit status.

Every format module (``text``, ``json``, ``junit``, ``github``, ``sarif``, ``markdown``,
``html``) has the same entry, ``render(result, *, inputs=(), view=None) -> str`` (text ending
in a newline; ``inputs`` are the paths the user gave, which a format may list); ``render``
here picks one by name. Every format shows each finding's stable ID (``Finding.id``), its
baseline state when there is a baseline, and renders part names (which come from files) as
data: ``printable`` for text, escapes for Markdown, XML and JSON. Formats render what the
check computed and compute nothing: the HTML view draws each interference's shared solid
from its verdict (``Finding.solid``).

``gltf`` is the ``--export`` (a file of the assembly with its clashes), not a report format.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from ..outcome import CheckResult
from . import github, html, json, junit, markdown, sarif, text
from .common import (
    View,
    describe,
    printable,
    summary,
    summary_line,
)


class Format(Protocol):
    """What every format module provides."""

    def render(
        self, result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None
    ) -> str: ...


#: Format name -> its module, in the order the command line lists them.
MODULES: dict[str, Format] = {
    "text": text,
    "json": json,
    "junit": junit,
    "github": github,
    "sarif": sarif,
    "markdown": markdown,
    "html": html,
}
FORMATS = tuple(MODULES)


def render(
    result: CheckResult,
    fmt: str = "text",
    *,
    inputs: Sequence[str] = (),
    view: View | None = None,
) -> str:
    """Render ``result`` in ``fmt`` (one of ``FORMATS``), ending with a newline.

    ``inputs`` are the paths the user gave (the HTML report lists them); ``view`` says how much
    the person-facing formats (text, Markdown) show and how wide the text table is (default
    ``View()``: everything, 100 columns). Every format lists findings most severe first
    (``common.ordered``).
    """
    if fmt not in MODULES:
        raise ValueError(f"unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
    return MODULES[fmt].render(result, inputs=inputs, view=view)


__all__ = [
    "FORMATS",
    "MODULES",
    "Format",
    "View",
    "describe",
    "printable",
    "render",
    "summary",
    "summary_line",
]
