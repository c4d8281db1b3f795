"""OpenCASCADE's solids -> closed triangle meshes, within a deflection of the CAD faces.

``BRepMesh_IncrementalMesh``, one thread per product. Each distinct product is meshed from its
BRep text (``mesh_task``), in this process or, for a large file whose workers loaded OpenCASCADE
while it was read (``PREPARE``), in them too; a small file read ahead (``ahead``) is triangulated
by the worker that read it (``triangulate``) and only welded here (``welded_triangles``). The
same text gives the same triangles wherever it is meshed, so the tessellation does not depend on
``-j``.

The chords of a curved face lie inside it, by at most the linear deflection: a pin in a hole, both
faceted, shows a gap up to one deflection wider (or an overlap up to two deflections shallower)
than the CAD model. The default, ``DEFAULT_DEFLECTION_MM``, keeps a 0.1 mm clearance within
0.01 mm and a 0.2 mm interference within 0.03 mm (tests/test_step.py); the value used is
``StepAssembly.deflection``, in the file's unit.

A deflection is honoured only when it can be with bounded time and memory: it must be at least
``MIN_DEFLECTION_MM`` (ten times OpenCASCADE's own confusion distance; finer triangles would
resolve nothing the B-rep holds) and at least ``MIN_RELATIVE_DEFLECTION`` of the largest solid's
diagonal, and the triangles it would make, estimated from a coarse tessellation before the fine
one, must fit the budget. Otherwise the file is refused with the deflection that would fit.

Faces are tessellated one by one: each face has its own copy of the vertices of the edges it
shares, and a few triangles collapse to slivers. Vertices closer than a tolerance far below the
deflection are merged (in float64), degenerate triangles dropped, and a closed solid comes out
closed: every edge used by exactly two triangles, consistently wound, facing out
(``close_mesh``). Each solid of a product is welded on its own (``product_mesh``): a part made of
several solids that share faces or edges is several closed shells, not one surface whose shared
edges join four triangles.

BRepMesh leaves some faces without triangles, or with triangles that stop short of the face's
edges (a full-turn chamfer cone a few tenths of a millimetre tall, at 0.005 mm): its node
insertion inside such a face fails, not the discretisation of its edges. Those faces of a solid
whose mesh is not closed are meshed again by BRepMesh (``mend_faces``) with the same deflection
on the edges, so they still share their neighbours' nodes, and a coarser one inside
(``IMeshTools_Parameters.DeflectionInterior``, ``MEND_INTERIOR_FACTORS``); the distance between
such a face and its new triangles is measured, and a distance above the deflection becomes the
deflection its product's parts hold (the file's is the largest).
"""

from __future__ import annotations

import dataclasses
import io
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...units import METRES
from . import PREPARE  # what workers import first (``preload``)
from .assembly import Instance, UniqueNames, order_key
from .document import captured_output

if TYPE_CHECKING:
    import trimesh

    from ...execute import Executor

# Linear deflection used when none is given: the largest distance between a curved face and its
# triangles. 0.005 mm keeps a measured 0.1 mm clearance within 0.01 mm (a pin and its hole are
# both faceted: the gap can widen by the hole's sag) and a 0.2 mm depth within 0.03 mm; see
# bench/step_tessellation.py for what it costs.
DEFAULT_DEFLECTION_MM = 0.005
# ... or this fraction of the largest solid's diagonal when that is more (parts of metres or
# kilometres: 0.005 mm across a 20 km part would be more triangles than any budget).
DEFAULT_RELATIVE_DEFLECTION = 1e-5
# Angular deflection, radians: the largest angle between neighbouring facets' normals. OpenCASCADE's
# usual; it only refines small radii, where the linear deflection already holds.
DEFAULT_ANGULAR_DEFLECTION = 0.5
# Deflections below this cannot be honoured: OpenCASCADE's confusion distance (Precision::
# Confusion, 1e-7 mm) is the size of a point to it, and its mesher fails or runs away below a
# few times that (1e-9 mm ended in an exception, 1e-6 mm in 1.7 GB and a crash).
MIN_DEFLECTION_MM = 1e-6
# ... and below this fraction of the largest solid's bounding-box diagonal: a million chords
# across a part resolve nothing a collision check can use, and cost memory quadratic in them.
MIN_RELATIVE_DEFLECTION = 1e-6
# Interior deflections tried, as multiples of the linear deflection, for a face BRepMesh could not
# mesh (``mend_faces``): the edges keep the linear deflection. A larger one makes BRepMesh insert
# fewer nodes inside the face, which the chamfer cones that fail need (the distance then measured
# is what the product holds). Twice the deflection meshed none of the faces that needed it in the
# real exports, and its failed tries cost more than the faces' meshes
# (``python bench/step_tessellation.py --mend FOLDERS``), so the list starts at four.
MEND_INTERIOR_FACTORS = (4, 8, 16)
# Triangles one STEP file may be tessellated into (every distinct product once), unless the run's
# budget (``--max-triangles``) has less left: a million triangles take about 200 MB here.
MAX_STEP_TRIANGLES = 5_000_000
#: What a worker that meshes STEP products imports besides ``PREPARE`` (``preload_welding``).
PREPARE_WELDING = "meshcheck.load.step.tessellate:preload_welding"
#: STEP files of this many bytes together have their workers started as the run starts
#: (``meshcheck.verify.brep.prepare_workers``), and a file this large has its products meshed in
#: them: the fastener-heavy exports (2.3-3.4 MB) spend 10-30 s of CPU on the B-rep, where the
#: files below 1 MB (box_sides.STEP, the AS1 assemblies, a KiCad board) decide theirs in less
#: than a worker's start-up, and a worker started for nothing costs 1.2 s of CPU.
PREPARE_BYTES = 1 << 20


