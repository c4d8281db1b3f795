"""The one touching-tolerance rule: how far apart two surfaces may be and still touch.

Overlaps and gaps below a pair's tolerance count as touching. When the user gives no tolerance,
each pair gets its own, from the two parts alone, never from other parts (a far, large part must
not loosen the verdict on a small pair):

``max(TOLERANCE_FRACTION * smaller diagonal, FLOAT32_ULPS * float32_spacing(largest magnitude))``

where the magnitude term (the float32 floor) only counts for parts whose coordinates went through
float32. Whatever the rule gives, a pair's tolerance is never below the sum of its two parts'
tessellation deflections (STEP parts: their triangles lie up to the deflection from the solid).

The float32 spacing (a unit in the last place) is a power of two, the same for every magnitude
between two powers of two: copies of one pair placed anywhere in that range get one tolerance,
so the verify stage decides them as one class (``verify.classes``).

Every stage that needs a tolerance (broad phase, verify, duplicates, patterns, B-rep, sweep) asks
this module; the kernels' own numerical thresholds are in ``geometry.constants``.
"""

from __future__ import annotations

import numpy as np

#: Overlaps and gaps below this fraction of the smaller part's bounding-box diagonal count as
#: touching. CAD exporters round coordinates, so faces modelled as coincident land up to ~1e-6 of
#: a part's size apart; 1e-5 leaves a 10x margin while staying far below any clearance an
#: engineer specifies (1 um on a 100 mm part).
TOLERANCE_FRACTION = 1e-5

#: ... and, for parts whose coordinates went through float32 (``Body.is_float32``: binary STL,
#: float PLY, glTF, STEP), never below ``FLOAT32_ULPS`` float32 units in the last place at the
#: largest such coordinate x of the pair (``float32_spacing``): a float32 coordinate at x is only
#: known to half a unit, so two coincident faces of two files can be a unit apart for each
#: vertex, and eight leave a margin of eight. Coordinates read in double (ASCII STL, OBJ, 3MF...)
#: get no such floor.
FLOAT32_ULPS = 8.0

#: Two closed shells of one part whose overlap is no thicker than this fraction of their size
#: (the diagonal of their larger extents) only touch, and draw no "shells overlap" warning
#: (``verify.shells``). Shells a CAD exporter wrote face to face land up to ~1e-7 of the size
#: apart (float32 STL); 1e-6 keeps a 10x margin, and stays under ``TOLERANCE_FRACTION``, so
#: shells overlapping by what would be an interference between two parts are warned about.
SHELL_TOUCH_FRACTION = 1e-6


