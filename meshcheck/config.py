"""The configuration file, and the rules it holds: approvals, groups and clash tests.

Patterns are shell globs (``fnmatch``, case-sensitive, ``*`` also crosses ``/``). A pattern
matches a part when it matches either the full name (``assembly/frame.stl#pin``) or the name
relative to the argument it came from (``frame.stl#pin`` for ``meshcheck assembly/``; the file's
base name for a file argument).
"""

from __future__ import annotations

import fnmatch
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError
from .results import FINDING_STATUSES

FAIL_ON_CHOICES = tuple(str(s) for s in FINDING_STATUSES)
# Allowed range of each number in options and the configuration file.
NUMBER_RANGES = {
    "tolerance": (0.0, math.inf),
    "clearance": (0.0, math.inf),
    "threshold": (0.01, 1.0),
    "step_deflection": (1e-9, 1e6),
}


def matches(pattern: str, names: str | Sequence[str]) -> bool:
    """True when ``pattern`` matches one of a part's names (full or relative)."""
    if isinstance(names, str):
        names = (names,)
    return any(fnmatch.fnmatchcase(n, pattern) for n in names)


@dataclass(frozen=True)
class Approval:
    """An approved finding, with the reason: by part-name patterns ``a`` and ``b`` (either order),
    or by the finding's stable ``id`` (which lapses when either part's mesh or placement
    changes)."""

    a: str | None
    b: str | None
    reason: str
    id: str | None = None

    @property
    def label(self) -> str:
        return f"id {self.id}" if self.id is not None else f"{self.a!r} / {self.b!r}"

    def matches(
        self, names_a: str | Sequence[str], names_b: str | Sequence[str], finding_id: str = ""
    ) -> bool:
        """True when the pair (each part given by its names) or the finding ID is approved."""
        if self.id is not None:
            return finding_id == self.id
        return (matches(self.a, names_a) and matches(self.b, names_b)) or (
            matches(self.b, names_a) and matches(self.a, names_b)
        )


@dataclass(frozen=True)
class Groups:
    """Check only parts matching one of ``a`` against parts matching one of ``b``."""

    a: tuple[str, ...]
    b: tuple[str, ...]

    def allows(self, name_a: str, name_b: str) -> bool:
        """Whether the pair of parts named ``name_a`` and ``name_b`` is checked."""
        return bool(self.pair_mask([name_a, name_b], np.array([[0, 1]]))[0])

    def members(self, names: Sequence[str | Sequence[str]]) -> tuple[np.ndarray, np.ndarray]:
        """Which parts (each given by its names) are in group a and in group b: two (n,) masks."""
        in_a = np.array([any(matches(p, n) for p in self.a) for n in names], bool)
        in_b = np.array([any(matches(p, n) for p in self.b) for n in names], bool)
        return in_a.reshape(len(names)), in_b.reshape(len(names))

    def pair_mask(self, names: Sequence[str | Sequence[str]], pairs: np.ndarray) -> np.ndarray:
        """Which of ``pairs`` ((k, 2) indices into ``names``) are checked, as a (k,) bool mask.

        ``names`` holds each part's name, or its names (full and relative). Each part is matched
        against the patterns once, so the cost is linear in parts + pairs.
        """
        in_a, in_b = self.members(names)
        i, j = pairs[:, 0], pairs[:, 1]
        return (in_a[i] & in_b[j]) | (in_a[j] & in_b[i])


#: The side of a clash test that holds every part.
ALL_PARTS = ("*",)
#: Keys of a ``[[test]]`` table.
TEST_KEYS = ("name", "a", "b", "clearance", "fail_on", "tolerance")
#: Longest clash test name.
MAX_TEST_NAME = 100