@dataclasses.dataclass
class Products:
    """A read file's distinct products, ready to mesh (``products``): no OpenCASCADE object, so
    a worker that read the file ahead (``ahead``) sends it as it is.

    Attributes
    ----------
    instances : list of Instance
        Every solid instance, without its shapes (``product`` and ``trsf`` None): its name,
        product key and placement, mm.
    deflection_mm : float
        The deflection to mesh at, mm (``_honoured_deflection``).
    coarse_mm : float
        The coarse deflection the costs were counted at, mm.
    costs : dict
        Triangles of each product's coarse mesh, by product key: what meshing it fine costs,
        roughly.
    texts : dict
        BRep text of each product's copy (``with_copied_topology``), by product key, named
        after its first instance in name order: what ``mesh_task`` meshes.
    solid_texts : dict or None
        BRep text of each product as read, by product key (the exact solids' text,
        ``read.StepSolids.product_text``), when the file was read ahead; None otherwise.
    triangles : dict or None
        Each product's parts as ``triangulate`` gives them, by product key, when the worker
        that read the file ahead meshed it too (a small file: ``ahead.read_task``); None
        otherwise.
    """

    instances: list[Instance]
    deflection_mm: float
    coarse_mm: float
    costs: dict[str, int]
    texts: dict[str, bytes]
    solid_texts: dict[str, bytes] | None = None
    triangles: dict[str, list] | None = None


def products(
    instances: list[Instance],
    path: str,
    deflection_mm: float | None,
    angular: float,
    unit: str,
    default_scale: float = 1.0,
    threads: int = 1,
) -> Products:
    """The distinct products of ``instances`` (as read), ready to mesh at ``deflection_mm``
    (None: the default for their size, ``DEFAULT_DEFLECTION_MM`` times ``default_scale``,
    OpenCASCADE's millimetres per real one): each copied (``with_copied_topology``), meshed
    coarse in ``threads`` threads (``in_parallel``) to count what it costs, and written as BRep
    text. OpenCASCADE and numpy only.

    Raises
    ------
    InputError
        The deflection cannot be honoured (``_honoured_deflection``).
    """
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools

    meshed = with_copied_topology(instances)
    by_key = {i.product_key: i.product for i in meshed}
    diagonal = max(shape_diagonal(shape) for shape in by_key.values())
    deflection_mm = _honoured_deflection(deflection_mm, diagonal, path, unit, default_scale)
    # Estimate before meshing fine: a doubly curved face needs triangles in proportion to
    # 1/deflection, a cylinder or a plane's curved border to 1/sqrt(deflection); counting
    # 1/deflection from a coarse mesh overestimates, which is the safe side.
    coarse = max(deflection_mm, 1e-3 * diagonal)
    costs = {}
    parallel = in_parallel(threads)
    with captured_output():
        for key, shape in by_key.items():
            BRepTools.Clean_s(shape)  # from no triangulation, whatever meshed it before
            BRepMesh_IncrementalMesh(shape, coarse, False, angular, parallel)
            costs[key] = _triangle_count(shape)
    named = first_instances(meshed)
    # The texts travel as shared values, not in the tasks (``_meshed_products``).
    texts = {key: brep_text(named[key].product) for key in named}
    shapeless = [dataclasses.replace(i, product=None, trsf=None) for i in meshed]
    return Products(shapeless, deflection_mm, coarse, costs, texts)


def first_instances(instances: list[Instance]) -> dict[str, Instance]:
    """Each product's first instance in name order, by product key (in that order)."""
    named: dict[str, Instance] = {}
    for inst in sorted(instances, key=order_key):
        named.setdefault(inst.product_key, inst)
    return named


