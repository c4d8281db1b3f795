"""Two exact solids -> their verdict: OpenCASCADE's distance, boolean and section (no I/O).

The decision ``verify.brep`` makes for each pair of STEP solids, on the solids themselves (see
its docstring for the rules): ``decide`` on two placed shapes, ``decide_pair`` on two products
and their relative placement (the verdict in the first product's frame), ``brep_task`` for a
worker, which reads each product once from its BRep text. This module imports OpenCASCADE and
numpy only, so a worker that decides solids starts in the time OpenCASCADE takes to load.
"""

from __future__ import annotations

import dataclasses
import functools
import heapq
import io
import math

import numpy as np

from ..results import Location, PairVerdict, Solid, Verdict
from . import volumes

#: Points of the shared solid's surface a ball is grown from, the largest facets first.
BALL_SEEDS = 24
#: The shared solid of an interference is drawn (reports, export) from a tessellation this
#: fraction of its box diagonal from its faces.
SOLID_DEFLECTION = 2e-3
#: The key of a process's solids (read from their BRep text) in a task's store.
SHAPES = ("brep", "shapes")
#: How much farther than the bound on two solids' distance a face's box may be and the face
#: still be searched for its solutions (``_boundary_distance``): well above the 1e-7 within
#: which ``BRepExtrema`` counts a solution.
NEAR_MARGIN = 1e-5
#: Why a pair is not decided when a product is not a closed solid.
NOT_ONE_SOLID = "the part is not one closed solid of its file"


class Undecided(Exception):
    """The pair cannot be decided on the B-rep; the message says why."""


def brep_task(store: dict, item: tuple) -> PairVerdict | str:
    """Decide one pair in a worker: ``item`` is ``(product_a, product_b, relative, tolerance,
    clearance, may_overlap)``, the products naming BRep texts in ``store`` (read once per
    process); the verdict is in the first product's frame, mm, or a string saying why there is
    none."""
    product_a, product_b, relative, tolerance, clearance, may_overlap = item
    try:
        return decide_pair(
            _shape(store, product_a),
            _shape(store, product_b),
            relative,
            tolerance=tolerance,
            clearance=clearance,
            may_overlap=may_overlap,
        )
    except Undecided as exc:
        return str(exc)


def _shape(store: dict, product) -> object:
    """The product's solid from its BRep text in ``store``, read once per process, its
    analytic B-spline faces and edges rebuilt on planes, cylinders, circles and lines
    (``analytic.analytic``: the same solid, intersected at their speed)."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    from .analytic import analytic

    memo = store.setdefault(SHAPES, {})
    if product not in memo:
        shape = TopoDS_Shape()
        BRepTools.Read_s(shape, io.BytesIO(store[product]), BRep_Builder())
        memo[product] = analytic(shape)
    return memo[product]


def decide_pair(
    product_a,
    product_b,
    relative: np.ndarray,
    *,
    tolerance: float,
    clearance: float | None,
    may_overlap: bool = True,
) -> PairVerdict:
    """The verdict of one pair of solids, decided in the first one's frame.

    Parameters
    ----------
    product_a, product_b : OCP.TopoDS.TopoDS_Shape
        The two products, each in its own frame, mm.
    relative : (4, 4) float64
        ``product_b``'s placement in ``product_a``'s frame (``relative_placement``), mm.
    tolerance : float
        mm.
    clearance : float, optional
        mm.
    may_overlap : bool
        False when the solids are known to be apart (the meshes stay farther apart than their
        deflections): the distance alone decides, no boolean is made.

    Returns
    -------
    PairVerdict
        In ``product_a``'s frame, mm (``to_world`` places it).

    Raises
    ------
    Undecided
        The solids are not closed, the placement is not rigid, or OpenCASCADE failed.
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.Standard import Standard_Failure

    for product in (product_a, product_b):
        if not is_closed_solid(product):
            raise Undecided(NOT_ONE_SOLID)
    try:
        moved = BRepBuilderAPI_Copy(product_b, True, False).Shape().Moved(_location(relative))
        verdict = decide(
            product_a, moved, tolerance=tolerance, clearance=clearance, may_overlap=may_overlap
        )
    except Standard_Failure as exc:
        raise Undecided(f"OpenCASCADE failed ({type(exc).__name__})") from None
    return _to_fields(verdict)


