"""STEP findings near the tolerance -> decided again on the exact solids (OpenCASCADE's B-rep).

Why
---
A STEP part is checked on its tessellation, whose triangles lie up to the deflection inside its
curved faces; so a STEP pair's tolerance is at least the two deflections, and a verdict within a
few tolerances of it says more about the chords than about the parts. A bolt coincident with its
hole (line to line: the CAD common volume is 0) shows overlapping chords a fraction of the
tolerance thick, and a 0.005 mm press fit hides inside a 0.01 mm tolerance. The solids the
triangles came from answer both exactly, so a STEP finding near the tolerance is decided on them:

- ``interference`` with a depth of at most ``NEAR_TOLERANCES`` tolerances (or no depth), every
  ``touching``, and ``clearance`` within ``NEAR_TOLERANCES`` tolerances, when both parts are
  closed STEP solids (``Body.brep``, handed down by the load stage); deeper interference stands
  as the meshes found it (the triangles lie within the deflections of the solids, so no depth
  that far above the tolerance can vanish), and a pair the meshes found clear is more than the
  two deflections apart on the meshes, hence apart on the solids.
- On the solids, with the pair's own tolerance ``t`` (the user's ``--tolerance``, or the one a
  mesh file would get: the deflections no longer enter, the solids are exact):
  ``BRepAlgoAPI_Common`` gives the shared solid and ``GProp`` its volume ``V``;
  ``BRepExtrema_DistShapeShape`` the distance ``d``.

  * A ball of diameter above ``t`` has volume above ``pi/6 t**3``: ``V`` at most that proves the
    shared volume thinner than ``t``; then ``d <= t`` is **touching**, ``t < d <= clearance`` is
    **clearance** (``d``), farther is clear (the finding is dropped).
  * Otherwise a ball is exhibited inside the shared solid (``_largest_ball``: a ray from a point
    of its surface into it, the midpoint classified inside, its radius the exact distance to the
    surface); a diameter above ``t`` is **interference** with that depth and volume ``V``.
  * Otherwise, when every connected piece of the shared solid is provably thinner than ``t``
    (its volume's ball, its box), **touching**; short of a proof, **interference** (the
    rule for meshes, kept).

A pair that cannot be confirmed (OpenCASCADE's boolean fails, a part was ``--split`` into
shells, a solid is open) keeps the tessellation's verdict; when that verdict is touching, a
``MeshcheckWarning`` names the finding and the tolerance that decided it.

Results are deterministic (one thread, no fuzzy value) and cached as pair verdicts are
(``cache.PairCache``: signed with the run's key), keyed by both files' content, the two solids'
names and placements, the tolerance, the clearance, this file and OpenCASCADE's version, so a
warm run gives the same report without reading a STEP document into OpenCASCADE.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import warnings
from collections.abc import Sequence

import numpy as np

from ..cache import PairCache
from ..cache.store import checksum, package_version
from ..errors import InputError, MeshcheckWarning
from ..load import Body
from ..load.files import STEP_EXTENSIONS
from ..results import Finding, Location, PairVerdict, Verdict
from ..settings import Settings
from ..tolerances import pair_tolerances, part_sizes
from ..units import METRES

#: Findings within this many tolerances of it are decided on the B-rep (see the module docstring).
NEAR_TOLERANCES = 4.0
#: Points of the shared solid's surface a ball is grown from, the largest facets first.
BALL_SEEDS = 24
#: Bump when a cached B-rep verdict's meaning changes.
FORMAT_VERSION = 1


@dataclasses.dataclass(frozen=True)
class BrepVerdict:
    """What the exact solids say about a pair; lengths in millimetres.

    Attributes
    ----------
    status : Verdict
    distance : float
        Distance between the solids (0 when they share volume).
    depth : float or None
        Diameter of a ball exhibited inside the shared solid (interference only).
    volume : float
        Volume of the shared solid.
    centroid, lower, upper : (3,) float64 or None
        Centre and box of the shared solid (interference only).
    """

    status: Verdict
    distance: float
    depth: float | None
    volume: float
    centroid: np.ndarray | None = None
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None


def confirm_on_brep(
    bodies: Sequence[Body],
    findings: Sequence[Finding],
    settings: Settings,
    *,
    cache: PairCache | None = None,
) -> list[Finding]:
    """Decide the STEP findings near the tolerance on the exact solids (see the module docstring).

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts.
    findings : sequence of Finding
        The verify stage's findings, sorted.
    settings : Settings
        The run's settings (``tolerance``, ``clearance``).
    cache : cache.PairCache, optional
        The run's pair verdicts, where B-rep verdicts are kept too.

    Returns
    -------
    list of Finding
        The findings, those confirmed replaced by the solids' verdict (dropped when the solids
        are clear), in the same order.
    """
    by_name = {b.name: b for b in bodies}
    out = []
    for finding in findings:
        a, b = by_name[finding.a], by_name[finding.b]
        if not _is_near(finding, a, b):
            out.append(finding)
            continue
        tolerance = _own_tolerance(a, b, settings)
        try:
            verdict = _cached_verdict(a, b, tolerance, settings.clearance, cache)
        except _Unconfirmed as exc:
            _warn_unconfirmed(finding, str(exc))
            out.append(finding)
            continue
        confirmed = _finding(finding, verdict, tolerance, _mm_to(a.units))
        if confirmed is not None:
            out.append(confirmed)
    return out


class _Unconfirmed(Exception):
    """The pair cannot be decided on the B-rep; the message says why."""


def _is_near(finding: Finding, a: Body, b: Body) -> bool:
    """Whether ``finding`` is a STEP pair's verdict within ``NEAR_TOLERANCES`` of its tolerance."""
    if not (_is_step(a) and _is_step(b)) or finding.tolerance is None:
        return False
    near = NEAR_TOLERANCES * finding.tolerance
    if finding.status == Verdict.TOUCHING:
        return True
    if finding.status == Verdict.CLEARANCE:
        return finding.distance <= near
    return finding.depth is None or finding.depth <= near