def tessellate(
    found: Products,
    path: str,
    angular: float,
    budget: int,
    unit: str,
    *,
    executor: Executor | None = None,
) -> dict[str, tuple[trimesh.Trimesh, float]]:
    """Mesh every distinct product of ``found`` once its cost is known to fit ``budget``
    triangles.

    Each product is meshed from its BRep text (``mesh_task``), here or, when ``executor``'s
    workers have loaded OpenCASCADE (``PREPARE``) for a large file, in them: the same triangles
    either way.

    Returns
    -------
    dict
        By product key: the product's closed mesh (file units) and the largest distance, mm,
        between a face meshed again and its triangles (``product_mesh``). Each mesh's
        ``metadata["brep"]`` is the hex SHA-256 of its product's BRep text: the solid it
        approximates, whatever the deflection or the mesher (``Body.source_digest``).

    Raises
    ------
    InputError
        The estimate exceeds ``budget``, or a product cannot be meshed.
    """
    to_unit = _file_units_per_mm(unit)
    deflection_mm, coarse = found.deflection_mm, found.coarse_mm
    estimate = estimated_triangles(found)
    if estimate > budget:
        fits = coarse * max(1.0, sum(found.costs.values()) / budget)
        raise InputError(
            path,
            f"STEP deflection {deflection_mm * to_unit:.3g} {unit} would make about "
            f"{estimate:.3g} triangles (budget {budget}): use {fits * to_unit:.3g} {unit} "
            "or more, or raise --max-triangles",
        )
    return _meshed_products(found, path, angular, to_unit, executor)


def triangulated(found: Products, unit: str, angular: float, threads: int = 1) -> dict[str, list]:
    """Each product of ``found`` triangulated (``triangulate``) as ``tessellate`` meshes it in
    the file's ``unit`` and ``angular``, by product key, in ``threads`` threads
    (``in_parallel``): what the worker that read a small file ahead sends
    (``Products.triangles``)."""
    to_unit = _file_units_per_mm(unit)
    deflection = _deflection(found, to_unit)
    return {
        key: triangulate(t, to_unit, deflection, angular, threads) for key, t in found.texts.items()
    }


def _file_units_per_mm(unit: str) -> float:
    return 1e-3 / METRES[unit]


def _deflection(found: Products, to_unit: float) -> float:
    """The deflection ``found`` is meshed at, file units, as every mesher is given it."""
    return found.deflection_mm * to_unit


def estimated_triangles(found: Products) -> float:
    """The triangles meshing ``found`` at its deflection makes, estimated from the coarse
    counts (an overestimate, ``products``)."""
    estimate = 0.0
    for count in found.costs.values():
        estimate += count * found.coarse_mm / found.deflection_mm
    return estimate


def _meshed_products(
    found: Products,
    path: str,
    angular: float,
    to_unit: float,
    executor: Executor | None,
) -> dict[str, tuple[trimesh.Trimesh, float]]:
    """``tessellate``'s meshes: one ``mesh_task`` per distinct product, each named after its
    first instance in name order, the costliest first (``found.costs``). A product the worker
    that read the file ahead triangulated (``found.triangles``) is only welded here, unless a
    face of it must be meshed again (``welded_triangles``)."""
    import trimesh

    from ...cache.store import checksum
    from ...execute import Executor, Task

    deflection = _deflection(found, to_unit)
    named = first_instances(found.instances)
    welded = {}
    for key, parts in (found.triangles or {}).items():
        try:
            mesh = welded_triangles(parts, f"{path}#{named[key].name}", to_unit, deflection)
        except InputError as exc:  # raised in order below, as ``mesh_task`` returns it
            welded[key] = (exc.path, exc.reason)
            continue
        if mesh is not None:
            welded[key] = (np.asarray(mesh.vertices), np.asarray(mesh.faces), 0.0)
    keys = [key for key in named if key not in welded]
    # The texts travel as shared values, not in the tasks: a task sent ahead to a busy worker
    # would block this process on a large one until that worker finished (``LocalPool``). A
    # worker keeps what it was sent for the next map (another file's products): by content.
    digests = {key: checksum(found.texts[key]).hex() for key in named}
    stored = {key: ("step-product", digests[key]) for key in keys}
    shared = {stored[key]: found.texts[key] for key in keys}
    in_workers = _meshes_in_workers(executor, len(keys))
    tasks = []
    for key in keys:  # the workers and this process start on the largest (``LocalPool.map``)
        args = (stored[key], f"{path}#{named[key].name}", to_unit, deflection, angular)
        tasks.append(Task(args, needs=(stored[key],), size=found.costs[key]))
    runner = executor if in_workers else Executor()
    function = "meshcheck.load.step.tessellate:mesh_task"
    results = dict(zip(keys, runner.map(function, tasks, shared=shared, here=True), strict=True))
    tasks = dict(zip(keys, tasks, strict=True))
    out = {}
    for key in named:
        result = welded[key] if key in welded else results[key]
        if result is None:  # its worker died: mesh it here (a bug then shows its traceback)
            result = Executor().map(function, [tasks[key]], shared=shared)[0]
        if isinstance(result[0], str):  # (part name, reason): the product cannot be meshed
            raise InputError(*result)
        vertices, faces, deviation = result
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        mesh.metadata["brep"] = digests[key]  # what its parts' finding IDs hash (``Body``)
        out[key] = (mesh, deviation)
    return out


