"""One frozen ``Settings`` for a run: every option, validated once, carried through the stages.

The command line and the Python API both build it with ``Settings.from_options``, which merges the
configuration file in (an option given explicitly wins over the file), checks every number
(finite, in range), and resolves the statuses that fail the run.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from .config import (
    NUMBER_RANGES,
    Approval,
    ClashTest,
    Config,
    Groups,
    checked_number,
    checked_scheduler,
    find_config,
    load_config,
    parse_fail_on,
)
from .errors import ConfigError
from .motion import Motion, motion_from_options
from .results import FINDING_STATUSES, Verdict

#: CoACD concavity threshold (CoACD's own default is 0.05); see decompose.DEFAULT_OPTIONS.
DEFAULT_THRESHOLD = 0.1
SCHEDULER_VARIABLE = "MESHCHECK_SCHEDULER"  # the environment's default for --scheduler


def default_cache_dir() -> str:
    """The user's cache directory for meshcheck (platform convention)."""
    import platformdirs

    return platformdirs.user_cache_dir("meshcheck")


@dataclass(frozen=True)
class Settings:
    """Everything a check runs with. Build it with ``from_options``; the fields are validated.

    Attributes
    ----------
    clearance : float or None
        Report pairs whose true distance is below this, model units.
    tolerance : float or None
        Overlaps and gaps below this count as touching, model units; None: each pair's own
        (``tolerances.pair_tolerances``).
    threshold : float
        CoACD concavity threshold of the convex pieces.
    fail_on : tuple of Verdict
        Statuses of unapproved findings that fail the run.
    approvals : tuple of Approval
        Approved findings (by part-name patterns or stable ID), in the order they were given.
    groups : Groups or None
        Check only pairs across the two groups.
    split : bool
        Each disconnected shell of a mesh is a part.
    units : str or None
        Unit of files that declare none, and of the report; None: see ``meshcheck.units``.
    file_units : tuple of units.UnitRule
        Units the user gave input files, whatever they declare: the configuration's rules, then
        the command line's (the last rule naming a file wins).
    cache_dir : str or None
        Cache directory; None neither reads nor writes a cache.
    jobs : int or None
        Worker processes; None: all cores.
    scheduler : str or None
        Address of a Dask scheduler: decomposition and pair verification run on its cluster.
    config_path : str or None
        The configuration file the settings came from, if any.
    step_deflection : float or None
        Tessellation tolerance of STEP files, in ``units`` (default mm); None: the reader's default.
    max_triangles : int or None
        Triangles allowed in the whole run (``load.Limits.max_triangles``); None: the default.
    fail_on_new : bool
        Only findings that are new against the baseline report fail the run (``--fail-on new``);
        without a baseline every finding is new.
    motion : Motion
        The pose of URDF robots, their package paths, adjacent-link approval, the sweep.
    quiet : bool
        The text and Markdown reports list only the findings that fail the run.
    hide_touching : bool
        The text and Markdown reports leave touching findings out of their tables.
    tests : tuple of ClashTest
        The clash tests of the run, names unique, each with its clearance, tolerance and
        resolved ``fail_on`` statuses (``resolve_fail_on``); empty: the run is one test of every
        part against every part (or the ``groups``) with the fields above. With tests,
        ``groups`` is refused (each test has its sides) and ``clearance``, ``tolerance`` and
        ``fail_on`` are only the defaults ``from_options`` gave the tests.
    """

    clearance: float | None = None
    tolerance: float | None = None
    threshold: float = DEFAULT_THRESHOLD
    fail_on: tuple[Verdict, ...] = (Verdict.INTERFERENCE,)
    approvals: tuple[Approval, ...] = ()
    groups: Groups | None = None
    split: bool = False
    units: str | None = None
    file_units: tuple = ()
    cache_dir: str | None = None
    jobs: int | None = None
    scheduler: str | None = None
    config_path: str | None = None
    fail_on_new: bool = False
    max_triangles: int | None = None
    step_deflection: float | None = None
    motion: Motion = dataclasses.field(default_factory=Motion)
    quiet: bool = False
    hide_touching: bool = False
    tests: tuple[ClashTest, ...] = ()

    def __post_init__(self):
        for name in NUMBER_RANGES:
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, checked_number(name, value, *NUMBER_RANGES[name]))
        for name in ("jobs", "max_triangles"):
            value = getattr(self, name)
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, int) or value < 1
            ):
                raise ConfigError(
                    None, f"{name} must be a whole number of at least 1, not {value!r}"
                )
        if self.units is not None:
            from .units import unit_name

            try:
                object.__setattr__(self, "units", unit_name(self.units))
            except ValueError as exc:
                raise ConfigError(None, str(exc)) from None
        if self.scheduler is not None:
            object.__setattr__(self, "scheduler", checked_scheduler(self.scheduler))
        object.__setattr__(self, "fail_on", tuple(Verdict(s) for s in self.fail_on))
        object.__setattr__(self, "approvals", tuple(self.approvals))
        object.__setattr__(self, "file_units", checked_file_units(self.file_units))
        object.__setattr__(self, "tests", checked_tests(self.tests, groups=self.groups))

    @classmethod
    def from_options(
        cls,
        *,
        config: Config | str | os.PathLike | None = None,
        clearance: float | None = None,
        tolerance: float | None = None,
        threshold: float | None = None,
        fail_on: Iterable[str] | None = None,
        approvals: Sequence[Approval] = (),
        groups: Groups | None = None,
        split: bool = False,
        units: str | None = None,
        file_units=(),
        cache_dir: str | os.PathLike | None = None,
        use_cache: bool = True,
        jobs: int | None = None,
        max_triangles: int | None = None,
        step_deflection: float | None = None,
        scheduler: str | None = None,
        motion: dict | None = None,
        quiet: bool | None = None,
        hide_touching: bool | None = None,
        tests: Sequence[ClashTest | str] | None = None,
    ) -> Settings:
        """Merge options (None: not given) with a configuration file, and validate.

        Parameters
        ----------
        config : Config or path, optional
            Settings from a configuration file; an option given here wins over it. Its approvals
            come after ``approvals``. Pass ``"auto"`` to search from the working directory as the
            command line does (``config.find_config``).
        fail_on : iterable of str, optional
            Status words (``interference``, ``touching``, ``clearance``, ``none``; comma lists
            allowed). Interference always fails unless ``none`` is given; the words add to the
            default, which is interference plus clearance when a clearance is set. ``new`` keeps
            those statuses but fails only findings new against a baseline (``fail_on_new``).
        cache_dir : path, optional
            Cache directory; default the user's cache directory. ``use_cache=False`` disables it.
        scheduler : str, optional
            Dask scheduler address; default ``MESHCHECK_SCHEDULER``, then the file's
            ``scheduler``. An empty string means none (run locally).
        motion : dict, optional
            Keyword options of ``motion.motion_from_options`` (``pose``, ``package_paths``,
            ``adjacent``, ``sweep``, ``resolution``), merged with the file's.
        file_units : mapping or sequence, optional
            Input files' units (``checked_file_units``), after the file's ``[units]``.
        tests : sequence of ClashTest or str, optional
            Clash tests (``--test NAME:A:B[:KEY=VALUE]...`` strings are parsed by
            ``config.parse_test``); they replace the file's ``[[test]]`` tables. Each test's
            unset clearance, tolerance and fail_on words are the run's.

        Raises
        ------
        ConfigError
            An invalid value or configuration file.
        """
        file = _config(config)
        pick = _pick
        clearance = pick(clearance, file.clearance)
        words, fail_on_new = _fail_on_words(fail_on, file)
        cache = _cache_dir(cache_dir, use_cache=use_cache)
        tolerance = pick(tolerance, file.tolerance)
        return cls(
            clearance=clearance,
            tolerance=tolerance,
            threshold=pick(threshold, pick(file.threshold, DEFAULT_THRESHOLD)),
            fail_on=resolve_fail_on(words, clearance=clearance),
            approvals=(*approvals, *file.approvals),
            groups=pick(groups, file.groups),
            split=split,
            units=pick(units, file.units),
            file_units=(*file.file_units, *checked_file_units(file_units)),
            cache_dir=cache,
            jobs=jobs,
            scheduler=pick(scheduler, os.environ.get(SCHEDULER_VARIABLE) or file.scheduler) or None,
            config_path=file.path,
            fail_on_new=fail_on_new,
            max_triangles=max_triangles,
            step_deflection=step_deflection,
            motion=motion_from_options(file.motion, **(motion or {})),
            quiet=bool(pick(quiet, file.quiet)),
            hide_touching=bool(pick(hide_touching, file.hide_touching)),
            tests=_resolved_tests(
                file.tests if tests is None else tests,
                clearance=clearance,
                tolerance=tolerance,
                words=words,
            ),
        )

    def replace(self, **changes) -> Settings:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def resolve_fail_on(words: Sequence[str] | None, *, clearance: float | None) -> tuple[Verdict, ...]:
    """Statuses that fail the run: duplicate and interference, plus clearance when a clearance
    is set, plus ``words``; an empty ``words`` (``none``) means nothing fails.

    Examples
    --------
    >>> [str(s) for s in resolve_fail_on(None, clearance=0.5)]
    ['duplicate', 'interference', 'clearance']
    >>> [str(s) for s in resolve_fail_on(("touching",), clearance=None)]
    ['duplicate', 'interference', 'touching']
    >>> resolve_fail_on((), clearance=0.5)
    ()
    """
    if words is not None and len(words) == 0:
        return ()
    chosen = {Verdict.DUPLICATE, Verdict.INTERFERENCE, *(Verdict(w) for w in words or ())}
    if clearance is not None:
        chosen.add(Verdict.CLEARANCE)
    return tuple(s for s in FINDING_STATUSES if s in chosen)


