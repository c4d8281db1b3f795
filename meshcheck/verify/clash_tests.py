"""Pair verdicts -> each clash test's findings, from one verification for all the tests.

A run of clash tests (``Settings.tests``) loads, prunes and verifies once:

- the broad phase reaches as far as the farthest-reaching test (the largest tolerance and the
  largest clearance of any test), then keeps only the pairs some test holds (``held_by_any``);
  the convex filters reach, for each pair, the largest tolerance (``widest_tolerances``) plus
  the largest clearance (``pair_clearances``) of the tests that hold it;
- ``verify_plans`` verifies each pair once per distinct tolerance among the tests that hold it,
  with the largest clearance of those tests; tests that agree on the tolerance (the usual case:
  none sets its own) share one verification, each pair verified once whatever the number of
  tests, and a pair no test with a clearance holds is verified without one;
- ``judged`` gives every test the verdicts of its pairs: interference and touching as verified
  (both depend on the tolerance alone, which the test shares with its verification), a clearance
  verdict only when its exact distance is below the test's own clearance (the distance of a pair
  verified with a larger clearance is exact: the closest triangles are within both reaches).

Why once per tolerance, not once: touching and interference are decided at a tolerance (a shared
solid proven no thicker than it touches), and a verdict at one tolerance does not say what the
solid's thickness is against another; a pair two tolerances judge is verified at each, never
re-judged from the other's verdict.

Without clash tests each function gives what the run of one test has always done: one plan of
every pair at the run's tolerance and clearance, findings unchanged.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..config import ClashTest
from ..results import Finding, Verdict, finding_id_in
from ..settings import Settings
from ..tolerances import largest_pair_tolerance, pair_tolerances
from .patterns import with_patterns


@dataclasses.dataclass(frozen=True)
class VerifyPlan:
    """One verification of a run: which pairs, at which tolerance, for which tests.

    Attributes
    ----------
    mask : (k,) bool
        The pairs (of those handed to ``verify_plans``) verified by this plan.
    tolerance : (m,) float64
        The touching tolerance of each pair of the plan (``m = mask.sum()``), model units.
    settings : Settings
        The run's settings with this plan's ``tolerance`` (the tests', None: each pair's own)
        and ``clearance`` (the largest of its tests'): what ``verify_classes`` and
        ``decide_on_brep`` are given.
    tests : tuple of str
        The clash tests of the plan's tolerance, which judge the verdicts of the pairs they hold;
        empty without clash tests.
    """

    mask: np.ndarray
    tolerance: np.ndarray
    settings: Settings
    tests: tuple[str, ...] = ()


def tolerances_of_tests(settings: Settings) -> tuple[float | None, ...]:
    """The distinct touching tolerances of the run's tests in order (None: each pair's own);
    the run's tolerance without tests."""
    if not settings.tests:
        return (settings.tolerance,)
    return tuple(dict.fromkeys(t.tolerance for t in settings.tests))


def largest_clearance(settings: Settings) -> float | None:
    """The largest clearance of the run's tests (None when none has one); the run's without
    tests."""
    if not settings.tests:
        return settings.clearance
    return _largest([t.clearance for t in settings.tests])


def largest_tolerance(
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    settings: Settings,
    *,
    deflection: np.ndarray | None = None,
) -> float:
    """An upper bound of every test's tolerance over every pair (``largest_pair_tolerance``):
    the broad phase's margin, with ``largest_clearance``."""
    return max(
        largest_pair_tolerance(diagonal, magnitude, tolerance=t, deflection=deflection)
        for t in tolerances_of_tests(settings)
    )


def widest_tolerances(
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    pairs: np.ndarray,
    settings: Settings,
    *,
    deflection: np.ndarray | None = None,
) -> np.ndarray:
    """The largest tolerance any test gives each of ``pairs``, ``(k,)`` float64: what the
    convex filters prune with, so no pair within any test's reach is pruned. Without tests,
    each pair's tolerance (``tolerances.pair_tolerances``)."""
    return np.max(
        [
            pair_tolerances(diagonal, magnitude, pairs, tolerance=t, deflection=deflection)
            for t in tolerances_of_tests(settings)
        ],
        axis=0,
    ).reshape(-1)


def pair_clearances(
    settings: Settings, names: Sequence[tuple[str, ...]], pairs: np.ndarray
) -> np.ndarray:
    """The largest clearance of the tests that hold each of ``pairs``, ``(k,)`` float64, 0
    where none has one: what the convex filters reach beyond the tolerance. Without tests, the
    run's clearance for every pair."""
    if not settings.tests:
        return np.full(len(pairs), settings.clearance or 0.0)
    return np.nan_to_num(_clearances(settings.tests, names, pairs), nan=0.0)


def _clearances(
    tests: Sequence[ClashTest], names: Sequence[tuple[str, ...]], pairs: np.ndarray
) -> np.ndarray:
    """The largest clearance of ``tests`` holding each pair, ``(k,)`` float64, NaN where none
    with a clearance does."""
    out = np.full(len(pairs), np.nan)
    for test in tests:
        if test.clearance is not None:
            held = test.holds(names, pairs)
            out[held] = np.fmax(out[held], test.clearance)
    return out


def held_by_any(
    tests: Sequence[ClashTest], names: Sequence[tuple[str, ...]], pairs: np.ndarray
) -> np.ndarray:
    """Which of ``pairs`` ((k, 2) indices into ``names``) some test holds, ``(k,)`` bool."""
    held = np.zeros(len(pairs), dtype=bool)
    for test in tests:
        held |= test.holds(names, pairs)
    return held