@dataclass(frozen=True)
class ClashTest:
    """A clash test: the parts of side ``a`` against those of side ``b``, judged with its own
    clearance, failing statuses and touching tolerance.

    Attributes
    ----------
    name : str
        Unique within a run; it heads the test's section of every report and enters the ID of
        each of its findings.
    sides : Groups
        Part-name patterns of the two sides; ``ALL_PARTS`` (``"*"``) is every part. A pair is
        the test's when one part is on side a and the other on side b
        (``Groups.pair_mask``).
    clearance : float or None
        Report pairs closer than this, model units; None: no clearance.
    fail_on : tuple of str or None
        Statuses whose findings fail the test: the words as written in a ``Config`` (None: not
        set there); the statuses ``settings.resolve_fail_on`` resolved in ``Settings.tests``.
    tolerance : float or None
        Touching tolerance, model units; None: each pair's own (``tolerances``).
    """

    name: str
    sides: Groups = Groups(ALL_PARTS, ALL_PARTS)
    clearance: float | None = None
    fail_on: tuple[str, ...] | None = None
    tolerance: float | None = None

    def holds(self, names: Sequence[str | Sequence[str]], pairs: np.ndarray) -> np.ndarray:
        """Which of ``pairs`` ((k, 2) indices into ``names``) are this test's, (k,) bool."""
        return self.sides.pair_mask(names, pairs)

    def describe(self) -> str:
        """``a against b``: the two sides' patterns (``all parts`` for ``*``), one line."""

        def side(patterns: tuple[str, ...]) -> str:
            return "all parts" if patterns == ALL_PARTS else ", ".join(patterns)

        return f"{side(self.sides.a)} against {side(self.sides.b)}"


def checked_test_name(name, *, path: str | None = None) -> str:
    """A clash test's name, refused unless a non-empty printable string of at most
    ``MAX_TEST_NAME`` characters, without ``:`` (the command line's separator) or spaces at
    its ends.

    Raises
    ------
    ConfigError
    """
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(path, "a clash test needs a name (a non-empty string)")
    if len(name) > MAX_TEST_NAME or not name.isprintable() or ":" in name or name != name.strip():
        raise ConfigError(
            path,
            f"clash test name {name[:MAX_TEST_NAME]!r} must be printable, at most "
            f"{MAX_TEST_NAME} characters, without ':' or spaces at its ends",
        )
    return name


def parse_test(text: str) -> ClashTest:
    """A clash test from the command line's ``NAME:A:B[:KEY=VALUE]...`` (``--test``).

    ``A`` and ``B`` are comma lists of part-name patterns (``*``: every part); each ``KEY=VALUE``
    sets ``clearance``, ``tolerance`` or ``fail_on`` (a comma list of statuses). Patterns holding
    ``:`` or ``,`` need a ``[[test]]`` table.

    Raises
    ------
    ConfigError
        Naming ``--test`` and the first problem.

    Examples
    --------
    >>> t = parse_test("housing:arm_*,link_*:housing.stl:clearance=1:fail_on=clearance,touching")
    >>> t.name, t.sides.a, t.sides.b, t.clearance, t.fail_on
    ('housing', ('arm_*', 'link_*'), ('housing.stl',), 1.0, ('clearance', 'touching'))
    """
    where = "--test"
    fields = text.split(":")
    if len(fields) < 3:
        raise ConfigError(
            where, f"{text!r} is not NAME:A:B[:KEY=VALUE]... (e.g. fasteners:bolt_*:plate.stl)"
        )
    name, a, b, *extra = fields
    checked_test_name(name.strip(), path=where)
    table: dict = {
        "name": name.strip(),
        "a": [p.strip() for p in a.split(",")],
        "b": [p.strip() for p in b.split(",")],
    }
    for item in extra:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in ("clearance", "tolerance", "fail_on"):
            raise ConfigError(
                where,
                f"test {name.strip()!r}: {item!r} is not KEY=VALUE with KEY clearance, "
                "tolerance or fail_on",
            )
        if key in table:
            raise ConfigError(where, f"test {name.strip()!r}: {key} given twice")
        table[key] = value.split(",") if key == "fail_on" else value.strip()
    return _test(table, where, number=_text_number)