def part_sizes(
    lower: np.ndarray, upper: np.ndarray, is_float32: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Bounding-box diagonal and float32 magnitude of each part, two ``(n,)`` arrays.

    Parameters
    ----------
    lower, upper : (n, 3) float64
        Each part's axis-aligned bounding box, world coordinates, model units.
    is_float32 : (n,) bool, optional
        Whether each part's coordinates went through float32 (``Body.is_float32``); the
        magnitude of the others is 0, so the float32 floor does not apply to them. Default: all.

    Returns
    -------
    diagonal : (n,) float64
    magnitude : (n,) float64
        The largest absolute coordinate of each float32 part, else 0.
    """
    lower, upper = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    diagonal = np.linalg.norm(upper - lower, axis=1)
    magnitude = np.maximum(np.abs(lower), np.abs(upper)).max(axis=1, initial=0.0)
    if is_float32 is not None:
        magnitude = np.where(np.asarray(is_float32, dtype=bool), magnitude, 0.0)
    return diagonal, magnitude


def float32_spacing(magnitude):
    """The distance between adjacent float32 numbers at ``magnitude`` (a unit in the last
    place): ``2^(k - 23)`` for ``magnitude`` in ``[2^k, 2^(k+1))``, 0 at 0. Floats and arrays.

    Examples
    --------
    >>> [float(float32_spacing(x)) * 2**23 for x in (1.0, 1.999, 2.0, 0.0)]
    [1.0, 1.0, 2.0, 0.0]
    """
    magnitude = np.abs(np.asarray(magnitude, dtype=np.float64))
    _, exponent = np.frexp(magnitude)  # magnitude = m 2^exponent with 0.5 <= m < 1
    return np.where(magnitude > 0.0, np.ldexp(1.0, exponent - 24), 0.0)


def default_tolerance(size, magnitude):
    """The default tolerance for a part (or pair) of this ``size`` and float32 ``magnitude``.

    ``max(TOLERANCE_FRACTION * size, FLOAT32_ULPS * float32_spacing(magnitude))``, and
    ``TOLERANCE_FRACTION`` units where both are 0 (a point at the origin). Works on floats and
    arrays alike.

    Examples
    --------
    >>> float(default_tolerance(10.0, 0.0))
    0.0001
    >>> float(default_tolerance(10.0, 2.0**20)) == 8.0 * 2.0**-23 * 2.0**20
    True
    >>> float(default_tolerance(10.0, 2.0**21 - 1)) == float(default_tolerance(10.0, 2.0**20))
    True
    """
    tol = np.maximum(
        TOLERANCE_FRACTION * np.asarray(size, dtype=np.float64),
        FLOAT32_ULPS * float32_spacing(magnitude),
    )
    return np.where(tol > 0.0, tol, TOLERANCE_FRACTION)


def pair_tolerances(
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    pairs: np.ndarray,
    *,
    tolerance: float | None = None,
    deflection: np.ndarray | None = None,
) -> np.ndarray:
    """The touching tolerance of each pair, model units, ``(k,)`` float64.

    The user's ``tolerance`` when given, else ``default_tolerance`` of the smaller diagonal and
    the larger magnitude; never below the sum of the two parts' ``deflection``.

    Parameters
    ----------
    diagonal, magnitude : (n,) float64
        ``part_sizes`` of the parts.
    pairs : (k, 2) int64
    tolerance : float, optional
        The user's tolerance, model units.
    deflection : (n,) float64, optional
        Each part's tessellation deflection (``Body.deflection``), model units.

    Examples
    --------
    >>> d, m = np.array([100.0, 10.0, 40000.0]), np.array([50.0, 50.0, 50000.0])
    >>> pair_tolerances(d, m, np.array([[0, 1]])).round(9).tolist()
    [0.0001]
    >>> pair_tolerances(d, m, np.array([[0, 1]]), deflection=np.array([0.01, 0.02, 0.0])).tolist()
    [0.03]
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    i, j = pairs[:, 0], pairs[:, 1]
    if tolerance is not None:
        tol = np.full(len(pairs), float(tolerance))
    else:
        tol = default_tolerance(
            np.minimum(diagonal[i], diagonal[j]), np.maximum(magnitude[i], magnitude[j])
        ).astype(np.float64)
    if deflection is not None:
        deflection = np.asarray(deflection, dtype=np.float64)
        tol = np.maximum(tol, deflection[i] + deflection[j])
    return tol


def mesh_tolerance(local: np.ndarray, corner: np.ndarray, *, is_float32: bool) -> float:
    """The default tolerance of one mesh alone, in its own frame's units.

    How far two copies of it may differ and be one geometry (``verify.duplicates``,
    ``verify.patterns``): ``default_tolerance`` of its diagonal and, when its coordinates went
    through float32, of its largest frame coordinate.

    Parameters
    ----------
    local : (n, 3) float64
        The mesh's vertices less ``corner`` (``load.local_geometry``).
    corner : (3,) float64
        The lower corner of its box, frame coordinates.
    is_float32 : bool
        ``Body.is_float32``.
    """
    if not len(local):
        return float(default_tolerance(0.0, 0.0))
    size = float(np.linalg.norm(local.max(axis=0)))
    magnitude = float(np.abs(local + corner).max()) if is_float32 else 0.0
    return float(default_tolerance(size, magnitude))


def largest_pair_tolerance(
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    *,
    tolerance: float | None = None,
    deflection: np.ndarray | None = None,
) -> float:
    """An upper bound of ``pair_tolerances`` over every pair of these parts, model units.

    The broad phase grows the parts' boxes by it, so no pair within its own reach is pruned.
    """
    if tolerance is not None:
        largest = float(tolerance)
    elif len(diagonal):
        largest = float(default_tolerance(np.max(diagonal), np.max(magnitude)))
    else:
        largest = 0.0
    if deflection is not None and len(deflection):
        largest = max(largest, 2.0 * float(np.max(deflection)))
    return largest


__all__ = [
    "FLOAT32_ULPS",
    "SHELL_TOUCH_FRACTION",
    "TOLERANCE_FRACTION",
    "default_tolerance",
    "float32_spacing",
    "largest_pair_tolerance",
    "mesh_tolerance",
    "pair_tolerances",
    "part_sizes",
]