def _meshes_in_workers(executor: Executor | None, products: int) -> bool:
    """Whether products are meshed in ``executor``'s workers: local ones that loaded
    OpenCASCADE while the file was read (``PREPARE``), and more than one product."""
    return (
        executor is not None
        and not executor.is_distributed
        and PREPARE in executor.prepared
        and products > 1
    )


def brep_text(shape) -> bytes:
    """``shape`` as OpenCASCADE's BRep text, without triangulation: what ``mesh_task`` and the
    verify stage's workers read a product from."""
    from OCP.BRepTools import BRepTools
    from OCP.TopTools import TopTools_FormatVersion

    stream = io.BytesIO()
    version = TopTools_FormatVersion.TopTools_FormatVersion_VERSION_1
    BRepTools.Write_s(shape, stream, False, False, version)
    return stream.getvalue()


def mesh_task(
    store: dict, text: tuple, name: str, to_unit: float, deflection: float, angular: float
) -> tuple[np.ndarray, np.ndarray, float] | tuple[str, str]:
    """Mesh one product read from its BRep text (``brep_text``, ``store[text]``) at
    ``deflection`` (file units) and ``angular``, closed (``product_mesh``): its vertices (file
    units), faces and the largest distance, mm, of a face meshed again; or ``(name, reason)``
    when it cannot be."""
    shape = _meshed_text(store[text], to_unit, deflection, angular)
    try:
        mesh, deviation = product_mesh(shape, name, to_unit, deflection, angular=angular)
    except InputError as exc:
        return exc.path, exc.reason
    return np.asarray(mesh.vertices), np.asarray(mesh.faces), deviation