def _text_number(key: str, value, where: str) -> float:
    return checked_number(key, value, *NUMBER_RANGES[key], path=where)


def _toml_number(key: str, value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(where, f"{key} must be a number, not {type(value).__name__}")
    return checked_number(key, value, *NUMBER_RANGES[key], path=where)


def _test(table: dict, where: str, *, number) -> ClashTest:
    """A ``[[test]]`` table (or the command line's fields) as a ``ClashTest``, checked."""
    name = checked_test_name(table.get("name"), path=where)
    label = f"test {name!r}"

    def fail(reason: str):
        raise ConfigError(where, f"{label}: {reason}")

    for key in table:
        if key not in TEST_KEYS:
            fail(f"unknown key {key!r} (known: {', '.join(TEST_KEYS)})")
    sides = [
        _patterns(
            table.get(key, list(ALL_PARTS)),
            fail,
            f"{key} must be a glob pattern or a non-empty list of them ('*': every part)",
        )
        for key in ("a", "b")
    ]
    fail_on = table.get("fail_on")
    if fail_on is not None:
        if isinstance(fail_on, str):
            fail_on = [fail_on]
        if not isinstance(fail_on, list) or not all(isinstance(w, str) for w in fail_on):
            fail("fail_on must be a list of strings")
        try:
            words = parse_fail_on(fail_on)
        except ConfigError as exc:
            fail(exc.reason)
        if words and "new" in words:
            fail("fail_on 'new' is for the whole run (--fail-on new), not one test")
        fail_on = words
    try:
        clearance, tolerance = (
            None if table.get(key) is None else number(key, table[key], where)
            for key in ("clearance", "tolerance")
        )
    except ConfigError as exc:
        fail(exc.reason)
    return ClashTest(name, Groups(*sides), clearance, fail_on, tolerance)


def approval_reason(
    approvals: Sequence[Approval],
    names_a: str | Sequence[str],
    names_b: str | Sequence[str],
    finding_id: str = "",
) -> str | None:
    """The reason of the approval that applies to a finding, or None.

    Rules by part names come first, in order, then rules by finding ID, in order.
    """
    for rule in sorted(approvals, key=lambda r: r.id is not None):
        if rule.matches(names_a, names_b, finding_id):
            return rule.reason
    return None


# --------------------------------------------------------------------------------------------
# Configuration file

CONFIG_NAMES = ("meshcheck.toml", "pyproject.toml")  # in one directory, meshcheck.toml wins
_KEYS = ("tolerance", "clearance", "threshold", "units", "fail_on", "ignore", "groups", "scheduler")
_KEYS += ("pose", "adjacent", "package_paths", "joint", "sweep_budget")  # meshcheck.motion
_KEYS += ("quiet", "hide_touching")  # what the text and Markdown reports list
_KEYS += ("test",)  # clash tests


@dataclass(frozen=True)
class Config:
    """Settings read from a configuration file; None means "not set there".

    Attributes
    ----------
    path : str or None
        The file the settings came from (None for an empty configuration).
    tolerance, clearance, threshold : float or None
        Defaults for the options of the same names.
    fail_on : tuple of str or None
        Finding statuses that fail the run, as written (``settings.resolve_fail_on`` reads them).
    approvals : tuple of Approval
        The ``[[ignore]]`` entries, in file order: by part-name patterns, or by stable ID (such an
        approval lapses when either part changes or moves: the ID hashes meshes and placements).
    groups : Groups or None
        Check only pairs across two groups of parts.
    units : str or None
        Unit of mesh files that declare none, and of the report (``meshcheck.units``): the
        ``units`` key when it is a string.
    file_units : tuple of units.UnitRule
        The ``[units]`` table (``units`` as a table): path or glob, relative to the file's
        folder -> the unit of the input files it names, whatever they declare.
    quiet, hide_touching : bool or None
        Defaults for ``--quiet`` and ``--hide-touching``.
    scheduler : str or None
        Address of a Dask scheduler to run on (``--scheduler``).
    tests : tuple of ClashTest
        The ``[[test]]`` tables, in file order (names unique); an unset clearance, fail_on or
        tolerance is None (the run's applies, ``Settings.from_options``).
    """

    path: str | None = None
    tolerance: float | None = None
    clearance: float | None = None
    threshold: float | None = None
    fail_on: tuple[str, ...] | None = None
    approvals: tuple[Approval, ...] = ()
    groups: Groups | None = None
    units: str | None = None
    file_units: tuple = ()
    quiet: bool | None = None
    hide_touching: bool | None = None
    scheduler: str | None = None
    motion: dict | None = None  # pose, adjacent, package_paths, joints (meshcheck.motion)
    tests: tuple[ClashTest, ...] = ()


def find_config(start: str | os.PathLike | None = None) -> str | None:
    """Find the configuration file that applies in ``start`` (default: the working directory).

    Looks in ``start``, then each parent up to the filesystem root; in each directory
    ``meshcheck.toml`` first, then ``pyproject.toml`` if it has a ``[tool.meshcheck]`` table.
    The first file found wins; files further up are not merged in.

    Returns
    -------
    path : str or None
        The file's path, or None when there is none.
    """
    here = os.path.abspath(os.fspath(start) if start is not None else os.getcwd())
    while True:
        candidate = os.path.join(here, "meshcheck.toml")
        if os.path.isfile(candidate):
            return candidate
        candidate = os.path.join(here, "pyproject.toml")
        if os.path.isfile(candidate) and _has_tool_table(candidate):
            return candidate
        parent = os.path.dirname(here)
        if parent == here:
            return None
        here = parent


def _has_tool_table(path: str) -> bool:
    try:
        doc = _read_toml(path)
    except ConfigError:
        # Not ours to judge: a pyproject.toml that is broken, huge, nested beyond reason or not a
        # regular file is somebody else's, and discovery skips it.
        return False
    return isinstance(doc.get("tool"), dict) and "meshcheck" in doc["tool"]


#: A configuration file larger than this is refused before reading (a real one is a few kB; a
#: pyproject.toml with a long tool section, a few hundred).
MAX_CONFIG_BYTES = 4 << 20


def _read_toml(path: str) -> dict:
    """The TOML document in ``path``: a regular file of at most ``MAX_CONFIG_BYTES``, opened
    without blocking (a FIFO or device is refused, never read)."""
    import tomllib

    try:
        data = _read_regular(path, MAX_CONFIG_BYTES)
        return tomllib.loads(data.decode("utf-8"))
    except OSError as exc:
        raise ConfigError(path, f"cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise ConfigError(path, "invalid TOML: not UTF-8") from None
    except RecursionError:
        raise ConfigError(path, "invalid TOML: nested too deep") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(path, f"invalid TOML: {exc}") from None


def _read_regular(path: str, limit: int) -> bytes:
    """The bytes of the regular file ``path``, checked through one non-blocking descriptor.

    Raises
    ------
    ConfigError
        It is not a regular file, or holds more than ``limit`` bytes.
    OSError
        It cannot be opened or read.
    """
    import stat

    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ConfigError(path, "cannot be read: not a regular file")
        if info.st_size > limit:
            raise ConfigError(
                path, f"is {info.st_size} bytes, over the limit of {limit} for a configuration"
            )
        data = fh.read(limit + 1)
    if len(data) > limit:  # it grew while being read
        raise ConfigError(path, f"is over the limit of {limit} bytes for a configuration")
    return data


def load_config(path: str | os.PathLike) -> Config:
    """Read and validate a configuration file.

    ``pyproject.toml`` files hold the settings in ``[tool.meshcheck]``; any other file holds them
    at the top level. Unknown keys, wrong types, and approvals without a reason are errors.

    Parameters
    ----------
    path : str or path-like
        A ``meshcheck.toml`` or ``pyproject.toml``: a regular file of at most
        ``MAX_CONFIG_BYTES``.

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        Naming the file and the first problem found.

    Examples
    --------
    A ``meshcheck.toml``::

        tolerance = 0.001
        clearance = 0.2
        fail_on = ["interference", "clearance"]

        [[ignore]]
        a = "frame.stl"
        b = "bearing_*.stl"
        reason = "press fit, 0.02 mm interference by design"

        [[ignore]]
        id = "e0ffa4dd810d"
        reason = "approved in review 2024-05; lapses when either part changes"

        [groups]
        a = ["frame.stl"]
        b = ["bolts/*"]

    or clash tests instead of ``[groups]`` (``ClashTest``; each test its own rule)::

        [[test]]
        name = "fasteners"
        a = "bolts/*"
        b = "frame.stl"
        fail_on = ["interference"]
    """
    path = os.fspath(path)
    doc, where = _settings_table(path)

    def fail(reason: str):
        raise ConfigError(path, reason)

    for key in doc:
        if key not in _KEYS:
            fail(f"unknown key {key!r} in {where} (known: {', '.join(_KEYS)})")

    def number(key: str) -> float | None:
        value = doc.get(key)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            fail(f"{key} must be a number, not {type(value).__name__}")
        return checked_number(key, value, *NUMBER_RANGES[key], path=path)

    return Config(
        path=path,
        motion=_motion(doc, path),
        tolerance=number("tolerance"),
        clearance=number("clearance"),
        threshold=number("threshold"),
        fail_on=_fail_on(doc.get("fail_on"), path, fail),
        approvals=_approvals(doc.get("ignore", []), fail),
        groups=_groups(doc.get("groups"), fail),
        scheduler=_scheduler(doc.get("scheduler"), fail),
        units=_unit(doc.get("units"), fail) if not isinstance(doc.get("units"), dict) else None,
        file_units=_file_units(doc.get("units"), path, fail),
        quiet=_flag(doc, "quiet", fail),
        hide_touching=_flag(doc, "hide_touching", fail),
        tests=_tests(doc.get("test", []), path, fail),
    )


def _flag(doc: dict, key: str, fail) -> bool | None:
    """A true/false key, or None when absent."""
    value = doc.get(key)
    if value is not None and not isinstance(value, bool):
        fail(f"{key} must be true or false, not {value!r}")
    return value


def _file_units(value, path: str, fail) -> tuple:
    """The ``[units]`` table as ``UnitRule``s in file order (relative to the file's folder), or
    () when ``units`` is absent or a string."""
    if not isinstance(value, dict):
        return ()
    from .units import UnitRule, unit_name

    base = os.path.dirname(os.path.abspath(path))
    rules = []
    for pattern, unit in value.items():
        if not pattern.strip():
            fail("units: a file pattern must not be empty")
        if not isinstance(unit, str):
            fail(f'units.{pattern!r} must be a unit such as "mm", not {type(unit).__name__}')
        try:
            rules.append(UnitRule(pattern, unit_name(unit), base=base, source=path))
        except ValueError as exc:
            fail(f"units.{pattern!r}: {exc}")
    return tuple(rules)


def _motion(doc: dict, path: str) -> dict | None:
    """The mechanism keys (``pose``, ``adjacent``, ``package_paths``, ``joint``,
    ``sweep_budget``), checked, or None."""
    keys = ("pose", "adjacent", "package_paths", "joint", "sweep_budget")
    motion = {k: doc[k] for k in keys if k in doc}
    if not motion:
        return None
    from .motion import checked_motion

    return checked_motion(motion, path=path) or None


def _settings_table(path: str) -> tuple[dict, str]:
    """The table of ``path`` that holds meshcheck's settings, and where it is, for messages."""
    doc = _read_toml(path)
    where = "top level"
    if os.path.basename(path) == "pyproject.toml":
        tool = doc.get("tool", {})
        doc = tool.get("meshcheck", {}) if isinstance(tool, dict) else tool
        where = "[tool.meshcheck]"
    if not isinstance(doc, dict):
        raise ConfigError(path, f"{where} must be a table")
    return doc, where


def _fail_on(value, path: str, fail) -> tuple[str, ...] | None:
    """The ``fail_on`` key, validated (resolved with the clearance later)."""
    if value is None:
        return None
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(s, str) for s in value):
        fail("fail_on must be a list of strings")
    parse_fail_on(value, path=path)
    return tuple(value)


def _approvals(ignore, fail) -> tuple[Approval, ...]:
    """The ``[[ignore]]`` entries as approvals, in file order."""
    if not isinstance(ignore, list):
        fail("ignore must be an array of tables ([[ignore]] entries with a, b and reason)")
    approvals = []
    for k, rule in enumerate(ignore, start=1):
        label = f"ignore entry {k}"
        if not isinstance(rule, dict):
            fail(f"{label} must be a table with a, b and reason (or id and reason)")
        for key in rule:
            if key not in ("a", "b", "id", "reason"):
                fail(f"unknown key {key!r} in {label} (known: a, b, id, reason)")
        if "id" in rule and ("a" in rule or "b" in rule):
            fail(f"{label}: give either id or a and b, not both")
        for key in ("id", "reason") if "id" in rule else ("a", "b", "reason"):
            if key not in rule:
                hint = ": say why the finding is approved" if key == "reason" else ""
                fail(f"{label} has no {key!r}{hint}")
            if not isinstance(rule[key], str) or not rule[key].strip():
                fail(f"{label}: {key} must be a non-empty string")
        if "id" in rule:
            approvals.append(
                Approval(None, None, rule["reason"].strip(), rule["id"].strip().lower())
            )
        else:
            approvals.append(Approval(rule["a"], rule["b"], rule["reason"].strip()))
    return tuple(approvals)


def _groups(groups, fail) -> Groups | None:
    """The ``[groups]`` table, or None when absent."""
    if groups is None:
        return None
    if not isinstance(groups, dict):
        fail("groups must be a table with a and b")
    for key in groups:
        if key not in ("a", "b"):
            fail(f"unknown key {key!r} in groups (known: a, b)")
    return Groups(
        *(
            _patterns(
                groups.get(key), fail, f"groups.{key} must be a non-empty list of glob patterns"
            )
            for key in ("a", "b")
        )
    )


def _patterns(value, fail, message: str) -> tuple[str, ...]:
    """``value`` (a glob pattern or a list of them) as a tuple of patterns; ``fail(message)``
    unless it is one non-empty string or a non-empty list of them."""
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value or not all(isinstance(p, str) and p for p in value):
        fail(message)
    return tuple(value)


def _tests(tables, path: str, fail) -> tuple[ClashTest, ...]:
    """The ``[[test]]`` tables as clash tests, in file order; a name used twice is refused."""
    if not isinstance(tables, list):
        fail("test must be an array of tables ([[test]] entries with a name)")
    tests: list[ClashTest] = []
    for k, table in enumerate(tables, start=1):
        label = f"test entry {k}"
        if not isinstance(table, dict):
            fail(f"{label} must be a table with a name, a, b...")
        if "name" not in table:
            fail(f"{label} has no 'name'")
        test = _test(table, path, number=_toml_number)
        if any(t.name == test.name for t in tests):
            fail(f"two clash tests are named {test.name!r}: each test needs its own name")
        tests.append(test)
    return tuple(tests)


def _scheduler(value, fail) -> str | None:
    """The ``scheduler`` key, checked, or None when absent."""
    if value is None:
        return None
    try:
        return checked_scheduler(value)
    except ConfigError as exc:
        fail(exc.reason)


#: URL schemes of the Dask schedulers meshcheck connects to (``inproc://``, ``ucx://`` and others
#: need a cluster set up in-process or extra libraries; they are refused up front).
SCHEDULER_SCHEMES = ("tcp", "tls")


def checked_scheduler(value) -> str:
    """A Dask scheduler address as given (``tcp://HOST:PORT``, ``tls://HOST:PORT``, ``HOST:PORT``),
    checked up front; whether a scheduler answers there is found out when connecting.

    Raises
    ------
    ConfigError
        Not such an address: another scheme, no host, a port outside 1..65535, a broken IPv6
        literal, spaces or control characters.

    Examples
    --------
    >>> checked_scheduler("10.0.0.5:8786"), checked_scheduler("tls://[::1]:8786")
    ('10.0.0.5:8786', 'tls://[::1]:8786')
    """
    from urllib.parse import urlsplit

    usage = "scheduler must be a scheduler address like tcp://HOST:8786"
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(None, usage)
    value = value.strip()
    if len(value) > 500 or not value.isprintable() or any(c.isspace() for c in value):
        raise ConfigError(None, usage)
    try:
        parts = urlsplit(value if "://" in value else f"tcp://{value}")
        host, port = parts.hostname, parts.port
    except ValueError as exc:
        raise ConfigError(None, f"{usage}, not {value!r} ({exc})") from None
    if parts.scheme not in SCHEDULER_SCHEMES:
        raise ConfigError(
            None, f"{usage}: scheme {parts.scheme}:// is not supported (use tcp:// or tls://)"
        )
    if not host or port is None or port == 0 or parts.path not in ("", "/") or parts.query:
        raise ConfigError(None, f"{usage}, not {value!r}")
    return value


def _unit(value, fail) -> str | None:
    """The ``units`` key: a known length unit name, or None when absent."""
    if value is None:
        return None
    from .units import unit_name

    if not isinstance(value, str):
        fail(
            f'units must be a unit such as "mm", or a table of file patterns and units, not '
            f"{type(value).__name__}"
        )
    try:
        return unit_name(value)
    except ValueError as exc:
        fail(f"units: {exc}")


def parse_fail_on(values: Iterable[str], *, path: str | None = None) -> tuple[str, ...] | None:
    """The statuses named in ``values`` (each a name or a comma list), checked.

    ``none`` stands alone and means nothing fails the run (an empty tuple); no words at all give
    None (the default applies). ``new`` is not a status: it narrows the failing findings to those
    a baseline report does not hold (``Settings.fail_on_new``).

    Raises
    ------
    ConfigError
        For an unknown word, or ``none`` beside a status.

    Examples
    --------
    >>> parse_fail_on(["touching,clearance"])
    ('touching', 'clearance')
    >>> parse_fail_on(["none"])
    ()
    """
    words: list[str] = []
    for value in values:
        for word in value.split(","):
            word = word.strip().lower()
            if not word:
                continue
            if word not in ("none", "new") and word not in FAIL_ON_CHOICES:
                raise ConfigError(
                    path,
                    f"unknown fail-on status {word!r} (choose from {', '.join(FAIL_ON_CHOICES)}, "
                    "new, none)",
                )
            if word not in words:
                words.append(word)
    if "none" in words:
        if len(words) > 1:
            others = ", ".join(w for w in words if w != "none")
            raise ConfigError(path, f"fail-on 'none' contradicts {others}: give one or the other")
        return ()
    return tuple(words) if words else None


def checked_number(
    name: str, value, low: float, high: float = math.inf, *, path: str | None = None
) -> float:
    """``value`` as a float, refused unless finite and within ``[low, high]``.

    Raises
    ------
    ConfigError
        Naming the setting and the value (NaN and infinities included).
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(path, f"{name} must be a number, not {value!r}") from None
    if not math.isfinite(number):
        raise ConfigError(path, f"{name} must be a finite number, not {value}")
    if not low <= number <= high:
        limits = f"at least {low:g}" if high == math.inf else f"in [{low:g}, {high:g}]"
        raise ConfigError(path, f"{name} = {value} is out of range: must be {limits}")
    return number
