"""The length unit a STEP file declares, and deflections in OpenCASCADE's millimetres.

OpenCASCADE converts every length to millimetres, whatever the file declares (it understands every
SI prefix and conversion-based unit). ``read_step`` converts back to the length unit the file
declares (its ``GLOBAL_UNIT_ASSIGNED_CONTEXT``, named by ``meshcheck.units``), so that a
millimetre STEP gives millimetres and an inch STEP inches.
"""

from __future__ import annotations

import re
import warnings

from ...errors import MeshcheckWarning
from ...units import METRES, SI_PREFIXES, unit_name

_ENTITY = r"#{}\s*=\s*((?:'(?:[^']|'')*'|[^;'])*);"
_CONTEXT_UNITS = re.compile(r"GLOBAL_UNIT_ASSIGNED_CONTEXT\s*\(\s*\(([#\d\s,]*)\)")
_SI_LENGTH = re.compile(r"SI_UNIT\s*\(\s*(\$|\.[A-Z]+\.)\s*,\s*\.METRE\.\s*\)")
_CONVERSION = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'((?:[^']|'')*)'")


def step_unit(data: bytes, path: str = "") -> str:
    """The length unit a STEP file declares, a key of ``meshcheck.units.METRES``.

    The units a file assigns to its representation contexts (``GLOBAL_UNIT_ASSIGNED_CONTEXT``);
    when contexts disagree (OpenCASCADE converts each), the one most of them use, the first
    in the file on a tie. A file declaring none that is recognised gives ``"mm"`` (what
    OpenCASCADE assumes) with a ``MeshcheckWarning`` naming ``path``.

    Examples
    --------
    >>> step_unit(b"#1=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));"
    ...           b"#2=(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNIT_ASSIGNED_CONTEXT((#1)));")
    'mm'
    """
    unit = declared_unit(data)
    if unit is None:
        warn_no_unit(path)
    return unit or "mm"


def warn_no_unit(path: str) -> None:
    """Warn that ``path`` declares no length unit meshcheck knows (it is read in millimetres)."""
    warnings.warn(
        MeshcheckWarning(f"{path}: declares no length unit meshcheck knows; reading millimetres"),
        stacklevel=3,
    )


def declared_unit(data: bytes) -> str | None:
    """The unit ``step_unit`` describes, or None when the file declares none we know."""
    text = data.decode("latin-1")
    counts: dict[str, int] = {}
    resolved: dict[str, str | None] = {}
    for match in _CONTEXT_UNITS.finditer(text):
        for ref in re.findall(r"#(\d+)", match.group(1)):
            if ref not in resolved:
                resolved[ref] = _length_unit(text, ref)
            if resolved[ref] is not None:
                counts[resolved[ref]] = counts.get(resolved[ref], 0) + 1
    if not counts:
        return None
    return max(counts, key=lambda unit: counts[unit])  # first in the file wins a tie


def _length_unit(text: str, ref: str) -> str | None:
    """The unit name of entity ``#ref`` when it is a length unit we know, else None."""
    match = re.search(_ENTITY.format(ref), text)
    if match is None or "LENGTH_UNIT" not in match.group(1):
        return None
    body = match.group(1)
    conversion = _CONVERSION.search(body)
    if conversion is not None:
        try:
            return unit_name(conversion.group(1).replace("''", "'"))
        except ValueError:
            return None
    si = _SI_LENGTH.search(body)
    if si is not None:
        prefix = si.group(1).strip(".")
        return "m" if prefix == "$" else SI_PREFIXES.get(prefix)
    return None


def deflection_mm(
    deflection: float | None, deflection_unit: str | None, unit: str, real_unit: str | None
) -> tuple[float | None, float]:
    """(the deflection in OpenCASCADE's millimetres or None for the default, OpenCASCADE's
    millimetres per real millimetre): the ratio is not 1 when the user says the file's lengths
    are in ``real_unit``, not the ``unit`` it declares."""
    ratio = 1.0 if real_unit is None else METRES[unit] / METRES[unit_name(real_unit)]
    if deflection is None:
        return None, ratio  # the default, at least DEFAULT_RELATIVE_DEFLECTION of the parts
    given_unit = (real_unit or unit) if deflection_unit is None else deflection_unit
    return float(deflection) * METRES[given_unit] / 1e-3 * ratio, ratio


def mesh_settings(
    data: bytes, deflection: float | None, deflection_unit: str | None, real_unit: str | None
) -> tuple[str | None, str, float | None, float]:
    """What a STEP file is meshed with, from its bytes and ``read_step``'s options: (the unit
    it declares or None, the unit it is read in, the deflection in OpenCASCADE's millimetres or
    None for the default, OpenCASCADE's millimetres per real one: ``deflection_mm``)."""
    declared = declared_unit(data)
    unit = declared or "mm"
    wanted_mm, ratio = deflection_mm(deflection, deflection_unit, unit, real_unit)
    return declared, unit, wanted_mm, ratio