def _location(matrix: np.ndarray):
    """A TopLoc_Location of a rigid (4, 4) transform."""
    from OCP.gp import gp_Trsf
    from OCP.TopLoc import TopLoc_Location

    m = np.asarray(matrix, dtype=np.float64)
    if not np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9):
        raise Undecided("its placement is not a rigid motion")
    trsf = gp_Trsf()
    trsf.SetValues(*(float(x) for x in m[:3].ravel()))
    return TopLoc_Location(trsf)


# ---------------------------------------------------------------------------------------------
# The solids (millimetres): OpenCASCADE only, no I/O


@dataclasses.dataclass(frozen=True)
class BrepVerdict:
    """What the exact solids say about a pair; lengths in their unit.

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
        Interference: the shared solid's centre of mass and box. Touching and clearance: the box
        of the closest points and its centre.
    closest : ((3,) float64, (3,) float64) or None
        Clearance: the two closest points, on the first solid and on the second.
    solid : (vertices (n, 3) float64, faces (m, 3) int64) or None
        Interference: a tessellation of the shared solid (``SOLID_DEFLECTION``), to draw.
    """

    status: Verdict
    distance: float
    depth: float | None
    volume: float
    centroid: np.ndarray | None = None
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    closest: tuple[np.ndarray, np.ndarray] | None = None
    solid: tuple[np.ndarray, np.ndarray] | None = None


def decide(
    shape_a,
    shape_b,
    *,
    tolerance: float,
    clearance: float | None = None,
    may_overlap: bool = True,
) -> BrepVerdict:
    """The verdict of two exact solids (see the module docstring), lengths in their unit.

    Parameters
    ----------
    shape_a, shape_b : OCP.TopoDS.TopoDS_Shape
        Closed solids, placed, in one frame; neither is modified.
    tolerance : float
        Overlaps thinner and gaps narrower than this are touching.
    clearance : float, optional
        Gaps up to this are ``clearance``; farther is ``clear``.
    may_overlap : bool
        True: the boolean comes first, and when the shared solid has volume the distance is 0
        without ``BRepExtrema``. False (the caller knows the solids apart): the distance comes
        first, and the boolean only when it is within ``tolerance``. The verdict is the same
        either way; a touching pair is located at the shared sliver's box in the first case.

    Returns
    -------
    BrepVerdict

    Raises
    ------
    Undecided
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
    >>> v = decide(a, b.Moved(_shift(0.5)), tolerance=1e-3, clearance=0.5, may_overlap=False)
    >>> str(v.status), round(v.distance, 9)
    ('clearance', 0.2)
    """
    meeting, volume, points = None, 0.0, None
    if may_overlap:
        meeting = _Intersection(shape_a, shape_b)
        volume = max(volumes.volume(meeting.shared), 0.0)
    if volume > 0.0:
        distance = 0.0  # they share volume: no distance to compute
    elif meeting is not None and _meets_within(meeting.section, tolerance):
        distance = 0.0  # the boundaries meet (within their own tolerances, at most ``tolerance``)
    else:  # no shared volume (the boolean says so, or the caller knows them apart)
        distance, points = _boundary_distance(shape_a, shape_b, may_nest=not may_overlap)
    if distance > tolerance:
        if clearance is not None and distance <= clearance:
            centre, lower, upper = _box_of(points)
            return BrepVerdict(
                Verdict.CLEARANCE, distance, None, 0.0, centre, lower, upper, closest=points[0]
            )
        return BrepVerdict(Verdict.CLEAR, distance, None, 0.0)
    if meeting is None:
        meeting = _Intersection(shape_a, shape_b)
        volume = max(volumes.volume(meeting.shared), 0.0)
    shared = meeting.shared
    if volume > math.pi / 6.0 * tolerance**3:
        depth = _largest_ball(shared)
        if depth > tolerance or _thickness_bound(shared) > tolerance:
            centroid, lower, upper = _placement_of(shared)
            return BrepVerdict(
                Verdict.INTERFERENCE,
                0.0,
                depth,
                volume,
                centroid,
                lower,
                upper,
                solid=_tessellation(shared),
            )
    if points is None and not _has_vertices(meeting.section):  # a sliver no boundary cuts
        _, points = _distance(shape_a, shape_b)
    if points is None:
        lower, upper = _box(meeting.section)
        centre = 0.5 * (lower + upper)
    else:
        centre, lower, upper = _box_of(points)
    return BrepVerdict(Verdict.TOUCHING, distance, None, volume, centre, lower, upper)