def _is_step(body: Body) -> bool:
    """A STEP solid whose B-rep is the part (not rescaled by ``--units FILE=UNIT``)."""
    is_step = os.path.splitext(body.path)[1].lower() in STEP_EXTENSIONS
    return is_step and body.deflection > 0 and not body.is_rescaled


def _own_tolerance(a: Body, b: Body, settings: Settings) -> float:
    """The pair's tolerance without the tessellation's share (``tolerances.pair_tolerances``
    without the deflections): the user's, or the default rule."""
    bounds = np.array([_world_bounds(a), _world_bounds(b)])
    diagonal, magnitude = part_sizes(bounds[:, 0], bounds[:, 1], [a.is_float32, b.is_float32])
    pair = np.array([[0, 1]])
    return float(pair_tolerances(diagonal, magnitude, pair, tolerance=settings.tolerance)[0])


def _world_bounds(body: Body) -> np.ndarray:
    return np.asarray(body.world.bounds, dtype=np.float64)


def _mm_to(units: str) -> float:
    """Factor from millimetres (OpenCASCADE's unit) to ``units``."""
    return 1e-3 / METRES[units]


def _node(body: Body) -> str:
    """The solid's node name in its STEP file (``PATH#NODE``)."""
    prefix = f"{body.path}#"
    if not body.name.startswith(prefix):
        raise _Unconfirmed("the part is not one solid of its file")
    return body.name[len(prefix) :]


# ---------------------------------------------------------------------------------------------
# One pair: cache, then the solids


def _cached_verdict(
    a: Body,
    b: Body,
    tolerance: float,
    clearance: float | None,
    cache: PairCache | None,
) -> BrepVerdict:
    """The solids' verdict on ``a`` and ``b`` (millimetres), from the cache when it holds it."""
    to_mm = 1.0 / _mm_to(a.units)
    key = _key(a, b, tolerance, clearance) if cache is not None else ""
    hit = cache.get(key) if cache is not None else None
    if hit is not None:
        return _from_fields(hit)
    verdict = decide(
        _exact_solid(a),
        _exact_solid(b),
        tolerance=tolerance * to_mm,
        clearance=None if clearance is None else clearance * to_mm,
    )
    if cache is not None:
        cache.put(key, _to_fields(verdict))
    return verdict


