"""What a whole run found and what it means: ``CheckResult``, whether it fails, its exit status.

The one place the run's pass/fail is decided (black's ``report.py``): a finding fails the run when
it is unapproved, has a status the settings fail on (its clash test's, in a run of clash tests)
and (with ``--fail-on new``) is new against the baseline; a ``[[joint]]`` mechanism that collides
within its ranges fails it too, and so does an audited SRDF entry that disables a
collision the sweep shows happening. A run of clash tests fails when any of its tests does, and
``CheckResult.for_test`` is one test's own result. The command line ends with ``exit_status``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from .errors import ExitStatus
from .results import (
    AuditedPair,
    Finding,
    PairSweep,
    Part,
    RobotPose,
    RobotSweep,
    SrdfAudit,
    SweepStatus,
    Verdict,
)

if TYPE_CHECKING:
    from .baseline import Baseline
    from .config import ClashTest
    from .settings import Settings


@dataclass(frozen=True)
class CheckResult:
    """Everything one check found, and the settings it ran with.

    Attributes
    ----------
    findings : list of Finding
        Sorted by part names.
    parts : list of Part
    settings : Settings
        What the check ran with; its ``fail_on`` decides ``passed``.
    checked_pairs : list of (str, str)
        The part pairs the broad phase left to check (sorted names), clear ones included.
    warnings : list of str
        The messages of the run's MeshcheckWarnings.
    units : str
        The unit every length of the result is in (``meshcheck.units``).
    bodies : tuple of load.Body
        The parts' geometry, for outputs that draw them (``--export``); not compared.
    baseline : baseline.Baseline or None
        The previous report the findings were compared with (``baseline.compare``), if any.
    sweeps : tuple of RobotSweep
        With ``--sweep``: each robot's link pairs classified over the joint ranges.
    poses : tuple of RobotPose
        The joint values each robot (and ``[[joint]]`` mechanism) of the run was checked at.
    audit : SrdfAudit or None
        With ``--audit-srdf``: the SRDF's disabled pairs, audited over the joint ranges.
    test_pairs : dict of str to list of (str, str)
        In a run of clash tests: each test's name -> the checked pairs that are its.
    test : ClashTest or None
        The clash test this result is the part of (``for_test``); None for a whole run.
    """

    findings: list[Finding]
    parts: list[Part]
    settings: Settings
    checked_pairs: list[tuple[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    bodies: tuple = field(default=(), repr=False, compare=False)
    units: str = "mm"
    baseline: Baseline | None = None
    sweeps: tuple[RobotSweep, ...] = ()
    poses: tuple[RobotPose, ...] = ()
    audit: SrdfAudit | None = None
    test_pairs: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    test: ClashTest | None = None

    @property
    def tolerance(self) -> float | None:
        """The touching tolerance the user set, or None when each pair had its own."""
        return self.settings.tolerance

    @property
    def clearance(self) -> float | None:
        return self.settings.clearance

    @property
    def fail_on(self) -> tuple[Verdict, ...]:
        return self.settings.fail_on

    def count(self, status: str) -> int:
        """Number of unapproved findings with this status."""
        return sum(1 for f in self.findings if f.status == status and not f.is_approved)

    @property
    def tests(self) -> tuple[ClashTest, ...]:
        """The run's clash tests (``Settings.tests``); empty for a run of one test."""
        return self.settings.tests

    def fail_on_of(self, finding: Finding) -> tuple[Verdict, ...]:
        """The statuses that fail ``finding``: its clash test's, else the settings'."""
        if finding.test:
            for test in self.settings.tests:
                if test.name == finding.test:
                    return test.fail_on
        return self.settings.fail_on

    def is_failing(self, finding: Finding) -> bool:
        """True when ``finding`` fails the run: unapproved, with a status its test fails on
        (``fail_on_of``), and new against the baseline when the settings ask for
        ``fail_on_new``."""
        if finding.is_approved or finding.status not in self.fail_on_of(finding):
            return False
        # Only a finding the baseline holds is spared: without a baseline, every finding is new.
        return not self.settings.fail_on_new or self.baseline_state(finding) != "active"

    def baseline_state(self, finding: Finding) -> str | None:
        """``"new"`` or ``"active"`` against the baseline; None when there is no baseline."""
        return None if self.baseline is None else self.baseline.state(finding)

    @property
    def failing_sweeps(self) -> list:
        """(robot, pair) of each swept pair that fails the run (``is_failing_sweep``)."""
        return [(r, p) for r in self.sweeps for p in r.pairs if self.is_failing_sweep(r, p)]

    def is_failing_sweep(self, robot: RobotSweep, pair: PairSweep) -> bool:
        """True when a swept ``pair`` of ``robot`` fails the run: a pair of a mechanism made by
        ``[[joint]]`` tables that collides somewhere in the declared ranges (a door hitting
        its stop), unapproved, with the verdict at its witness in ``fail_on``. A URDF robot's
        pairs never fail it: a robot collides with itself at some poses by design, and its
        sweep's output is the allowed-collision matrix (``--srdf``)."""
        return (
            not robot.is_urdf
            and pair.status in (SweepStatus.SOMETIMES, SweepStatus.ALWAYS)
            and pair.approval_reason is None
            and pair.verdict in self.settings.fail_on
        )

    @property
    def failing_audits(self) -> list[AuditedPair]:
        """The audited SRDF entries that fail the run (``is_failing_audit``), in file order."""
        if self.audit is None:
            return []
        return [p for p in self.audit.pairs if self.is_failing_audit(p)]

    def is_failing_audit(self, pair: AuditedPair) -> bool:
        """True when an audited SRDF entry fails the run: it disables two links the sweep shows
        colliding at a witness pose (interfering or touching: MoveIt's collision checking
        reports contact), unless nothing fails the run (``--fail-on none``)."""
        return pair.is_wrong and bool(self.settings.fail_on)

    @property
    def failed(self) -> bool:
        """True when an unapproved finding has a status that fails the run, a mechanism's
        parts collide within its joint ranges (``failing_sweeps``), or an audited SRDF entry
        disables a collision (``failing_audits``)."""
        return (
            any(self.is_failing(f) for f in self.findings)
            or bool(self.failing_sweeps)
            or bool(self.failing_audits)
        )

    @property
    def passed(self) -> bool:
        return not self.failed

    def for_test(self, name: str) -> CheckResult:
        """The result of the clash test ``name`` alone, as a run of that one test reads: its
        findings, its pairs, settings with its clearance, tolerance and ``fail_on``, the
        baseline's findings of that test; no sweeps, poses, SRDF audit, warnings or configuration
        (the run's)."""
        test = next((t for t in self.settings.tests if t.name == name), None)
        if test is None:
            raise KeyError(name)
        settings = replace(
            self.settings,
            tests=(),
            clearance=test.clearance,
            tolerance=test.tolerance,
            fail_on=test.fail_on,
            config_path=None,
        )
        return replace(
            self,
            findings=[f for f in self.findings if f.test == name],
            settings=settings,
            checked_pairs=list(self.test_pairs.get(name, [])),
            warnings=[],
            baseline=None if self.baseline is None else self.baseline.for_test(name),
            sweeps=(),
            poses=(),
            audit=None,
            test_pairs={},
            test=test,
        )

    @property
    def failed_tests(self) -> list[str]:
        """Names of the clash tests that fail (``is_failing`` on a finding of theirs), in order."""
        failing = {f.test for f in self.findings if self.is_failing(f)}
        return [t.name for t in self.settings.tests if t.name in failing]


def compare(result: CheckResult, baseline: Baseline) -> CheckResult:
    """``result`` with ``baseline`` attached: ``result.baseline_state(f)`` then says new or
    active, and ``fail_on_new`` settings fail only the new findings."""
    return replace(result, baseline=baseline)


def exit_status(result: CheckResult) -> ExitStatus:
    """``FAILED`` when the run fails (``CheckResult.failed``), else ``OK``."""
    return ExitStatus.FAILED if result.failed else ExitStatus.OK


__all__ = ["CheckResult", "compare", "exit_status"]
