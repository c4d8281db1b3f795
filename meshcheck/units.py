"""Length units: the names meshcheck accepts, their sizes, and which unit a report uses.

Every part is converted at load to one *report unit*, the unit of every length meshcheck reports
(distances, depths, locations, tolerances; volumes in its cube). The rule:

- ``units`` given (the command line's ``--units``): it is the unit of every file that declares
  none (STL, OBJ, PLY, OFF) and the report unit;
- ``units`` not given: files that declare none are millimetres; the report unit is the unit all
  the files declare when every file declares one and they agree, else millimetres.

Files that declare a unit: glTF/GLB (always metres, by the glTF specification), 3MF (its
``unit`` attribute, millimetre when absent), STEP (the unit in its header).

A file's own unit can be given (``UnitRule``: ``--units FILE=UNIT``, the configuration's
``[units]`` table): it wins over what the file declares (a glTF exported in millimetres, a 3MF
or STEP whose unit is wrong) and counts as that file's declared unit in the rule above.

Examples
--------
>>> unit_name("Millimeter"), unit_name("inch")
('mm', 'in')
>>> scale("in", "mm")
25.4
>>> report_unit(["m", "m"], None), report_unit(["m", None], None), report_unit(["m"], "in")
('m', 'mm', 'in')
"""

from __future__ import annotations

import fnmatch
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

#: Size of each unit in metres, by canonical name: every length unit a STEP file can declare
#: (an SI metre with any prefix ISO 10303-41 allows, or a conversion-based inch, foot, yard,
#: mile, mil or microinch), which includes every unit 3MF and glTF declare. Canonical names are
#: case-sensitive where SI needs it (``Mm`` megametre, ``mm`` millimetre; ``Pm``, ``pm``).
METRES = {
    "am": 1e-18,
    "fm": 1e-15,
    "pm": 1e-12,
    "nm": 1e-9,
    "um": 1e-6,
    "mm": 1e-3,
    "cm": 1e-2,
    "dm": 1e-1,
    "m": 1.0,
    "dam": 1e1,
    "hm": 1e2,
    "km": 1e3,
    "Mm": 1e6,
    "Gm": 1e9,
    "Tm": 1e12,
    "Pm": 1e15,
    "Em": 1e18,
    "uin": 2.54e-8,
    "mil": 2.54e-5,
    "in": 0.0254,
    "ft": 0.3048,
    "yd": 0.9144,
    "mi": 1609.344,
}

#: The SI prefixes of ISO 10303-41 (``SI_UNIT(.MILLI.,.METRE.)``): prefix -> canonical name.
SI_PREFIXES = {
    "EXA": "Em",
    "PETA": "Pm",
    "TERA": "Tm",
    "GIGA": "Gm",
    "MEGA": "Mm",
    "KILO": "km",
    "HECTO": "hm",
    "DECA": "dam",
    "DECI": "dm",
    "CENTI": "cm",
    "MILLI": "mm",
    "MICRO": "um",
    "NANO": "nm",
    "PICO": "pm",
    "FEMTO": "fm",
    "ATTO": "am",
}

#: Other spellings (lower case) of the canonical names, including the 3MF and STEP words (a STEP
#: ``CONVERSION_BASED_UNIT`` name is looked up here, upper case folded).
ALIASES = {
    "micron": "um",
    "microns": "um",
    "micrometer": "um",
    "micrometers": "um",
    "micrometre": "um",
    "micrometres": "um",
    "µm": "um",
    "nanometer": "nm",
    "nanometre": "nm",
    "millimeter": "mm",
    "millimeters": "mm",
    "millimetre": "mm",
    "millimetres": "mm",
    "centimeter": "cm",
    "centimeters": "cm",
    "centimetre": "cm",
    "centimetres": "cm",
    "decimeter": "dm",
    "decimetre": "dm",
    "meter": "m",
    "meters": "m",
    "metre": "m",
    "metres": "m",
    "kilometer": "km",
    "kilometre": "km",
    "inch": "in",
    "inches": "in",
    "foot": "ft",
    "feet": "ft",
    "yard": "yd",
    "yards": "yd",
    "mile": "mi",
    "miles": "mi",
    "thou": "mil",
    "mils": "mil",
    "microinch": "uin",
    "micro inch": "uin",
}

#: Unit of files that declare none, when the caller names no unit.
DEFAULT_UNIT = "mm"


def unit_name(name: str) -> str:
    """Canonical name (a key of ``METRES``: ``mm``, ``in``, ``km``...) of a unit name or alias.

    Raises
    ------
    ValueError
        The name is not a known length unit; the message lists the known ones.
    """
    text = str(name).strip()
    if text in METRES:  # exact case first: Mm is a megametre, mm a millimetre
        return text
    key = text.lower()
    if key in METRES:
        return key
    if key in ALIASES:
        return ALIASES[key]
    known = ", ".join(METRES)
    raise ValueError(f"unknown length unit {name!r}; known: {known} (or their full names)")


