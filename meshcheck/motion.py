"""Mechanism settings: the pose robots are checked at, where their meshes live, what is swept,
and which SRDF is audited.

A pose is a setting like any other: the URDF reader (``load.urdf``) places every link at it, and
``load.joints`` places the parts of mesh files that ``[[joint]]`` tables of the configuration
(``JointSpec``) make into a mechanism, so the rest of the check sees ordinary placed parts.
``Motion`` rides in ``Settings.motion``.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from .errors import ConfigError

#: Default sweep resolution: joint intervals narrower than this (radians, or metres for a slide)
#: are not split further; a pair still undecided there is reported "sometimes" only with a
#: colliding witness, else "undecided". 0.001 rad moves a point 1 m from the axis by 1 mm.
DEFAULT_RESOLUTION = 1e-3

#: Default sweep budget: the work one run's sweep may do (a pose of a link pair costs the joints
#: that move it, a convex-piece pair measured 1; see ``sweep.search.WorkBudget``). The PR2's
#: 1,431 link pairs need about two fifths of it (``bench/sweep.py --robot pr2`` prints the work);
#: any input, however many links, stops there with the pairs left over undecided.
DEFAULT_SWEEP_BUDGET = 1_000_000_000
#: The largest budget accepted (a bound a CI job can still rely on).
MAX_SWEEP_BUDGET = 10**12

#: Joint types a ``[[joint]]`` table may have (URDF's, less floating and planar).
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed")
#: ``[[joint]]`` tables one configuration may hold: real mechanisms have a few; patterns are
#: matched against every part for each.
MAX_JOINTS = 1000
#: Keys of a ``[[joint]]`` table.
JOINT_KEYS = ("name", "parent", "child", "type", "axis", "origin", "range")
#: The ``disable_collisions`` reasons an SRDF audit checks unless told otherwise: the entries
#: MoveIt's Setup Assistant wrote from random samples.
AUDIT_REASONS = ("Never",)

_VALUE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(deg)?\s*$")


@dataclass(frozen=True)
class JointValue:
    """One joint value of a pose, as given.

    Attributes
    ----------
    joint : str
        The joint's name in the URDF.
    value : float
        Radians (revolute, continuous) or metres (prismatic); already converted from degrees.
    in_degrees : bool
        Given with the ``deg`` suffix (only revolute and continuous joints take one).
    """

    joint: str
    value: float
    in_degrees: bool = False


@dataclass(frozen=True)
class JointSpec:
    """One ``[[joint]]`` table: parts of mesh files moved relative to others.

    Attributes
    ----------
    name : str
        The joint's name, for ``--pose`` and ``--sweep-joints``.
    parent, child : str
        Part-name patterns (globs, as approvals use): the parts the joint moves (``child``)
        and the parts it is mounted on (``parent``), as they lie in the files at value 0.
    type : str
        One of ``JOINT_TYPES``.
    axis : (3,) tuple of float
        Unit axis in world coordinates as the files place the parts: the rotation axis, or the
        slide direction.
    origin : (3,) tuple of float
        A point on the rotation axis, world coordinates, report units.
    lower, upper : float
        The range: radians (revolute), report units (prismatic); -inf/inf for continuous.
    source : str or None
        The configuration file, for messages.
    """

    name: str
    parent: str
    child: str
    type: str
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lower: float = -math.inf
    upper: float = math.inf
    source: str | None = None


@dataclass(frozen=True)
class Motion:
    """How mechanisms are posed and swept.

    Attributes
    ----------
    pose : tuple of JointValue
        Joint values; joints not named are at zero (or the nearest limit when zero is outside
        it); mimic joints follow their leader.
    package_paths : tuple of str
        Folders searched for ``package://NAME/...`` meshes besides the URDF's folder and its
        ancestors: a folder named NAME, a folder holding NAME, or one whose ``package.xml``
        names NAME (or holding such a folder). Files a robot names are read inside these, its
        folder, the package it lies in and the package roots ``package://`` finds
        (``load.urdf.resolve_mesh``).
    adjacent : bool
        Approve findings between links joined by a joint (reason "adjacent"), as MoveIt does.
    sweep : tuple of str or None
        None: no sweep; empty: sweep every movable joint; else the joints named.
    resolution : float
        Narrowest joint interval the sweep splits, radians or metres.
    joints : tuple of JointSpec
        The configuration's ``[[joint]]`` tables: a mechanism made of mesh-file parts.
    budget : int
        Work the sweep may do (``DEFAULT_SWEEP_BUDGET``); link pairs past it are
        undecided.
    audit : str or None
        An SRDF whose ``disable_collisions`` entries are audited over the joint ranges
        (``--audit-srdf``).
    audit_reasons : tuple of str
        The entries' reasons audited (``--audit-reasons``); empty: every entry.
    allow_outside : bool
        Read files a robot names outside its folder, its package and the package paths
        (``--allow-outside-paths``: set on the command line only, never by a configuration
        file a pull request could change).
    """

    pose: tuple[JointValue, ...] = ()
    package_paths: tuple[str, ...] = ()
    adjacent: bool = True
    sweep: tuple[str, ...] | None = None
    resolution: float = DEFAULT_RESOLUTION
    joints: tuple[JointSpec, ...] = ()
    budget: int = DEFAULT_SWEEP_BUDGET
    audit: str | None = None
    audit_reasons: tuple[str, ...] = AUDIT_REASONS
    allow_outside: bool = False

    def __post_init__(self):
        names = [v.joint for v in self.pose]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ConfigError(None, f"pose gives joint {twice[0]!r} more than once")
        if not (math.isfinite(self.resolution) and self.resolution > 0.0):
            raise ConfigError(None, f"sweep resolution must be positive, not {self.resolution!r}")
        checked_budget(self.budget)


def is_within(folder: str, path: str) -> bool:
    """Whether absolute ``path`` is ``folder`` or below it (False on another drive)."""
    try:
        return os.path.commonpath([path, folder]) == folder
    except ValueError:
        return False


def checked_budget(value, *, path: str | None = None) -> int:
    """A sweep budget: a whole number from 1 to ``MAX_SWEEP_BUDGET``.

    Examples
    --------
    >>> checked_budget(5_000_000)
    5000000
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, int)
        or not (1 <= value <= MAX_SWEEP_BUDGET)
    ):
        raise ConfigError(
            path, f"sweep_budget must be a whole number from 1 to {MAX_SWEEP_BUDGET}, not {value!r}"
        )
    return value