def _shift(dx: float):
    """A TopLoc_Location moving by ``dx`` along x (for the examples)."""
    return _location(np.array([[1, 0, 0, dx], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))


def _to_fields(v: BrepVerdict) -> PairVerdict:
    """A verdict as every stage after verify reads one (``results.PairVerdict``)."""
    interferes = v.status == Verdict.INTERFERENCE
    location = None if v.centroid is None else Location(v.centroid, v.lower, v.upper)
    solid = None if v.solid is None or not len(v.solid[1]) else Solid(*v.solid)
    return PairVerdict(
        v.status,
        0.0 if interferes else v.distance,
        depth=v.depth if interferes else None,
        volume=v.volume if interferes else None,
        location=location,
        solid=solid,
        closest=v.closest if v.status == Verdict.CLEARANCE else None,
    )


def is_closed_solid(shape) -> bool:
    """Whether ``shape`` holds solids, each bounded by closed shells (OpenCASCADE's check of
    the topology: every edge of a shell shared by two of its faces)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer

    solids = _solids(shape)
    for solid in solids:
        explorer, shells = TopExp_Explorer(solid, TopAbs_SHELL), 0
        while explorer.More():
            if not BRep_Tool.IsClosed_s(explorer.Current()):
                return False
            shells += 1
            explorer.Next()
        if not shells:
            return False
    return bool(solids)


class _Intersection:
    """One OpenCASCADE intersection of two solids (one thread, the arguments left untouched):
    the shared solid (boolean common) at once, the section of their boundaries when asked, from
    the same intersection."""

    def __init__(self, shape_a, shape_b):
        from OCP.BOPAlgo import BOPAlgo_PaveFiller
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
        from OCP.OCP.collections import List_TopoDS_Shape

        arguments = List_TopoDS_Shape()
        arguments.Append(shape_a)
        arguments.Append(shape_b)
        self.filler = BOPAlgo_PaveFiller()
        self.filler.SetArguments(arguments)
        self.filler.SetRunParallel(False)
        self.filler.SetNonDestructive(True)
        self.filler.Perform()
        if self.filler.HasErrors():
            raise Undecided("OpenCASCADE's boolean intersection failed")
        self.shapes = (shape_a, shape_b)
        common = BRepAlgoAPI_Common(shape_a, shape_b, self.filler)
        if not common.IsDone():
            raise Undecided("OpenCASCADE's boolean common failed")
        self.shared = common.Shape()

    @functools.cached_property
    def section(self):
        """The section of the two boundaries."""
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Section

        section = BRepAlgoAPI_Section(*self.shapes, self.filler)
        if not section.IsDone():
            raise Undecided("OpenCASCADE's boolean section failed")
        return section.Shape()


def _meets_within(section, tolerance: float) -> bool:
    """Whether a section of two boundaries has an edge or a vertex that lies on both within
    ``tolerance`` (OpenCASCADE's tolerance of it): a point of it is then on both boundaries, so
    the solids are at most ``tolerance`` apart. (The vertices where a section ends on tangent
    faces can carry a far larger tolerance than its edges; one element suffices.)"""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    for kind, cast in ((TopAbs_EDGE, TopoDS.Edge), (TopAbs_VERTEX, TopoDS.Vertex)):
        explorer = TopExp_Explorer(section, kind)
        while explorer.More():
            if BRep_Tool.Tolerance_s(cast(explorer.Current())) <= tolerance:
                return True
            explorer.Next()
    return False


def _has_vertices(shape) -> bool:
    from OCP.TopAbs import TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer

    return TopExp_Explorer(shape, TopAbs_VERTEX).More()


def _placement_of(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre of mass and bounding box of a solid."""
    return (volumes.centre_of_mass(shape), *_box(shape))


def _box(shape) -> tuple[np.ndarray, np.ndarray]:
    """A shape's exact bounding box (not enlarged by its tessellation): lower, upper corner."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)
    return np.array(box.CornerMin().Coord()), np.array(box.CornerMax().Coord())


def _box_of(points: list[tuple[np.ndarray, np.ndarray]]):
    """Centre and box of the closest points."""
    every = np.array([p for pair in points for p in pair], dtype=np.float64)
    lower, upper = every.min(axis=0), every.max(axis=0)
    return 0.5 * (lower + upper), lower, upper


def _distance(shape_a, shape_b) -> tuple[float, list[tuple[np.ndarray, np.ndarray]]]:
    """Distance between two solids (0 when one holds the other) and its solutions' points."""
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    extrema = BRepExtrema_DistShapeShape(shape_a, shape_b)
    if not extrema.IsDone() or extrema.NbSolution() == 0:
        raise Undecided("OpenCASCADE's distance failed")
    points = [
        (np.array(extrema.PointOnShape1(k).Coord()), np.array(extrema.PointOnShape2(k).Coord()))
        for k in range(1, extrema.NbSolution() + 1)
    ]
    return float(extrema.Value()), points


def _boundary_distance(
    shape_a, shape_b, *, may_nest: bool = True
) -> tuple[float, list[tuple[np.ndarray, np.ndarray]]]:
    """``_distance`` of two solids that share no volume, on the faces that can hold its
    solutions only: the same distance and solutions, found among fewer faces (a screw near its
    hole's wall: the few faces of each that face the other).

    First a bound on the distance: the nearest two vertices, or the nearest farthest points of
    two faces' boxes. A face is kept when its box comes within the bound (and ``NEAR_MARGIN``)
    of a box of the other solid's faces: any pair of faces not both kept is farther apart than
    that, so when the kept faces' distance is within the bound it is the solids' distance, and
    every solution (``BRepExtrema``'s, within 1e-7 of it) is among them. Otherwise (a vertex
    off its faces by its tolerance) that distance is the bound, and the faces are kept again.

    ``may_nest``: no boolean has said that the solids share no volume, so one may hold the
    other (the caller's screen would be wrong). When one's box holds the other's and a vertex
    of the inner one is not outside the outer one, the whole ``_distance`` decides (0 for a
    solid inside the other)."""
    faces_a, lower_a, upper_a = _face_boxes(shape_a)
    faces_b, lower_b, upper_b = _face_boxes(shape_b)
    if not faces_a or not faces_b:
        return _distance(shape_a, shape_b)
    points_a, points_b = _vertex_points(shape_a), _vertex_points(shape_b)
    # A solid's box is its faces' boxes together.
    boxes = ((lower_a.min(axis=0), upper_a.max(axis=0)), (lower_b.min(axis=0), upper_b.max(axis=0)))
    if may_nest and _may_hold((shape_a, shape_b), boxes, (points_a, points_b)):
        return _distance(shape_a, shape_b)
    bound = min(
        _nearest_points(points_a, points_b), _nearest_farthest(lower_a, upper_a, lower_b, upper_b)
    )
    for _ in range(2):
        kept_a, kept_b = _near_boxes(lower_a, upper_a, lower_b, upper_b, bound + NEAR_MARGIN)
        if kept_a.all() and kept_b.all():
            break
        distance, points = _distance(_compound(faces_a, kept_a), _compound(faces_b, kept_b))
        if distance <= bound:
            return distance, points
        bound = distance
    return _distance(shape_a, shape_b)


def _face_boxes(shape) -> tuple[list, np.ndarray, np.ndarray]:
    """The faces of ``shape`` and their boxes' lower and upper corners ((n, 3) each), boxes
    that hold them (enlarged by their tolerances)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.TopAbs import TopAbs_FACE

    faces = _sub_shapes(shape, TopAbs_FACE)
    corners = np.empty((len(faces), 6))
    for i, face in enumerate(faces):
        box = Bnd_Box()
        BRepBndLib.Add_s(face, box, False)
        if box.IsVoid():  # no geometry to bound: kept, as if it were everywhere
            corners[i] = (-math.inf,) * 3 + (math.inf,) * 3
        else:
            corners[i] = (*box.CornerMin().Coord(), *box.CornerMax().Coord())
    return faces, corners[:, :3], corners[:, 3:]


def _sub_shapes(shape, kind) -> list:
    """The distinct sub-shapes of ``shape`` of one kind (``TopAbs_FACE``, ``TopAbs_VERTEX``)."""
    from OCP.OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as Found
    from OCP.TopExp import TopExp

    found = Found()
    TopExp.MapShapes_s(shape, kind, found)
    return [found.FindKey(i) for i in range(1, found.Extent() + 1)]


def _row_blocks(rows: int, columns: int):
    """Slices of ``rows`` whose blocks of ``columns`` boxes or points stay small."""
    step = max(1, (1 << 20) // max(columns, 1))
    return (slice(i, i + step) for i in range(0, rows, step))


def _near_boxes(lower_a, upper_a, lower_b, upper_b, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Which boxes of ``a`` come within ``reach`` of a box of ``b``, and which of ``b`` do."""
    kept_a = np.zeros(len(lower_a), dtype=bool)
    kept_b = np.zeros(len(lower_b), dtype=bool)
    for rows in _row_blocks(len(lower_a), len(lower_b)):
        gaps = np.maximum(
            np.maximum(lower_b[None] - upper_a[rows, None], lower_a[rows, None] - upper_b[None]),
            0.0,
        )
        near = np.einsum("ijk,ijk->ij", gaps, gaps) <= reach * reach
        kept_a[rows] = near.any(axis=1)
        kept_b |= near.any(axis=0)
    return kept_a, kept_b


def _nearest_farthest(lower_a, upper_a, lower_b, upper_b) -> float:
    """The least, over pairs of boxes, of the farthest two points of the two: no two faces in
    those boxes are farther apart, so the solids are not."""
    least = math.inf
    for rows in _row_blocks(len(lower_a), len(lower_b)):
        spans = np.maximum(
            np.abs(upper_b[None] - lower_a[rows, None]), np.abs(upper_a[rows, None] - lower_b[None])
        )
        least = min(least, float(np.einsum("ijk,ijk->ij", spans, spans).min()))
    return math.sqrt(least)


def _nearest_points(a: np.ndarray, b: np.ndarray) -> float:
    """The distance of the nearest two points of two sets ((n, 3) each; inf when one is
    empty)."""
    least = math.inf
    for rows in _row_blocks(len(a), len(b)):
        gaps = a[rows, None] - b[None]
        least = min(least, float(np.einsum("ijk,ijk->ij", gaps, gaps).min(initial=math.inf)))
    return math.sqrt(least)


def _vertex_points(shape) -> np.ndarray:
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_VERTEX
    from OCP.TopoDS import TopoDS

    vertices = _sub_shapes(shape, TopAbs_VERTEX)
    return np.array(
        [BRep_Tool.Pnt_s(TopoDS.Vertex(v)).Coord() for v in vertices], dtype=np.float64
    ).reshape(-1, 3)


def _compound(faces: list, kept: np.ndarray):
    """The ``kept`` faces, in their order, as one compound shape."""
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    compound, builder = TopoDS_Compound(), BRep_Builder()
    builder.MakeCompound(compound)
    for face in np.flatnonzero(kept):
        builder.Add(compound, faces[face])
    return compound


def _may_hold(shapes: tuple, boxes: tuple, points: tuple) -> bool:
    """Whether one of two solids may hold the other: its box holds the other's, and a vertex of
    the other is not outside it (or the other has none). ``boxes``: each solid's (lower,
    upper); ``points``: each one's vertices, (n, 3)."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.TopAbs import TopAbs_OUT

    (lower_a, upper_a), (lower_b, upper_b) = boxes
    # Boxes enlarged by the faces' tolerances: a solid inside the other may poke out by those.
    slack = 1e-3 * max(np.linalg.norm(upper_a - lower_a), np.linalg.norm(upper_b - lower_b))
    for outer, inner, holds in (
        (0, 1, (lower_a <= lower_b + slack).all() & (upper_b <= upper_a + slack).all()),
        (1, 0, (lower_b <= lower_a + slack).all() & (upper_a <= upper_b + slack).all()),
    ):
        if not holds:
            continue
        if not len(points[inner]):  # nothing to classify
            return True
        classifier = BRepClass3d_SolidClassifier(shapes[outer])
        classifier.Perform(_pnt(points[inner][0]), 1e-9)
        if classifier.State() != TopAbs_OUT:
            return True
    return False


def _tessellation(shape) -> tuple[np.ndarray, np.ndarray]:
    """A tessellation of a solid, ``SOLID_DEFLECTION`` of its size from its faces, to draw."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    from ..load.step.tessellate import triangulation_arrays

    shape = _meshed(shape, max(SOLID_DEFLECTION * _diagonal(shape), 1e-9))
    vertices, faces, offset = [np.zeros((0, 3))], [np.zeros((0, 3), dtype=np.int64)], 0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        location = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, location)
        if tri is None:
            continue
        nodes, triangles = triangulation_arrays(tri, location)
        if face.Orientation() == TopAbs_REVERSED:
            triangles = triangles[:, ::-1]
        vertices.append(nodes)
        faces.append(triangles - 1 + offset)
        offset += len(nodes)
    return np.concatenate(vertices), np.concatenate(faces)


def _meshed(shape, deflection: float):
    """A copy of ``shape`` (its geometry shared) meshed afresh at ``deflection``.

    A shared solid's faces can be its arguments' own faces, and a face keeps the finest
    triangulation any call gave it: meshing them in place would make one pair's seeds and
    drawing depend on the pairs decided before it in the same process (so on ``-j``)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    copy = BRepBuilderAPI_Copy(shape, False, False).Shape()
    BRepMesh_IncrementalMesh(copy, deflection, False, 0.5, False)
    return copy


def _diagonal(shape) -> float:
    """Diagonal of a shape's bounding box (0 for an empty shape)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)
    return 0.0 if box.IsVoid() else float(box.CornerMin().Distance(box.CornerMax()))


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
        ball = 2.0 * (3.0 * max(volumes.volume(solid), 0.0) / (4.0 * math.pi)) ** (1.0 / 3.0)
        bound = max(bound, min(side, ball))
    return bound


def _largest_ball(shape) -> float:
    """Diameter of the largest of a few balls exhibited inside ``shape`` (0 when none).

    For each seed (the centroids of a coarse tessellation's largest facets), a ray goes from the
    seed into the solid along the facet's inward normal; the midpoint between the seed and where
    the ray leaves is a candidate centre, with the exact distance from it to the solid's surface
    as its radius; a ball whose centre OpenCASCADE classifies inside is inside the solid, so the
    largest of them is a lower bound on its depth.

    Classifying a point against B-spline faces costs several distances to the surface (35 ms
    against 7 ms in a screw thread's shared solid), so not every candidate is classified: the
    rays are measured longest first (a diameter is at most its ray's length), the largest ball
    measured is classified once no ray left can beat it, and the first one inside is the
    largest inside, the same as classifying them all.
    """
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector
    from OCP.TopAbs import TopAbs_IN

    best = 0.0
    for solid in _solids(shape):
        intersector = IntCurvesFace_ShapeIntersector()
        intersector.Load(solid, 1e-9)
        rays = []  # (exit_at, seed order, centre), longest first
        for order, (point, inward) in enumerate(_seeds(solid)):
            exit_at = _ray_exit(intersector, point, inward)
            # The centre is exit_at / 2 from its seed, a point of the surface: its diameter is
            # at most exit_at, so a ray no longer than the best ball cannot beat it.
            if exit_at is not None and exit_at > best:
                rays.append((exit_at, order, point + 0.5 * exit_at * inward))
        rays.sort(key=lambda ray: (-ray[0], ray[1]))
        measured: list = []  # heap of (-diameter, seed order, centre)
        classifier, k = None, 0
        while True:  # balls largest first: measure rays while one may hold a larger ball
            while k < len(rays) and (not measured or -measured[0][0] < rays[k][0]):
                _, order, centre = rays[k]
                heapq.heappush(
                    measured, (-2.0 * _distance_to_surface(solid, centre), order, centre)
                )
                k += 1
            if not measured or -measured[0][0] <= best:
                break
            diameter, _, centre = heapq.heappop(measured)
            if classifier is None:
                classifier = BRepClass3d_SolidClassifier(solid)
            classifier.Perform(_pnt(centre), 1e-12)
            if classifier.State() == TopAbs_IN:
                best = -diameter
                break
    return best


def _seeds(solid) -> list[tuple[np.ndarray, np.ndarray]]:
    """(point, inward unit normal) on the solid's faces, at the parameters of the centroids of a
    coarse mesh's largest facets: points of the exact surface, normals of the exact surface."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    solid = _meshed(solid, max(_diagonal(solid) * 1e-2, 1e-9))
    meshed = []  # (face, triangulation, (t, 3) node indices, (t,) areas), every face
    explorer = TopExp_Explorer(solid, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
        if tri is None or not tri.HasUVNodes() or tri.NbTriangles() == 0:
            continue
        xyz = np.array([tri.Node(k).Coord() for k in range(1, tri.NbNodes() + 1)])
        idx = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)]) - 1
        corners = xyz[idx]
        area = np.linalg.norm(
            np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
        )
        meshed.append((face, tri, idx, area))
    if not meshed:
        return []
    # Only the largest facets can be seeds: those within a hair of the k-th largest area (ties
    # included) are measured exactly, one at a time; k grows while degenerate facets leave
    # fewer than BALL_SEEDS.
    every = np.sort(np.concatenate([m[3] for m in meshed]))[::-1]
    count = BALL_SEEDS
    while True:
        least = every[min(count, len(every)) - 1] * (1.0 - 1e-9)
        facets = _facets(meshed, least)
        if len(facets) >= BALL_SEEDS or count >= len(every):
            break
        count *= 4
    facets.sort(key=lambda f: (-f[0], tuple(f[1])))
    return [(p, n) for _, p, n in facets[:BALL_SEEDS]]


def _facets(meshed, least: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """(area, point, inward unit normal) of the facets of area ``least`` or more: the surface's
    point and normal at the parameters of the facet's centroid."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.gp import gp_Pnt, gp_Vec
    from OCP.TopAbs import TopAbs_REVERSED

    facets = []
    for face, tri, idx, areas in meshed:
        surface = BRepAdaptor_Surface(face)
        sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
        for i in np.flatnonzero(areas >= least):
            nodes = [int(k) + 1 for k in idx[i]]
            uv = np.mean([tri.UVNode(k).Coord() for k in nodes], axis=0)
            xyz = np.array([tri.Node(k).Coord() for k in nodes])
            area = float(np.linalg.norm(np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])))
            point, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            surface.D1(float(uv[0]), float(uv[1]), point, du, dv)
            normal = np.cross(du.Coord(), dv.Coord())
            length = float(np.linalg.norm(normal))
            if area > 0 and length > 0:
                facets.append((area, np.array(point.Coord()), -sign * normal / length))
    return facets


def _ray_exit(intersector, point: np.ndarray, direction: np.ndarray) -> float | None:
    """Distance along ``direction`` from ``point`` (on the surface) to where the ray meets the
    surface again, or None; ``intersector`` is an ``IntCurvesFace_ShapeIntersector`` loaded
    with the solid."""
    from OCP.gp import gp_Dir, gp_Lin

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