def verify_plans(
    settings: Settings,
    names: Sequence[tuple[str, ...]],
    pairs: np.ndarray,
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    *,
    deflection: np.ndarray | None = None,
) -> list[VerifyPlan]:
    """The verifications of ``pairs`` ((k, 2) part indices): for each distinct tolerance among
    the tests, the pairs its tests hold, split by the largest clearance of those tests that hold
    each pair (none first, then by value), so every pair is verified once per tolerance.

    Without tests, one plan of every pair at the run's tolerance and clearance.

    Parameters
    ----------
    settings : Settings
    names : sequence of tuple of str
        Each part's names (full, relative), which test sides are matched against.
    pairs : (k, 2) int64
    diagonal, magnitude : (n,) float64
        ``tolerances.part_sizes`` of the parts.
    deflection : (n,) float64, optional
        Each part's tessellation deflection.
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    if not settings.tests:
        tolerance = pair_tolerances(
            diagonal, magnitude, pairs, tolerance=settings.tolerance, deflection=deflection
        )
        return [VerifyPlan(np.ones(len(pairs), dtype=bool), tolerance, settings)]
    plans = []
    for key in tolerances_of_tests(settings):
        tests = [t for t in settings.tests if t.tolerance == key]
        held = held_by_any(tests, names, pairs)
        clearance = _clearances(tests, names, pairs)
        values = np.unique(clearance[held & ~np.isnan(clearance)])
        for value in [None, *(float(v) for v in values)]:
            mask = held & (np.isnan(clearance) if value is None else clearance == value)
            if not mask.any():
                continue
            tolerance = pair_tolerances(
                diagonal, magnitude, pairs[mask], tolerance=key, deflection=deflection
            )
            plan_settings = settings.replace(tolerance=key, clearance=value)
            plans.append(VerifyPlan(mask, tolerance, plan_settings, tuple(t.name for t in tests)))
    return plans


def judged(
    bodies: Sequence,
    settings: Settings,
    plans: Sequence[VerifyPlan],
    verified: Sequence[Sequence[Finding]],
    duplicates: Sequence[Finding],
    *,
    geometry: dict,
    names: Sequence[tuple[str, ...]],
) -> list[Finding]:
    """The run's findings: each test's, judged from its plan's verdicts, with its name and ID.

    Parameters
    ----------
    bodies : sequence of load.Body
    settings : Settings
    plans : sequence of VerifyPlan
        ``verify_plans``.
    verified : sequence of list of Finding
        The findings of each plan (``decide_on_brep`` and ``verify_classes``), in plan order.
    duplicates : sequence of Finding
        The duplicate sets' findings (``verify.duplicates``).
    geometry : dict
        ``load.local_geometries(bodies)``, for the clash patterns.
    names : sequence of tuple of str
        Each part's names (full, relative).

    Returns
    -------
    list of Finding
        Without tests: the duplicates and the one plan's findings, sorted by names, patterns
        set. With tests: test by test in the run's order, the findings of the pairs (and the
        duplicate sets) the test holds that are findings at its clearance, sorted by names,
        patterns set at its tolerance, each with ``test`` and its ID (``finding_id_in``).
    """
    if not settings.tests:
        (found,) = verified
        findings = sorted([*duplicates, *found], key=lambda f: (f.a, f.b))
        return with_patterns(bodies, findings, geometry, tolerance=settings.tolerance)
    index = {b.name: k for k, b in enumerate(bodies)}
    out: list[Finding] = []
    for test in settings.tests:
        own = [
            f
            for plan, found in zip(plans, verified, strict=True)
            if test.name in plan.tests
            for f in _held(test, found, index, names)
            if f.status != Verdict.CLEARANCE
            or _is_within(f, test.clearance, plan.settings.clearance)
        ]
        own += [f for f in duplicates if _holds_a_copy_pair(test, f, index, names)]
        own = sorted(own, key=lambda f: (f.a, f.b))
        own = with_patterns(bodies, own, geometry, tolerance=test.tolerance)
        out += [
            dataclasses.replace(f, test=test.name, id=finding_id_in(test.name, f.id)) for f in own
        ]
    return out


def _held(test: ClashTest, findings: Sequence[Finding], index: dict, names) -> list[Finding]:
    """The findings of ``findings`` whose pair ``test`` holds."""
    if not findings:
        return []
    pairs = np.array([[index[f.a], index[f.b]] for f in findings], dtype=np.int64)
    mask = test.holds(names, pairs)
    return [f for f, is_held in zip(findings, mask, strict=True) if is_held]


def _is_within(finding: Finding, clearance: float | None, verified_with: float | None) -> bool:
    """True when a clearance verdict found with clearance ``verified_with`` is a finding at
    ``clearance``: always at the same clearance (the verification decided it), else when its
    exact distance is below ``clearance``; never without one."""
    if clearance is None:
        return False
    return clearance == verified_with or finding.distance < clearance


def _holds_a_copy_pair(test: ClashTest, finding: Finding, index: dict, names) -> bool:
    """True when ``test`` holds a pair of the copies of a duplicate finding: one copy on side
    a, another on side b."""
    in_a, in_b = test.sides.members([names[index[m]] for m in finding.members])
    count_a, count_b = int(in_a.sum()), int(in_b.sum())
    if count_a == 0 or count_b == 0:
        return False
    return count_a > 1 or count_b > 1 or not np.array_equal(in_a, in_b)


def _largest(values: Sequence[float | None]) -> float | None:
    known = [v for v in values if v is not None]
    return max(known) if known else None


__all__ = [
    "VerifyPlan",
    "held_by_any",
    "judged",
    "largest_clearance",
    "largest_tolerance",
    "pair_clearances",
    "tolerances_of_tests",
    "verify_plans",
    "widest_tolerances",
]