def parse_value(joint: str, text: str | float | int, *, where: str | None = None) -> JointValue:
    """A joint value from ``0.5`` (radians or metres) or ``30deg`` (degrees).

    Examples
    --------
    >>> parse_value("elbow", "90deg").value == math.pi / 2
    True
    >>> parse_value("slide", 0.25)
    JointValue(joint='slide', value=0.25, in_degrees=False)
    """
    if isinstance(text, bool) or not isinstance(text, str | int | float):
        raise ConfigError(where, f"pose value of {joint!r} must be a number or 'NUMBERdeg'")
    if isinstance(text, str):
        match = _VALUE.match(text)
        if match is None:
            raise ConfigError(
                where, f"pose value {text!r} of {joint!r} is not a number (or NUMBERdeg)"
            )
        number, degrees = float(match.group(1)), match.group(2) is not None
    else:
        number, degrees = float(text), False
    if not math.isfinite(number):
        raise ConfigError(where, f"pose value of {joint!r} must be finite, not {text!r}")
    value = math.radians(number) if degrees else number
    return JointValue(joint, value, degrees)


def parse_pose(
    given: str | Iterable[str] | Mapping[str, str | float], *, where: str | None = None
) -> tuple[JointValue, ...]:
    """Joint values from ``joint=value,...`` strings (repeatable) or a ``[pose]`` table.

    Examples
    --------
    >>> [(v.joint, round(v.value, 4)) for v in parse_pose("a=0.5, b=90deg")]
    [('a', 0.5), ('b', 1.5708)]
    """
    if isinstance(given, Mapping):
        return tuple(parse_value(str(k), v, where=where) for k, v in given.items())
    if isinstance(given, str):
        given = [given]
    out = []
    for text in given:
        for item in text.split(","):
            if not item.strip():
                continue
            joint, eq, value = item.partition("=")
            if not eq or not joint.strip():
                raise ConfigError(where, f"pose item {item.strip()!r} is not JOINT=VALUE")
            out.append(parse_value(joint.strip(), value, where=where))
    return tuple(out)


