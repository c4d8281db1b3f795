"""Options, tolerances and the rules that approve findings or restrict which pairs are checked."""

from __future__ import annotations

import fnmatch
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError

# Overlaps and gaps below this fraction of the assembly's bounding-box diagonal count as touching.
# STL stores float32 (about 7 significant digits) and CAD exporters round coordinates, so faces
# modelled as coincident land up to ~1e-6 of the model size apart; 1e-5 leaves a 10x margin while
# staying far below any clearance an engineer specifies (1 um on a 100 mm assembly).
TOLERANCE_FRACTION = 1e-5


def default_tolerance(lower: np.ndarray, upper: np.ndarray) -> float:
    """Touching tolerance for an assembly with bounding box ``lower``..``upper``, model units."""
    diagonal = float(np.linalg.norm(np.asarray(upper) - np.asarray(lower)))
    return TOLERANCE_FRACTION * diagonal if diagonal > 0 else TOLERANCE_FRACTION


@dataclass(frozen=True)
class Approval:
    """An approved finding: parts matching ``a`` and ``b`` (glob patterns, either order)."""

    a: str
    b: str
    reason: str

    def matches(self, name_a: str, name_b: str) -> bool:
        return (fnmatch.fnmatchcase(name_a, self.a) and fnmatch.fnmatchcase(name_b, self.b)) or (
            fnmatch.fnmatchcase(name_a, self.b) and fnmatch.fnmatchcase(name_b, self.a)
        )


@dataclass(frozen=True)
class Groups:
    """Check only parts matching one of ``a`` against parts matching one of ``b``."""

    a: tuple[str, ...]
    b: tuple[str, ...]

    def allows(self, name_a: str, name_b: str) -> bool:
        """Whether the pair of parts named ``name_a`` and ``name_b`` is checked."""
        return bool(self.pair_mask([name_a, name_b], np.array([[0, 1]]))[0])

    def pair_mask(self, names: Sequence[str], pairs: np.ndarray) -> np.ndarray:
        """Which of ``pairs`` ((k, 2) indices into ``names``) are checked, as a (k,) bool mask.

        Each name is matched against the patterns once, so the cost is linear in parts + pairs.
        """
        in_a = np.array([any(fnmatch.fnmatchcase(n, p) for p in self.a) for n in names], bool)
        in_b = np.array([any(fnmatch.fnmatchcase(n, p) for p in self.b) for n in names], bool)
        i, j = pairs[:, 0], pairs[:, 1]
        return (in_a[i] & in_b[j]) | (in_a[j] & in_b[i])


def approval_reason(approvals: Sequence[Approval], name_a: str, name_b: str) -> str | None:
    """The reason of the first approval that matches the pair, or None."""
    for rule in approvals:
        if rule.matches(name_a, name_b):
            return rule.reason
    return None


# --------------------------------------------------------------------------------------------
# Configuration file