def scale(from_unit: str, to_unit: str) -> float:
    """Factor turning lengths in ``from_unit`` into lengths in ``to_unit``."""
    a, b = METRES[unit_name(from_unit)], METRES[unit_name(to_unit)]
    if a == b:
        return 1.0
    ratio = a / b
    rounded = round(ratio, 9)  # 0.0254 / 0.001 is 25.400000000000002 in binary
    return rounded if rounded and abs(rounded - ratio) <= 1e-12 * ratio else ratio


def report_unit(declared: Iterable[str | None], units: str | None = None) -> str:
    """The unit every length is reported in (see the module docstring for the rule).

    Parameters
    ----------
    declared : iterable of str or None
        The unit each input file declares, None for a file that declares none.
    units : str, optional
        The caller's unit: of undeclared files, and of the report.
    """
    if units is not None:
        return unit_name(units)
    names = [None if d is None else unit_name(d) for d in declared]
    if names and None not in names and len(set(names)) == 1:
        return names[0]
    return DEFAULT_UNIT


# ---------------------------------------------------------------------------------------------
# A file's unit, given by the user


@dataclass(frozen=True)
class UnitRule:
    """The unit of the input files a path or glob names (``--units FILE=UNIT``, ``[units]``).

    Attributes
    ----------
    pattern : str
        A file's path or a shell glob (``fnmatch``: case-sensitive, ``*`` also crosses ``/``).
    unit : str
        A canonical unit name (a key of ``METRES``).
    base : str or None
        The folder a relative ``pattern`` is relative to: the configuration file's; None: the
        working directory (a pattern from the command line).
    source : str or None
        The configuration file the rule comes from; None: the command line (or the Python API).
    """

    pattern: str
    unit: str
    base: str | None = None
    source: str | None = None

    def matches(self, path: str, names: Sequence[str] | None = None) -> bool:
        """Whether the input file ``path`` (as meshcheck names it) is one this rule names.

        A file is named by its path as given, its absolute path or its real path (links
        resolved): ``names``, computed when not given (``file_names``). The pattern, made
        absolute against ``base`` (or the working directory), is matched as a glob against each;
        a pattern that is a path to the same file, or to a directory above it, matches too.

        Examples
        --------
        >>> UnitRule("cad/*.glb", "mm").matches("cad/sub/engine.glb")
        True
        >>> UnitRule("engine.glb", "mm", base="/proj").matches("/proj/engine.glb")
        True
        """
        names = file_names(path) if names is None else names
        pattern = self.pattern
        if self.base is not None:
            pattern = os.path.join(self.base, pattern)  # unchanged when the pattern is absolute
        patterns = {os.path.abspath(pattern)} | ({pattern} if self.base is None else set())
        if any(fnmatch.fnmatchcase(n, p) for n in names for p in patterns):
            return True
        real = os.path.realpath(pattern)
        return real == names[-1] or names[-1].startswith(os.path.join(real, ""))


def file_names(path: str) -> tuple[str, str, str]:
    """The names a ``UnitRule`` matches a file by: as given, absolute, real (last)."""
    return path, os.path.abspath(path), os.path.realpath(path)


def unit_rule(text: str) -> UnitRule:
    """A command-line ``FILE=UNIT`` as a ``UnitRule`` (split at the last ``=``: no unit has one).

    Raises
    ------
    ValueError
        Not ``FILE=UNIT``, or an unknown unit.

    Examples
    --------
    >>> unit_rule("cad/engine.glb=millimetre")
    UnitRule(pattern='cad/engine.glb', unit='mm', base=None, source=None)
    """
    pattern, sep, unit = str(text).rpartition("=")
    if not sep or not pattern or not unit.strip():
        raise ValueError(f"{text!r} is not FILE=UNIT (e.g. engine.glb=mm)")
    return UnitRule(pattern, unit_name(unit))


def given_units(paths: Sequence[str], rules: Sequence[UnitRule]) -> dict[str, str]:
    """The unit the user gave each of ``paths`` that a rule names: the last matching rule wins
    (configuration rules come first, the command line's after them).

    Returns
    -------
    dict
        Path -> canonical unit, for the paths some rule names.
    """
    out: dict[str, str] = {}
    if not rules:  # nothing to match (resolving every path's real name costs a system call)
        return out
    for path in paths:
        names = file_names(path)
        for rule in rules:
            if rule.matches(path, names):
                out[path] = rule.unit
    return out


def unmatched_rules(paths: Sequence[str], rules: Sequence[UnitRule]) -> list[UnitRule]:
    """The rules that name none of ``paths``, in order."""
    if not rules:
        return []
    names = [file_names(path) for path in paths]
    return [r for r in rules if not any(r.matches(p, n) for p, n in zip(paths, names, strict=True))]
