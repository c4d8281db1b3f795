"""Mechanism settings: the pose robots are checked at, where their meshes live, what is swept.

A pose is a setting like any other: the URDF reader (``load.urdf``) places every link at it, so
the rest of the check sees ordinary placed parts. ``Motion`` rides in ``Settings.motion``.
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
        names NAME (or holding such a folder).
    adjacent : bool
        Approve findings between links joined by a joint (reason "adjacent"), as MoveIt does.
    sweep : tuple of str or None
        None: no sweep; empty: sweep every movable joint; else the joints named.
    resolution : float
        Narrowest joint interval the sweep splits, radians or metres.
    """

    pose: tuple[JointValue, ...] = ()
    package_paths: tuple[str, ...] = ()
    adjacent: bool = True
    sweep: tuple[str, ...] | None = None
    resolution: float = DEFAULT_RESOLUTION

    def __post_init__(self):
        names = [v.joint for v in self.pose]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ConfigError(None, f"pose gives joint {twice[0]!r} more than once")
        if not (math.isfinite(self.resolution) and self.resolution > 0.0):
            raise ConfigError(None, f"sweep resolution must be positive, not {self.resolution!r}")


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
    ``adjacent`` (bool), ``package_paths`` (folders, relative to the file's folder)."""
    out: dict = {}
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
        out["package_paths"] = tuple(os.path.join(base, p) for p in paths)
    return out


def motion_from_options(
    file: Mapping | None,
    *,
    pose=None,
    package_paths=(),
    adjacent: bool | None = None,
    sweep=None,
    resolution: float | None = None,
) -> Motion:
    """The run's ``Motion``: options given here win over the configuration file's (``file``,
    from ``checked_motion``); pose values of both merge, an option's winning for its joint."""
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
    )


def _is_values(pose) -> bool:
    return isinstance(pose, tuple | list) and all(isinstance(v, JointValue) for v in pose)


__all__ = [
    "DEFAULT_RESOLUTION",
    "JointValue",
    "Motion",
    "checked_motion",
    "motion_from_options",
    "parse_pose",
    "parse_value",
]