def checked_motion(table: Mapping, *, path: str | None = None) -> dict:
    """A configuration file's mechanism keys, validated: ``pose`` (a table of joint values),
    ``adjacent`` (bool), ``package_paths`` (folders inside the file's folder, relative to it:
    a configuration a pull request can change never points the readers elsewhere; the command
    line's ``--package-path`` can), ``joint`` (an array of ``[[joint]]`` tables,
    ``checked_joints``), ``sweep_budget`` (a whole number, ``checked_budget``)."""
    out: dict = {}
    if "sweep_budget" in table:
        out["budget"] = checked_budget(table["sweep_budget"], path=path)
    if "joint" in table:
        out["joints"] = checked_joints(table["joint"], path=path)
    if "pose" in table:
        if not isinstance(table["pose"], Mapping):
            raise ConfigError(path, "pose must be a table of joint = value")
        out["pose"] = parse_pose(table["pose"], where=path)
    if "adjacent" in table:
        if not isinstance(table["adjacent"], bool):
            raise ConfigError(path, "adjacent must be true or false")
        out["adjacent"] = table["adjacent"]
    if "package_paths" in table:
        paths = table["package_paths"]
        if isinstance(paths, str):
            paths = [paths]
        if not isinstance(paths, list) or not all(isinstance(p, str) and p for p in paths):
            raise ConfigError(path, "package_paths must be a list of folders")
        base = os.path.dirname(os.path.abspath(path)) if path else ""
        root = os.path.abspath(base)
        for p in paths:
            if not is_within(root, os.path.abspath(os.path.join(base, p))):
                raise ConfigError(
                    path,
                    f"package_paths: {p!r} is outside the configuration's folder (give folders "
                    "elsewhere with --package-path)",
                )
        out["package_paths"] = tuple(os.path.join(base, p) for p in paths)
    return out


def checked_joints(tables, *, path: str | None = None) -> tuple[JointSpec, ...]:
    """The ``[[joint]]`` tables of a configuration file, validated.

    Each has ``name``, ``parent`` and ``child`` (part-name patterns), ``type`` (one of
    ``JOINT_TYPES``); a moving joint an ``axis`` (3 numbers, not all zero); a revolute or
    continuous one may have an ``origin`` (a point on the axis, default the origin); a revolute
    or prismatic one a ``range`` of two values, radians or ``"NUMBERdeg"`` for a revolute joint,
    report units for a prismatic one (lower first).

    Raises
    ------
    ConfigError
        Naming the file, the entry and the first problem found.

    Examples
    --------
    >>> (hinge,) = checked_joints([{"name": "hinge", "parent": "frame.stl", "child": "door.stl",
    ...     "type": "revolute", "axis": [0, 0, 1], "range": ["0deg", "90deg"]}])
    >>> round(hinge.upper, 4)
    1.5708
    """
    if not isinstance(tables, list):
        raise ConfigError(path, "joint must be an array of tables ([[joint]] entries)")
    if len(tables) > MAX_JOINTS:
        raise ConfigError(
            path, f"{len(tables)} [[joint]] tables, over the limit of {MAX_JOINTS} (write a URDF)"
        )
    out: list[JointSpec] = []
    for k, table in enumerate(tables, start=1):
        spec = _joint_spec(table, f"joint entry {k}", path)
        if any(j.name == spec.name for j in out):
            raise ConfigError(path, f"joint entry {k}: a joint named {spec.name!r} comes twice")
        out.append(spec)
    return tuple(out)


def _joint_spec(table, label: str, path: str | None) -> JointSpec:
    """One ``[[joint]]`` table, validated (``checked_joints``)."""

    def fail(reason: str):
        raise ConfigError(path, f"{label}: {reason}")

    if not isinstance(table, Mapping):
        fail("must be a table with name, parent, child, type, axis and range")
    for key in table:
        if key not in JOINT_KEYS:
            fail(f"unknown key {key!r} (known: {', '.join(JOINT_KEYS)})")
    for key in ("name", "parent", "child", "type"):
        if not isinstance(table.get(key), str) or not table[key].strip():
            fail(f"{key} must be a non-empty string")
    name, kind = table["name"].strip(), table["type"].strip()
    label = f"{label} ({name!r})"
    if not name.isprintable() or any(c in name for c in ",="):
        fail("name must be printable, without ',' or '=' (a --pose item is NAME=VALUE)")
    if kind not in JOINT_TYPES:
        fail(f"unknown type {kind!r} (known: {', '.join(JOINT_TYPES)})")
    allowed = {
        "fixed": (),
        "continuous": ("axis", "origin"),
        "revolute": ("axis", "origin", "range"),
        "prismatic": ("axis", "range"),
    }[kind]
    for key in ("axis", "origin", "range"):
        if key in table and key not in allowed:
            fail(f"a {kind} joint takes no {key}")
        if key in ("axis", "range") and key in allowed and key not in table:
            fail(f"a {kind} joint needs {'an axis' if key == 'axis' else 'a range'}")
    axis = _vector(table.get("axis", [0.0, 0.0, 1.0]), "axis", fail)
    norm = math.sqrt(sum(x * x for x in axis))
    if norm == 0.0:
        fail("axis must not be zero")
    origin = _vector(table.get("origin", [0.0, 0.0, 0.0]), "origin", fail)
    lower, upper = _range(table.get("range"), kind, name, fail, path)
    return JointSpec(
        name,
        table["parent"],
        table["child"],
        kind,
        tuple(x / norm for x in axis),
        origin,
        lower,
        upper,
        path,
    )