def triangulate(
    text: bytes, to_unit: float, deflection: float, angular: float, threads: int = 1
) -> list[tuple[bool, tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """A product read from its BRep text and meshed as ``mesh_task`` meshes it (in ``threads``
    threads: the same triangles, ``in_parallel``), not welded: ``(is a solid, face_arrays)`` of
    each of its parts (``_solids_and_rest``). OpenCASCADE and numpy only: what the worker that
    reads a small file ahead does while this process imports trimesh (``welded_triangles``
    welds them)."""
    shape = _meshed_text(text, to_unit, deflection, angular, threads)
    return [(is_solid, face_arrays(part)) for part, is_solid in _solids_and_rest(shape)]


def _meshed_text(text: bytes, to_unit: float, deflection: float, angular: float, threads: int = 1):
    """The shape of a BRep text, meshed by BRepMesh at ``deflection`` (file units, ``to_unit``
    file units per mm) and ``angular``, in ``threads`` threads (``in_parallel``)."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    BRepTools.Read_s(shape, io.BytesIO(text), BRep_Builder())
    parallel = in_parallel(threads)
    with captured_output():
        BRepMesh_IncrementalMesh(shape, deflection / to_unit, False, angular, parallel)
    return shape


def in_parallel(threads: int) -> bool:
    """Whether BRepMesh is to mesh in parallel: in up to ``threads`` threads of OpenCASCADE's
    pool (sized by the first call in a process), when ``threads`` is more than one.

    Each edge, then each face, is meshed on its own, so the triangles are the same in any
    number of threads (every STEP file of the tests and benchmarks checked, array for array).
    Only a worker that reads a file ahead meshes in threads (``ahead.read_task``): the run's
    other processes wait for it then. It forks its twin before: a process forked after the
    pool's threads started would have none."""
    if threads < 2:
        return False
    from OCP.OSD import OSD_ThreadPool

    OSD_ThreadPool.DefaultPool_s(threads).SetNbDefaultThreadsToLaunch(threads)
    return True


def preload() -> None:
    """What a worker of a run with large STEP files imports while the files are read
    (``PREPARE``): OpenCASCADE's bindings (one extension, 0.7-1.0 s of CPU) for the B-rep and
    the mesher."""
    import OCP.TopoDS  # noqa: F401


def preload_welding() -> None:
    """What ``mesh_task`` imports besides (``PREPARE_WELDING``): trimesh and scipy, with which
    ``product_mesh`` welds the triangles (0.4-0.5 s of CPU)."""
    from ... import mesh  # noqa: F401


def _honoured_deflection(
    deflection_mm: float | None, diagonal: float, path: str, unit: str, default_scale: float
) -> float:
    """The deflection to mesh at, mm: ``deflection_mm``, or the default for parts of
    ``diagonal`` mm; refused (``InputError``) below what OpenCASCADE can honour."""
    floor = max(MIN_DEFLECTION_MM, MIN_RELATIVE_DEFLECTION * diagonal)
    if deflection_mm is None:
        deflection_mm = max(
            DEFAULT_DEFLECTION_MM * default_scale, DEFAULT_RELATIVE_DEFLECTION * diagonal
        )
    if deflection_mm < floor:
        to_unit = 1e-3 / METRES[unit]
        raise InputError(
            path,
            f"STEP deflection {deflection_mm * to_unit:.3g} {unit} is finer than meshcheck can "
            f"honour (OpenCASCADE's precision, or 1e-6 of the largest part): use "
            f"{floor * to_unit:.3g} {unit} or more",
        )
    return deflection_mm


def with_copied_topology(instances: list[Instance]) -> list[Instance]:
    """The instances, each product replaced by a copy of its topology that shares its geometry
    (one copy per product): the mesher writes its triangulation there, and the instances' own
    shapes stay exactly as read, for the exact solids (``read.StepSolids``)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy

    copies: dict[str, object] = {}
    out = []
    for inst in instances:
        if inst.product_key not in copies:
            copy = BRepBuilderAPI_Copy(inst.product, False, False)  # no geometry, no mesh
            copies[inst.product_key] = copy.Shape()
        out.append(dataclasses.replace(inst, product=copies[inst.product_key]))
    return out


def shape_diagonal(shape) -> float:
    """Diagonal of an OpenCASCADE shape's bounding box, its unit (0 for an empty shape)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)
    if box.IsVoid():
        return 0.0
    return float(box.CornerMin().Distance(box.CornerMax()))


def _triangle_count(shape) -> int:
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    n, explorer = 0, TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        tri = BRep_Tool.Triangulation_s(TopoDS.Face(explorer.Current()), TopLoc_Location())
        n += 0 if tri is None else tri.NbTriangles()
        explorer.Next()
    return n


def triangulation_arrays(tri, location) -> tuple[np.ndarray, np.ndarray]:
    """A face's triangulation ``tri`` as arrays: its nodes placed by ``location`` ((n, 3)
    float64) and its triangles as OpenCASCADE numbers them, from 1 ((m, 3) int64), not wound by
    the face's orientation."""
    node, triangle = tri.Node, tri.Triangle
    if location.IsIdentity():  # as a product's faces are: Transformed would copy each node
        points = [node(i).Coord() for i in range(1, tri.NbNodes() + 1)]
    else:
        trsf = location.Transformation()
        points = [node(i).Transformed(trsf).Coord() for i in range(1, tri.NbNodes() + 1)]
    triangles = [triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)]
    return (
        np.array(points, dtype=np.float64).reshape(-1, 3),
        np.array(triangles, dtype=np.int64).reshape(-1, 3),
    )


def face_arrays(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The triangles of a meshed shape, one copy of the vertices per face, wound by each face's
    orientation (outward for a solid), and which copies the topology says are one point.

    Returns
    -------
    vertices : (n, 3) float64
        mm.
    faces : (m, 3) int64
    same : (k, 2) int64
        Vertex pairs that are one node of an edge two faces share (OpenCASCADE meshes an edge
        once; each face evaluates the node on its own surface, so the copies may differ by up to
        the edge's tolerance).
    """
    from OCP.BRep import BRep_Tool
    from OCP.OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp, TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    edges = IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher()
    TopExp.MapShapes_s(shape, TopAbs_EDGE, edges)
    first: dict[int, np.ndarray] = {}  # edge index -> its nodes in the first face meshed
    vertices, faces, same, offset = [], [], [], 0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        location = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, location)
        if tri is None or tri.NbTriangles() == 0:
            continue
        nodes, triangles = triangulation_arrays(tri, location)
        if face.Orientation() == TopAbs_REVERSED:
            triangles = triangles[:, ::-1]
        edge_explorer = TopExp_Explorer(face, TopAbs_EDGE)
        while edge_explorer.More():
            edge = TopoDS.Edge(edge_explorer.Current())
            edge_explorer.Next()
            polygon = BRep_Tool.PolygonOnTriangulation_s(edge, tri, location)
            if polygon is None:
                continue
            ids = (
                offset
                - 1
                + np.array(
                    [polygon.Node(i) for i in range(1, polygon.NbNodes() + 1)], dtype=np.int64
                )
            )
            known = first.setdefault(edges.FindIndex(edge), ids)
            if known is not ids and len(known) == len(ids):
                same.append(np.stack([known, ids], axis=1))
        vertices.append(nodes)
        faces.append(triangles - 1 + offset)
        offset += len(nodes)
    if not faces:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2), np.int64)
    pairs = np.concatenate(same) if same else np.zeros((0, 2), dtype=np.int64)
    return np.concatenate(vertices), np.concatenate(faces), pairs


def placed_meshes(
    instances: list[Instance],
    meshes: dict[str, tuple[trimesh.Trimesh, float]],
    path: str,
    to_unit: float,
    deflection: float,
) -> tuple[list[tuple[str, trimesh.Trimesh, np.ndarray]], float]:
    """(unique product name, closed local mesh, transform) per solid instance, file units; and
    the deflection the meshes hold, file units: ``deflection``, or more when a face meshed
    again (``mend_faces``) lies farther from its triangles. ``meshes`` are ``tessellate``'s;
    each product's mesh keeps its own deflection in ``mesh.metadata["deflection"]``."""
    items = []
    unique = UniqueNames()
    held = deflection
    for mesh, deviation_mm in meshes.values():
        mesh.metadata["deflection"] = max(deflection, deviation_mm * to_unit)
        held = max(held, mesh.metadata["deflection"])
    for inst in sorted(instances, key=order_key):
        mesh = meshes[inst.product_key][0]
        transform = inst.matrix.copy()
        transform[:3, 3] *= to_unit
        if not np.all(np.isfinite(transform)):
            raise InputError(
                f"{path}#{inst.name}", "placement transform holds NaN or infinite values"
            )
        if len(mesh.faces):
            items.append((unique(inst.name), mesh, transform))
        else:
            unique(inst.name)  # names in step with placed_solids
    if not items:
        raise InputError(path, "holds no solids (nothing OpenCASCADE could tessellate)")
    items.sort(key=lambda item: item[0])
    return items, held


def product_mesh(
    shape, name: str, to_unit: float, deflection: float, *, angular: float
) -> tuple[trimesh.Trimesh, float]:
    """A meshed product as one mesh, file units: each solid welded on its own (so each closed
    solid is a closed shell), then the faces outside every solid welded together.

    A solid whose mesh is not closed has its faces meshed again where BRepMesh left them
    without triangles or short of their edges (``mend_faces``).

    Returns
    -------
    mesh : trimesh.Trimesh
        The shells one after the other, no vertex shared between two of them.
    deviation : float
        The largest distance, mm, between a face meshed again and its triangles (0 if none).
    """
    from ...mesh import is_closed

    deflection_mm = deflection / to_unit
    shells, deviation = [], 0.0
    for part, is_solid in _solids_and_rest(shape):
        mesh = _welded(face_arrays(part), name, to_unit, deflection)
        if is_solid and not is_closed(mesh):
            measured = mend_faces(part, deflection_mm, angular)
            if measured is not None:
                deviation = max(deviation, measured)
                mesh = _welded(face_arrays(part), name, to_unit, deflection)
        shells.append(mesh)
    return _one_mesh(shells), deviation


def welded_triangles(
    parts: list, name: str, to_unit: float, deflection: float
) -> trimesh.Trimesh | None:
    """A product's mesh from its parts' triangles (``triangulate``), the one ``product_mesh``
    makes when no face must be meshed again; None when one must (a solid's mesh is not closed):
    ``mesh_task`` meshes that product.

    Raises
    ------
    InputError
        A vertex is not finite (as ``product_mesh``).
    """
    from ...mesh import is_closed

    shells = []
    for is_solid, arrays in parts:
        mesh = _welded(arrays, name, to_unit, deflection)
        if is_solid and not is_closed(mesh):
            return None
        shells.append(mesh)
    return _one_mesh(shells)


def _one_mesh(shells: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The shells as one mesh, one after the other, no vertex shared between two of them."""
    import trimesh

    if len(shells) == 1:
        return shells[0]
    offsets = np.cumsum([0] + [len(m.vertices) for m in shells[:-1]])
    vertices = np.concatenate([m.vertices for m in shells]) if shells else np.zeros((0, 3))
    faces = np.concatenate([m.faces + k for m, k in zip(shells, offsets, strict=True)])
    return trimesh.Trimesh(vertices, faces.reshape(-1, 3), process=False)


def _welded(arrays: tuple, name: str, to_unit: float, deflection: float) -> trimesh.Trimesh:
    """A shape's triangles (``face_arrays``) welded into one surface (``close_mesh``), file
    units."""
    vertices, faces, same = arrays
    if not np.all(np.isfinite(vertices)):
        raise InputError(name, "vertices have NaN or infinite coordinates")
    return close_mesh(vertices * to_unit, faces, deflection, same=same)


def _solids_and_rest(shape) -> list[tuple[object, bool]]:
    """(sub-shape, is a solid): each solid of ``shape``, then a compound of the faces outside
    every solid, if any; ``shape`` itself when it holds no solid."""
    from OCP.BRep import BRep_Builder
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS_Compound

    out = []
    explorer = TopExp_Explorer(shape, TopAbs_SOLID)
    while explorer.More():
        out.append((explorer.Current(), True))
        explorer.Next()
    if not out:
        return [(shape, False)]
    builder, rest, has_rest = BRep_Builder(), TopoDS_Compound(), False
    builder.MakeCompound(rest)
    explorer = TopExp_Explorer(shape, TopAbs_FACE, TopAbs_SOLID)
    while explorer.More():
        builder.Add(rest, explorer.Current())
        has_rest = True
        explorer.Next()
    return [*out, (rest, False)] if has_rest else out


def mend_faces(solid, deflection_mm: float, angular: float) -> float | None:
    """Mesh again the faces of a meshed ``solid`` that BRepMesh left without triangles or whose
    triangles do not reach their edges (``follows_edges``).

    BRepMesh meshes the compound of those faces alone, at the deflection and angle the solid was
    meshed at on the edges: it discretises their edges as it did the first time (the same nodes
    as the neighbours' triangulations hold), so the seams stay closed. Inside the faces the
    deflection is ``MEND_INTERIOR_FACTORS`` times coarser, the first that succeeds; the
    triangles' real distance from the face is then measured (``face_deviation``).

    Parameters
    ----------
    solid : TopoDS_Shape
        Meshed at ``deflection_mm`` and ``angular`` by ``BRepMesh_IncrementalMesh``.
    deflection_mm, angular : float
        Its linear (mm) and angular (radians) deflections.

    Returns
    -------
    float or None
        The largest distance, mm, between a face meshed again and its triangles; None when no
        face needed it.
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.IMeshTools import IMeshTools_Parameters

    broken = [face for face in _faces(solid) if not follows_edges(face)]
    if not broken:
        return None
    mended, builder = list(broken), BRep_Builder()
    for factor in MEND_INTERIOR_FACTORS:
        for face in broken:
            builder.UpdateFace(face, None)  # dropped: BRepMesh meshes them again
        params = IMeshTools_Parameters()
        params.Deflection = deflection_mm
        params.Angle = angular
        params.DeflectionInterior = factor * deflection_mm
        with captured_output():
            BRepMesh_IncrementalMesh(_compound(broken), params)
        broken = [face for face in broken if not follows_edges(face)]
        if not broken:
            break
    return max((face_deviation(face) for face in mended if _has_triangles(face)), default=0.0)


def _compound(shapes):
    """An OpenCASCADE compound of ``shapes`` (which stay shared with their solid)."""
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    builder, compound = BRep_Builder(), TopoDS_Compound()
    builder.MakeCompound(compound)
    for shape in shapes:
        builder.Add(compound, shape)
    return compound


def _faces(shape) -> list:
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out, explorer = [], TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        out.append(TopoDS.Face(explorer.Current()))
        explorer.Next()
    return out


def _has_triangles(face) -> bool:
    from OCP.BRep import BRep_Tool
    from OCP.TopLoc import TopLoc_Location

    tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
    return tri is not None and tri.NbTriangles() > 0


def _triangles(tri) -> np.ndarray:
    """(m, 3) int64: a ``Poly_Triangulation``'s triangles, 1-based node numbers."""
    return np.array(
        [tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64
    ).reshape(-1, 3)


def follows_edges(face) -> bool:
    """Whether a meshed face's triangles cover it up to its edges: each segment of its edges'
    polygons (OpenCASCADE's nodes of the edge on this face's triangulation) borders exactly one
    triangle, and no other triangle side is unshared or shared by more than two triangles.
    Degenerate edges (a cone's apex) and internal ones (inside the face) are left out."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_EXTERNAL, TopAbs_INTERNAL
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    location = TopLoc_Location()
    tri = BRep_Tool.Triangulation_s(face, location)
    if tri is None or tri.NbTriangles() == 0:
        return False
    triangles = _triangles(tri)
    sides = np.sort(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1
    )
    sides, uses = np.unique(sides, axis=0, return_counts=True)
    if (uses > 2).any():
        return False
    segments = [np.zeros((0, 2), dtype=np.int64)]
    explorer = TopExp_Explorer(face, TopAbs_EDGE)
    while explorer.More():
        edge = TopoDS.Edge(explorer.Current())
        explorer.Next()
        if BRep_Tool.Degenerated_s(edge) or edge.Orientation() in (
            TopAbs_INTERNAL,
            TopAbs_EXTERNAL,
        ):
            continue
        polygon = BRep_Tool.PolygonOnTriangulation_s(edge, tri, location)
        if polygon is None:
            return False
        nodes = np.array([polygon.Node(i) for i in range(1, polygon.NbNodes() + 1)], dtype=np.int64)
        segments.append(np.stack([nodes[:-1], nodes[1:]], axis=1))
    border = np.sort(np.concatenate(segments), axis=1)
    border = np.unique(border[border[:, 0] != border[:, 1]], axis=0)
    return np.array_equal(border, sides[uses == 1])


def face_deviation(face) -> float:
    """Largest distance, mm, between a meshed face's surface and its triangles, measured at each
    triangle's centroid and the midpoints of its sides (where a chord strays farthest from a
    surface curved along it)."""
    from OCP.BRep import BRep_Tool
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.gp import gp_Pnt
    from OCP.TopLoc import TopLoc_Location

    location = TopLoc_Location()
    tri = BRep_Tool.Triangulation_s(face, location)
    surface = BRep_Tool.Surface_s(face)  # placed by the face's location
    trsf = location.Transformation()
    nodes = np.array([tri.Node(i).Transformed(trsf).Coord() for i in range(1, tri.NbNodes() + 1)])
    corners = nodes[_triangles(tri) - 1]
    points = np.concatenate(
        [corners.mean(axis=1)] + [(corners[:, k] + corners[:, (k + 1) % 3]) / 2 for k in range(3)]
    )
    worst = 0.0
    for point in points:
        projection = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, point)), surface)
        if projection.NbPoints():
            worst = max(worst, float(projection.LowerDistance()))
    return worst


def close_mesh(
    vertices: np.ndarray, faces: np.ndarray, deflection: float, *, same: np.ndarray | None = None
) -> trimesh.Trimesh:
    """Weld a tessellation's faces into one surface: close seams, drop slivers, face outward.

    Parameters
    ----------
    vertices : (n, 3) float64
        Vertices as the mesher wrote them, one copy per face of each shared edge point.
    faces : (m, 3) int64
        Triangles.
    deflection : float
        The tessellation's linear deflection, same unit: vertices closer than a hundredth of it
        (but never a thousandth of the mesh's size: a deflection coarser than a part must not
        merge it to a point; and at least 2**-40 of the coordinates) are one point.
    same : (k, 2) int64, optional
        Vertex pairs that are one point whatever their distance (the nodes of an edge shared by
        two faces, ``face_arrays``).

    Returns
    -------
    trimesh.Trimesh
        Vertices merged (the lowest index of each cluster stands for it), triangles with a
        repeated vertex dropped; inverted when it is closed and encloses a negative volume.

    Examples
    --------
    >>> import trimesh
    >>> box = trimesh.creation.box()
    >>> split = box.vertices[box.faces].reshape(-1, 3) + 1e-9  # every face its own vertices
    >>> mesh = close_mesh(split, np.arange(36).reshape(-1, 3), 1e-3)
    >>> bool(mesh.is_watertight), len(mesh.vertices), round(float(mesh.volume), 9)
    (True, 8, 1.0)
    """
    import trimesh

    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    extent = float(np.abs(vertices).max()) if len(vertices) else 0.0
    size = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0
    tol = max(min(0.01 * deflection, 1e-3 * size), 2.0**-40 * extent)
    rep = np.arange(len(vertices))
    for group in trimesh.grouping.clusters(vertices, tol):
        group = np.asarray(group, dtype=np.int64)
        rep[group] = group.min()
    if same is not None and len(same):
        rep = _joined(rep, np.asarray(same, dtype=np.int64).reshape(-1, 2))
    faces = rep[faces]
    keep = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    mesh = trimesh.Trimesh(vertices, faces[keep], process=False)
    mesh.remove_unreferenced_vertices()
    if mesh.is_watertight and mesh.is_winding_consistent and mesh.volume < 0:
        mesh.invert()
    return mesh


def _joined(rep: np.ndarray, same: np.ndarray) -> np.ndarray:
    """``rep`` (each vertex's cluster's lowest index) with the clusters of each pair in ``same``
    joined: each vertex's joined cluster's lowest index."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(rep)
    links = np.concatenate([np.stack([np.arange(n), rep], axis=1), same])
    graph = coo_matrix((np.ones(len(links)), (links[:, 0], links[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    lowest = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(lowest, labels, np.arange(n))
    return lowest[labels]