def _exact_solid(body: Body):
    """The body's solid in its file's B-rep (``Body.brep``), placed, millimetres."""
    if body.brep is None:
        raise _Unconfirmed(_NOT_ONE_SOLID)
    try:
        solids = body.brep.by_node()
    except InputError as exc:
        raise _Unconfirmed(f"its file cannot be read again ({exc.reason})") from None
    node = _node(body)
    if node not in solids or not body.is_closed:
        raise _Unconfirmed(_NOT_ONE_SOLID)
    return solids[node]


_NOT_ONE_SOLID = "the part is not one closed solid of its file"


def _key(a: Body, b: Body, tolerance: float, clearance: float | None) -> str:
    payload = {
        "brep": FORMAT_VERSION,
        "code": _code_version(),
        "parts": [_identity(a), _identity(b)],
        "tolerance": float(tolerance).hex(),
        "clearance": None if clearance is None else float(clearance).hex(),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return checksum(text.encode()).hex()


def _identity(body: Body) -> list[str]:
    """What fixes a solid in the world: its file's content, its node, its placement, the unit."""
    if body.brep is None:
        raise _Unconfirmed(_NOT_ONE_SOLID)
    matrix = np.ascontiguousarray(body.transform, dtype=np.float64).tobytes().hex()
    return [body.brep.digest, _node(body), matrix, body.units]


@functools.cache
def _code_version() -> str:
    """Digest of what computes a B-rep verdict: this file and OpenCASCADE's version."""
    with open(__file__, "rb") as f:
        source = f.read()
    return checksum(source, package_version("cadquery-ocp-novtk", missing="?").encode()).hex()


def _to_fields(v: BrepVerdict) -> PairVerdict:
    """A verdict as the pair cache stores one (``cache.PairCache``: the one verdict type)."""
    location = None if v.centroid is None else Location(v.centroid, v.lower, v.upper)
    return PairVerdict(v.status, v.distance, v.depth, v.volume, location)


def _from_fields(stored: PairVerdict) -> BrepVerdict:
    where = stored.location
    location = (None, None, None) if where is None else (where.centroid, where.lower, where.upper)
    return BrepVerdict(
        stored.status, float(stored.distance), stored.depth, float(stored.volume or 0.0), *location
    )


def _finding(finding: Finding, v: BrepVerdict, tolerance: float, scale: float) -> Finding | None:
    """``finding`` with the solids' verdict ``v`` (millimetres, times ``scale`` to report units);
    None when the solids are clear."""
    if v.status == Verdict.CLEAR:
        return None
    location = finding.location
    if v.centroid is not None:
        location = Location(v.centroid * scale, v.lower * scale, v.upper * scale)
    interferes = v.status == Verdict.INTERFERENCE
    verdict = dataclasses.replace(
        finding.verdict,
        status=v.status,
        distance=0.0 if interferes else v.distance * scale,
        depth=None if v.depth is None or not interferes else v.depth * scale,
        volume=v.volume * scale**3 if interferes else None,
        location=location,
        # The meshes' shared solid is drawn for an interference the solids confirm; a clearance
        # keeps the meshes' closest points. Neither belongs to a verdict the solids changed.
        solid=finding.verdict.solid if interferes else None,
        closest=finding.verdict.closest if v.status == Verdict.CLEARANCE else None,
    )
    return dataclasses.replace(finding, verdict=verdict, tolerance=tolerance)


def _warn_unconfirmed(finding: Finding, reason: str) -> None:
    if finding.status != Verdict.TOUCHING:
        return  # an interference or a clearance the meshes found stands; nothing can hide
    warnings.warn(
        MeshcheckWarning(
            f"{finding.a} and {finding.b}: touching on the tessellation (tolerance "
            f"{finding.tolerance:.3g}, the deflections' sum) but not confirmed on the B-rep: "
            f"{reason}; an interference thinner than that tolerance would not be reported"
        ),
        stacklevel=3,
    )


# ---------------------------------------------------------------------------------------------
# The solids (millimetres): OpenCASCADE only, no I/O


def decide(shape_a, shape_b, *, tolerance: float, clearance: float | None = None) -> BrepVerdict:
    """The verdict of two exact solids (see the module docstring), lengths in their unit.

    Parameters
    ----------
    shape_a, shape_b : OCP.TopoDS.TopoDS_Shape
        Closed solids, placed, in one frame.
    tolerance : float
        Overlaps thinner and gaps narrower than this are touching.
    clearance : float, optional
        Gaps up to this are ``clearance``; farther is ``clear``.

    Returns
    -------
    BrepVerdict

    Raises
    ------
    _Unconfirmed
        OpenCASCADE's boolean or distance failed.

    Examples
    --------
    >>> from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    >>> from OCP.gp import gp_Pnt
    >>> a = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(1, 1, 1)).Shape()
    >>> b = BRepPrimAPI_MakeBox(gp_Pnt(0.7, 0, 0), gp_Pnt(2, 1, 1)).Shape()
    >>> v = decide(a, b, tolerance=1e-3)
    >>> str(v.status), round(v.volume, 9), round(v.depth, 6)
    ('interference', 0.3, 0.3)
    >>> str(decide(a, b.Moved(_shift(0.3)), tolerance=1e-3).status)
    'touching'
    """
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common

    common = BRepAlgoAPI_Common(shape_a, shape_b)
    common.SetRunParallel(False)
    common.Build()
    if not common.IsDone():
        raise _Unconfirmed("OpenCASCADE's boolean common failed")
    shared = common.Shape()
    volume = max(_volume(shared), 0.0)
    if volume > math.pi / 6.0 * tolerance**3:
        depth, ball_bound = _largest_ball(shared), _thickness_bound(shared)
        if depth > tolerance or ball_bound > tolerance:
            centroid, lower, upper = _placement_of(shared)
            return BrepVerdict(Verdict.INTERFERENCE, 0.0, depth, volume, centroid, lower, upper)
    distance = _distance(shape_a, shape_b)
    if distance <= tolerance:
        return BrepVerdict(Verdict.TOUCHING, distance, None, volume)
    if clearance is not None and distance <= clearance:
        return BrepVerdict(Verdict.CLEARANCE, distance, None, 0.0)
    return BrepVerdict(Verdict.CLEAR, distance, None, 0.0)


def _shift(dx: float):
    """A TopLoc_Location moving by ``dx`` along x (for the examples)."""
    from OCP.gp import gp_Trsf, gp_Vec
    from OCP.TopLoc import TopLoc_Location

    trsf = gp_Trsf()
    trsf.SetTranslation(gp_Vec(dx, 0, 0))
    return TopLoc_Location(trsf)


def _volume(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return float(props.Mass())


def _placement_of(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre of mass and bounding box of a solid."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)  # exact, not enlarged by the tessellation
    return (
        np.array(props.CentreOfMass().Coord()),
        np.array(box.CornerMin().Coord()),
        np.array(box.CornerMax().Coord()),
    )


def _distance(shape_a, shape_b) -> float:
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    extrema = BRepExtrema_DistShapeShape(shape_a, shape_b)
    if not extrema.IsDone():
        raise _Unconfirmed("OpenCASCADE's distance failed")
    return float(extrema.Value())


def _solids(shape) -> list:
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out, explorer = [], TopExp_Explorer(shape, TopAbs_SOLID)
    while explorer.More():
        out.append(TopoDS.Solid(explorer.Current()))
        explorer.Next()
    return out


def _thickness_bound(shape) -> float:
    """An upper bound on the diameter of any ball inside ``shape``: per connected solid, the
    ball of its volume and its box's smallest side; the largest of them."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    bound = 0.0
    for solid in _solids(shape):
        box = Bnd_Box()
        BRepBndLib.Add_s(solid, box, False)
        side = min(np.array(box.CornerMax().Coord()) - np.array(box.CornerMin().Coord()))
        ball = 2.0 * (3.0 * max(_volume(solid), 0.0) / (4.0 * math.pi)) ** (1.0 / 3.0)
        bound = max(bound, min(side, ball))
    return bound


def _largest_ball(shape) -> float:
    """Diameter of the largest of a few balls exhibited inside ``shape`` (0 when none).

    For each seed (the centroids of a coarse tessellation's largest facets), a ray goes from the
    seed into the solid along the facet's inward normal; the midpoint between the seed and where
    the ray leaves is kept when OpenCASCADE classifies it inside, with the exact distance from it
    to the solid's surface as the radius. Each ball is inside the solid, so the largest is a
    lower bound on its depth.
    """
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.TopAbs import TopAbs_IN

    best = 0.0
    for solid in _solids(shape):
        classifier = BRepClass3d_SolidClassifier(solid)
        for point, inward in _seeds(solid):
            exit_at = _ray_exit(solid, point, inward)
            if exit_at is None:
                continue
            centre = point + 0.5 * exit_at * inward
            classifier.Perform(_pnt(centre), 1e-12)
            if classifier.State() != TopAbs_IN:
                continue
            best = max(best, 2.0 * _distance_to_surface(solid, centre))
    return best


def _seeds(solid) -> list[tuple[np.ndarray, np.ndarray]]:
    """(point, inward unit normal) on the solid's faces, at the parameters of the centroids of a
    coarse mesh's largest facets: points of the exact surface, normals of the exact surface."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.gp import gp_Pnt, gp_Vec
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    from ..load.step import shape_diagonal

    BRepMesh_IncrementalMesh(solid, max(shape_diagonal(solid) * 1e-2, 1e-9), False, 0.5, False)
    facets = []
    explorer = TopExp_Explorer(solid, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
        if tri is None or not tri.HasUVNodes():
            continue
        surface = BRepAdaptor_Surface(face)
        sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
        for i in range(1, tri.NbTriangles() + 1):
            idx = tri.Triangle(i).Get()
            uv = np.mean([tri.UVNode(k).Coord() for k in idx], axis=0)
            xyz = np.array([tri.Node(k).Coord() for k in idx])
            area = float(np.linalg.norm(np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])))
            point, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            surface.D1(float(uv[0]), float(uv[1]), point, du, dv)
            normal = np.cross(du.Coord(), dv.Coord())
            length = float(np.linalg.norm(normal))
            if area > 0 and length > 0:
                facets.append((area, np.array(point.Coord()), -sign * normal / length))
    facets.sort(key=lambda f: (-f[0], tuple(f[1])))
    return [(p, n) for _, p, n in facets[:BALL_SEEDS]]


def _ray_exit(solid, point: np.ndarray, direction: np.ndarray) -> float | None:
    """Distance along ``direction`` from ``point`` (on the surface) to where the ray meets the
    surface again, or None."""
    from OCP.gp import gp_Dir, gp_Lin
    from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector

    intersector = IntCurvesFace_ShapeIntersector()
    intersector.Load(solid, 1e-9)
    intersector.Perform(gp_Lin(_pnt(point), gp_Dir(*direction)), 0.0, math.inf)
    if not intersector.IsDone():
        return None
    hits = [intersector.WParameter(i) for i in range(1, intersector.NbPnt() + 1)]
    scale = max(1.0, float(np.abs(point).max()))
    hits = [w for w in hits if w > 1e-9 * scale]
    return min(hits) if hits else None


def _distance_to_surface(solid, centre: np.ndarray) -> float:
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer

    vertex = BRepBuilderAPI_MakeVertex(_pnt(centre)).Vertex()
    nearest = math.inf
    explorer = TopExp_Explorer(solid, TopAbs_SHELL)  # the surface, not the solid's inside
    while explorer.More():
        extrema = BRepExtrema_DistShapeShape(vertex, explorer.Current())
        if extrema.IsDone():
            nearest = min(nearest, float(extrema.Value()))
        explorer.Next()
    return 0.0 if not math.isfinite(nearest) else nearest


def _pnt(xyz):
    from OCP.gp import gp_Pnt

    return gp_Pnt(*(float(c) for c in xyz))