CONFIG_NAMES = ("meshcheck.toml", "pyproject.toml")  # in one directory, meshcheck.toml wins
FAIL_ON_CHOICES = ("interference", "touching", "clearance")
_KEYS = ("tolerance", "clearance", "threshold", "fail_on", "ignore", "groups")


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
        Finding statuses that fail the run.
    ignore : tuple of Approval
        Approved findings, by part-name patterns.
    ignore_ids : tuple of (str, str)
        Approved findings by stable ID, with the reason: the approval lapses when either mesh
        changes, since the ID hashes both meshes' content.
    groups : Groups or None
        Check only pairs across two groups of parts.
    """

    path: str | None = None
    tolerance: float | None = None
    clearance: float | None = None
    threshold: float | None = None
    fail_on: tuple[str, ...] | None = None
    ignore: tuple[Approval, ...] = ()
    ignore_ids: tuple[tuple[str, str], ...] = ()
    groups: Groups | None = None


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
        return False  # a broken pyproject.toml that is not ours is somebody else's problem
    return isinstance(doc.get("tool"), dict) and "meshcheck" in doc["tool"]


def _read_toml(path: str) -> dict:
    import tomllib

    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as exc:
        raise ConfigError(path, f"cannot be read ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(path, f"invalid TOML: {exc}") from None


def load_config(path: str | os.PathLike) -> Config:
    """Read and validate a configuration file.

    ``pyproject.toml`` files hold the settings in ``[tool.meshcheck]``; any other file holds them
    at the top level. Unknown keys, wrong types, and approvals without a reason are errors.

    Parameters
    ----------
    path : str or path-like
        A ``meshcheck.toml`` or ``pyproject.toml``.

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
    """
    path = os.fspath(path)
    doc = _read_toml(path)
    where = "top level"
    if os.path.basename(path) == "pyproject.toml":
        doc = doc.get("tool", {}).get("meshcheck", {})
        where = "[tool.meshcheck]"
    if not isinstance(doc, dict):
        raise ConfigError(path, f"{where} must be a table")

    def fail(reason: str):
        raise ConfigError(path, reason)

    for key in doc:
        if key not in _KEYS:
            fail(f"unknown key {key!r} in {where} (known: {', '.join(_KEYS)})")

    def number(key: str, lo: float, hi: float = float("inf")) -> float | None:
        value = doc.get(key)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            fail(f"{key} must be a number, not {type(value).__name__}")
        if not lo <= float(value) <= hi:
            fail(f"{key} = {value} is out of range [{lo:g}, {hi:g}]")
        return float(value)

    fail_on = doc.get("fail_on")
    if fail_on is not None:
        if isinstance(fail_on, str):
            fail_on = [fail_on]
        if not isinstance(fail_on, list) or not all(isinstance(s, str) for s in fail_on):
            fail("fail_on must be a list of strings")
        fail_on = tuple(parse_fail_on(fail_on, path=path))

    ignore = doc.get("ignore", [])
    if not isinstance(ignore, list):
        fail("ignore must be an array of tables ([[ignore]] entries with a, b and reason)")
    approvals, id_approvals = [], []
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
            id_approvals.append((rule["id"].strip().lower(), rule["reason"].strip()))
        else:
            approvals.append(Approval(rule["a"], rule["b"], rule["reason"].strip()))

    groups = doc.get("groups")
    if groups is not None:
        if not isinstance(groups, dict):
            fail("groups must be a table with a and b")
        for key in groups:
            if key not in ("a", "b"):
                fail(f"unknown key {key!r} in groups (known: a, b)")
        patterns = []
        for key in ("a", "b"):
            value = groups.get(key)
            if isinstance(value, str):
                value = [value]
            if not isinstance(value, list) or not value or not all(
                isinstance(p, str) and p for p in value
            ):
                fail(f"groups.{key} must be a non-empty list of glob patterns")
            patterns.append(tuple(value))
        groups = Groups(*patterns)

    return Config(
        path=path,
        tolerance=number("tolerance", 0.0),
        clearance=number("clearance", 0.0),
        threshold=number("threshold", 0.01, 1.0),
        fail_on=fail_on,
        ignore=tuple(approvals),
        ignore_ids=tuple(id_approvals),
        groups=groups,
    )


def parse_fail_on(values: Iterable[str], *, path: str | None = None) -> list[str]:
    """Statuses named in ``values`` (each a name or a comma list); ``none`` selects nothing.

    Raises
    ------
    ConfigError
        For an unknown status name.
    """
    out: list[str] = []
    for value in values:
        for word in value.split(","):
            word = word.strip().lower()
            if not word or word == "none":
                continue
            if word not in FAIL_ON_CHOICES:
                raise ConfigError(
                    path, f"unknown fail-on status {word!r} (choose from "
                    f"{', '.join(FAIL_ON_CHOICES)}, none)"
                )
            if word not in out:
                out.append(word)
    return out