def _vector(value, key: str, fail) -> tuple[float, float, float]:
    if (
        not isinstance(value, list)
        or len(value) != 3
        or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in value)
        or not all(math.isfinite(x) and abs(x) < 1e15 for x in value)
    ):
        fail(f"{key} must be 3 finite numbers, as [x, y, z]")
    return (float(value[0]), float(value[1]), float(value[2]))


def _range(value, kind: str, name: str, fail, path: str | None) -> tuple[float, float]:
    """A joint's (lower, upper) from its ``range``; +-inf for continuous, 0 for fixed."""
    if kind == "continuous":
        return -math.inf, math.inf
    if kind == "fixed":
        return 0.0, 0.0
    if not isinstance(value, list) or len(value) != 2:
        fail('range must be two values, as [lower, upper] (radians, or "NUMBERdeg")')
    ends = [parse_value(name, v, where=path) for v in value]
    if kind == "prismatic" and any(v.in_degrees for v in ends):
        fail("is prismatic: give its range in report units, not degrees")
    lower, upper = (v.value for v in ends)
    if not lower <= upper:
        fail(f"range lower end {value[0]!r} is above its upper end {value[1]!r}")
    if max(abs(lower), abs(upper)) > 1e15:
        fail("range ends must be below 1e15 in size")
    return lower, upper


def motion_from_options(
    file: Mapping | None,
    *,
    pose=None,
    package_paths=(),
    adjacent: bool | None = None,
    sweep=None,
    resolution: float | None = None,
    budget: int | None = None,
    audit: str | None = None,
    audit_reasons=None,
    allow_outside: bool = False,
) -> Motion:
    """The run's ``Motion``: options given here win over the configuration file's (``file``,
    from ``checked_motion``); pose values of both merge, an option's winning for its joint.
    ``audit_reasons`` is a comma list or a sequence of reasons, ``all`` for every entry."""
    file = file or {}
    merged = {v.joint: v for v in file.get("pose", ())}
    if pose is not None:
        given = Motion(pose=tuple(pose) if _is_values(pose) else parse_pose(pose))  # refuses twice
        merged.update({v.joint: v for v in given.pose})
    if isinstance(sweep, str):
        sweep = tuple(s.strip() for s in sweep.split(",") if s.strip())
    return Motion(
        pose=tuple(merged.values()),
        package_paths=(*package_paths, *file.get("package_paths", ())),
        adjacent=file.get("adjacent", True) if adjacent is None else adjacent,
        sweep=None if sweep is None else tuple(sweep),
        resolution=DEFAULT_RESOLUTION if resolution is None else resolution,
        joints=file.get("joints", ()),
        budget=file.get("budget", DEFAULT_SWEEP_BUDGET) if budget is None else budget,
        audit=audit,
        audit_reasons=AUDIT_REASONS if audit_reasons is None else parse_reasons(audit_reasons),
        allow_outside=bool(allow_outside),
    )


def parse_reasons(given: str | Iterable[str]) -> tuple[str, ...]:
    """``disable_collisions`` reasons to audit from ``Never,Default`` (repeatable), or ``all``
    alone for every entry (an empty tuple).

    Examples
    --------
    >>> parse_reasons("Never, Default"), parse_reasons(["all"])
    (('Never', 'Default'), ())
    """
    if isinstance(given, str):
        given = [given]
    words: list[str] = []
    for text in given:
        for word in (w.strip() for w in text.split(",")):
            if not word:
                continue
            if not word.isprintable():
                raise ConfigError("--audit-reasons", f"{word!r} is not a reason")
            if word not in words:
                words.append(word)
    if not words:
        raise ConfigError("--audit-reasons", "give one reason or more (Never,Default...), or all")
    if "all" in words:
        if len(words) > 1:
            raise ConfigError("--audit-reasons", "'all' stands alone")
        return ()
    return tuple(words)


def _is_values(pose) -> bool:
    return isinstance(pose, tuple | list) and all(isinstance(v, JointValue) for v in pose)


__all__ = [
    "AUDIT_REASONS",
    "DEFAULT_RESOLUTION",
    "DEFAULT_SWEEP_BUDGET",
    "JOINT_TYPES",
    "JointSpec",
    "JointValue",
    "Motion",
    "checked_budget",
    "checked_joints",
    "checked_motion",
    "is_within",
    "motion_from_options",
    "parse_pose",
    "parse_reasons",
    "parse_value",
]