__all__ = [
    "DEFAULT_THRESHOLD",
    "Settings",
    "default_cache_dir",
    "resolve_fail_on",
]


def _pick(value, from_file):
    """An option's value, or the configuration file's when the option is None."""
    return from_file if value is None else value


def _fail_on_words(fail_on, file: Config) -> tuple[tuple[str, ...] | None, bool]:
    """The ``--fail-on`` words (else the file's) without ``new``, and whether ``new`` was one."""
    words = parse_fail_on(fail_on) if fail_on is not None else None
    if words is None and file.fail_on is not None:
        words = parse_fail_on(file.fail_on, path=file.path)
    fail_on_new = bool(words) and "new" in words
    if fail_on_new:  # "new" narrows which findings fail; the statuses resolve as without it
        words = tuple(w for w in words if w != "new") or None
    return words, fail_on_new


def _resolved_tests(tests, *, clearance, tolerance, words) -> tuple[ClashTest, ...]:
    """``tests`` (``ClashTest``s, or ``--test`` strings) with the run's clearance, tolerance
    and fail_on words where a test sets none, its failing statuses resolved."""
    from .config import parse_test

    out = []
    for test in tests:
        if isinstance(test, str):
            test = parse_test(test)
        test_clearance = _pick(test.clearance, clearance)
        own = _test_words(test)
        out.append(
            dataclasses.replace(
                test,
                clearance=test_clearance,
                tolerance=_pick(test.tolerance, tolerance),
                fail_on=resolve_fail_on(_pick(own, words), clearance=test_clearance),
            )
        )
    return tuple(out)


