"""Findings against a previous JSON report: each one ``new`` or ``active``, and the ``resolved``.

A finding is *active* when the baseline report holds a finding with the same stable ID
(``Finding.id``: the sorted part names, the two parts' geometry and placements, and the clash
test's name) and the same status; any other finding is *new*, so a pair that was touching and
now interferes is new. A baseline finding whose ID no current finding has is *resolved*. The
baseline file comes from outside (a CI artifact): it is read with a size limit and checked field
by field, and every problem is one ``ConfigError`` naming the file.

Examples
--------
>>> from meshcheck.results import Finding, PairVerdict, Verdict
>>> old = Baseline("old.json", {"0123456789ab": ("a.stl", "b.stl", Verdict.TOUCHING)})
>>> old.state(Finding("a.stl", "b.stl", PairVerdict(Verdict.TOUCHING, 0.0), id="0123456789ab"))
'active'
>>> old.state(Finding("a.stl", "b.stl", PairVerdict(Verdict.INTERFERENCE, 0.0), id="0123456789ab"))
'new'
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from .errors import ConfigError
from .results import FINDING_STATUSES, Finding, Verdict

#: A baseline larger than this is refused before reading: a report of 100,000 findings is ~40 MB.
MAX_BASELINE_BYTES = 256 * 1024 * 1024

_ID = re.compile(r"[0-9a-f]{12}")


@dataclass(frozen=True)
class Resolved:
    """A finding of the baseline that the current run no longer has."""

    id: str
    a: str
    b: str
    status: Verdict
    test: str = ""

    def to_dict(self) -> dict:
        doc = {"id": self.id, "a": self.a, "b": self.b, "status": str(self.status)}
        return {**doc, "test": self.test} if self.test else doc


@dataclass(frozen=True)
class Baseline:
    """The findings of a previous report, by stable ID.

    Attributes
    ----------
    path : str
        The report file, for messages.
    findings : mapping of str to (str, str, Verdict)
        Stable ID -> part names and status.
    tests : mapping of str to str
        Stable ID -> the clash test of the finding, for the findings that had one.
    """

    path: str
    findings: Mapping[str, tuple[str, str, Verdict]] = field(default_factory=dict)
    tests: Mapping[str, str] = field(default_factory=dict)

    def state(self, finding: Finding) -> str:
        """``"active"`` when the baseline holds this ID with this status, else ``"new"``."""
        held = self.findings.get(finding.id)
        return "active" if held is not None and held[2] == finding.status else "new"

    def resolved(self, findings: Iterable[Finding]) -> list[Resolved]:
        """Baseline findings whose ID is not among ``findings``, sorted by part names."""
        current = {f.id for f in findings}
        gone = [
            Resolved(i, a, b, status, self.tests.get(i, ""))
            for i, (a, b, status) in self.findings.items()
            if i not in current
        ]
        return sorted(gone, key=lambda r: (r.a, r.b, r.id))

    def for_test(self, name: str) -> Baseline:
        """The baseline's findings of the clash test ``name`` alone."""
        kept = {i: v for i, v in self.findings.items() if self.tests.get(i, "") == name}
        return Baseline(self.path, kept, {i: name for i in kept} if name else {})

    def other_than(self, names: Iterable[str]) -> Baseline:
        """The baseline's findings of none of the clash tests ``names`` (those of a run
        without clash tests included)."""
        names = set(names)
        kept = {i: v for i, v in self.findings.items() if self.tests.get(i, "") not in names}
        return Baseline(self.path, kept, {i: t for i, t in self.tests.items() if i in kept})


def load_baseline(path: str | os.PathLike) -> Baseline:
    """Read a JSON report written by ``meshcheck --format json`` as a baseline.

    Raises
    ------
    ConfigError
        The file cannot be read, is too large, is not JSON, or is not a meshcheck report.
    """
    name = os.fspath(path)
    try:
        if not stat.S_ISREG(os.stat(name).st_mode):  # before opening: a FIFO would block
            raise ConfigError(name, "the baseline must be a regular file (a JSON report)")
        with open(name, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > MAX_BASELINE_BYTES:
                raise ConfigError(
                    name,
                    f"the baseline is {size} bytes, more than the limit of {MAX_BASELINE_BYTES}",
                )
            data = fh.read(MAX_BASELINE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(name, f"cannot read the baseline ({exc.strerror or exc})") from None
    try:
        doc = json.loads(data)
    except RecursionError:
        raise ConfigError(name, "the baseline is nested too deep to be a report") from None
    except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError
        reason = exc.msg if isinstance(exc, json.JSONDecodeError) else "not UTF-8"
        raise ConfigError(name, f"the baseline is not JSON ({reason})") from None
    return Baseline(name, *_findings(name, doc))


def _findings(name: str, doc) -> tuple[dict[str, tuple[str, str, Verdict]], dict[str, str]]:
    def fail(reason: str):
        raise ConfigError(name, f"the baseline is not a meshcheck JSON report: {reason}")

    if not isinstance(doc, dict) or not isinstance(doc.get("results"), list):
        fail("no 'results' list")
    statuses = {str(s) for s in FINDING_STATUSES}
    found: dict[str, tuple[str, str, Verdict]] = {}
    tests: dict[str, str] = {}
    for k, entry in enumerate(doc["results"]):
        if not isinstance(entry, dict):
            fail(f"results[{k}] is not an object")
        values = [entry.get(key) for key in ("id", "a", "b", "status")]
        if not all(isinstance(v, str) for v in values):
            fail(f"results[{k}] lacks a string id, a, b or status")
        finding_id, a, b, status = values
        if not _ID.fullmatch(finding_id):
            fail(f"results[{k}] has an id that is not 12 hex digits")
        if status not in statuses:
            fail(f"results[{k}] has an unknown status")
        found[finding_id] = (a, b, Verdict(status))
        test = entry.get("test")
        if test is not None:
            if not isinstance(test, str) or not test:
                fail(f"results[{k}] has a test that is not a non-empty string")
            tests[finding_id] = test
    return found, tests


__all__ = ["MAX_BASELINE_BYTES", "Baseline", "Resolved", "load_baseline"]