def _test_words(test: ClashTest) -> tuple[str, ...] | None:
    """A test's fail_on words, checked (``parse_fail_on``; ``()`` is ``none``), or None."""
    if test.fail_on is None or test.fail_on == ():
        return test.fail_on
    words = parse_fail_on([test.fail_on] if isinstance(test.fail_on, str) else test.fail_on)
    if words and "new" in words:
        raise ConfigError(
            None, f"test {test.name!r}: fail_on 'new' is for the whole run (--fail-on new)"
        )
    return words


def checked_tests(tests, *, groups: Groups | None) -> tuple[ClashTest, ...]:
    """``tests`` as a tuple of ``ClashTest`` with numbers checked and ``fail_on`` as statuses
    (resolved with ``resolve_fail_on`` where None).

    Raises
    ------
    ConfigError
        A test that is not a ``ClashTest``, two tests of one name, a number out of range, or
        tests beside ``groups``.
    """
    from .config import checked_test_name

    out: list[ClashTest] = []
    for test in tests or ():
        if not isinstance(test, ClashTest):
            raise ConfigError(None, f"a clash test must be a ClashTest, not {test!r}")
        checked_test_name(test.name)
        if any(t.name == test.name for t in out):
            raise ConfigError(
                None, f"two clash tests are named {test.name!r}: each test needs its own name"
            )
        numbers = {}
        for key in ("clearance", "tolerance"):
            value = getattr(test, key)
            if value is not None:
                label = f"test {test.name!r}: {key}"
                numbers[key] = checked_number(label, value, *NUMBER_RANGES[key])
        fail_on = test.fail_on
        if fail_on is None:
            fail_on = resolve_fail_on(None, clearance=numbers.get("clearance"))
        try:
            fail_on = tuple(Verdict(s) for s in fail_on)
        except ValueError:
            raise ConfigError(
                None, f"test {test.name!r}: fail_on must be statuses, not {fail_on!r}"
            ) from None
        out.append(dataclasses.replace(test, fail_on=fail_on, **numbers))
    if out and groups is not None:
        raise ConfigError(
            None,
            "groups and clash tests cannot be combined: give each [[test]] its sides a and b",
        )
    return tuple(out)


def checked_file_units(rules) -> tuple:
    """``file_units`` as a tuple of ``units.UnitRule``: from a mapping (pattern -> unit, e.g.
    ``{"engine.glb": "mm"}``), or a sequence of rules, ``FILE=UNIT`` strings or (pattern, unit)
    pairs; paths and globs relative to the working directory (the last rule naming a file wins).

    Raises
    ------
    ConfigError
        A rule that is none of those, or an unknown unit.
    """
    from .units import UnitRule, unit_name, unit_rule

    if isinstance(rules, dict):
        rules = list(rules.items())
    out = []
    for rule in rules or ():
        try:
            if isinstance(rule, UnitRule):
                out.append(dataclasses.replace(rule, unit=unit_name(rule.unit)))
            elif isinstance(rule, str):
                out.append(unit_rule(rule))
            else:
                pattern, unit = rule
                out.append(unit_rule(f"{pattern}={unit}"))
        except (TypeError, ValueError) as exc:
            raise ConfigError(None, f"--units: {exc}") from None
    return tuple(out)


def _config(config) -> Config:
    """The configuration ``from_options`` merges: found (``"auto"``), read, given, or empty."""
    if isinstance(config, str) and config == "auto":
        config = find_config()
    if config is not None and not isinstance(config, Config):
        config = load_config(config)
    return config or Config()


def _cache_dir(cache_dir, *, use_cache: bool) -> str | None:
    """The cache directory a run uses: none without the cache, else the given or the default."""
    if not use_cache:
        return None
    return os.fspath(cache_dir) if cache_dir is not None else default_cache_dir()
