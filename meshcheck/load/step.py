"""STEP files -> solids: read and tessellated by OpenCASCADE (OCP), closed, in the file's own unit.

Reading
-------
OpenCASCADE's XCAF reader (``STEPCAFControl_Reader``, through the OCP bindings) reads the file
into a document of products and instances. Before anything is transferred the file's assembly
structure is checked on its entities: a ``NEXT_ASSEMBLY_USAGE_OCCURRENCE`` cycle (an assembly
that lists itself), a reference to an entity the file does not hold, or parts kept in other files
(AP214 external references: ``DOCUMENT_FILE``) are an ``InputError`` naming what is wrong;
OpenCASCADE would otherwise drop the parts it cannot reach and say nothing. After the transfer,
every solid the file holds must be in a placed product, or the file is refused: no solid is ever
dropped without saying so.

Each solid instance is a part named after its product (made unique in a fixed order: ``bolt``,
``bolt_1``...), placed by the composed transforms of the assembly, in double precision. The same
walk gives the exact solids (``brep_solids``), so the verify stage can confirm a finding on the
B-rep the part came from (``meshcheck.verify.brep``).

Units
-----
OpenCASCADE converts every length to millimetres, whatever the file declares (it understands
every SI prefix and conversion-based unit). ``read_step`` converts back to the length unit the
file declares (its ``GLOBAL_UNIT_ASSIGNED_CONTEXT``, named by ``meshcheck.units``), so that a
millimetre STEP gives millimetres and an inch STEP inches.

Tessellation
------------
``BRepMesh_IncrementalMesh``, one thread. The chords of a curved face lie inside it, by at most
the linear deflection: a pin in a hole, both faceted, shows a gap up to one deflection wider (or
an overlap up to two deflections shallower) than the CAD model. The default,
``DEFAULT_DEFLECTION_MM``, keeps a 0.1 mm clearance within 0.01 mm and a 0.2 mm interference within
0.03 mm (tests/test_step.py); the value used is ``StepAssembly.deflection``, in the file's unit.

A deflection is honoured only when it can be with bounded time and memory: it must be at least
``MIN_DEFLECTION_MM`` (ten times OpenCASCADE's own confusion distance; finer triangles would
resolve nothing the B-rep holds) and at least ``MIN_RELATIVE_DEFLECTION`` of the largest
solid's diagonal, and the triangles it would make, estimated from a coarse tessellation before
the fine one, must fit ``max_triangles``. Otherwise the file is refused with the deflection that
would fit.

Closed solids
-------------
Faces are tessellated one by one: each face has its own copy of the vertices of the edges it
shares, and a few triangles collapse to slivers. Vertices closer than a tolerance far below the
deflection are merged (in float64), degenerate triangles dropped, and a closed solid comes out
closed: every edge used by exactly two triangles, consistently wound, facing out.

Messages
--------
OpenCASCADE prints its diagnostics on the process's standard output and error streams (file
descriptors 1 and 2), where the report goes. They are captured while it runs, and the first
error line becomes the reason of the ``InputError`` for a broken file.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import trimesh

from .. import units as units_
from ..cache import Tessellation, TessellationCache, tessellation_key
from ..errors import InputError, MeshcheckWarning

STEP_EXTENSIONS = (".step", ".stp")

# Linear deflection used when none is given: the largest distance between a curved face and its
# triangles. 0.005 mm keeps a measured 0.1 mm clearance within 0.01 mm (a pin and its hole are
# both faceted: the gap can widen by the hole's sag) and a 0.2 mm depth within 0.03 mm; see
# bench/step.py for what it costs.
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
# Triangles one STEP file may be tessellated into (every distinct product once), unless the run's
# budget (``--max-triangles``) has less left: a million triangles take about 200 MB here.
MAX_STEP_TRIANGLES = 5_000_000

UNIT_METRES = units_.METRES  # the one unit table (meshcheck.units)
_NAME_LIMIT = 200  # characters of a product name kept in a part name


@dataclass(frozen=True)
class StepAssembly:
    """The solids of a STEP file.

    Attributes
    ----------
    items : list of (str, trimesh.Trimesh, (4, 4) float64)
        ``(name, mesh, transform)`` per solid instance, sorted by name. ``name`` is the STEP
        product name, made unique (``bolt``, ``bolt_1``...); ``mesh`` is in the product's own
        frame (shared by the instances of one product); ``transform`` places it in the
        assembly. Lengths in ``unit``.
    unit : str
        The length unit the file declares, a key of ``meshcheck.units.METRES`` (``"mm"`` when it
        declares none that is recognised, with a warning).
    deflection : float
        Linear deflection of the tessellation, ``unit``: the triangles lie within this of the
        CAD faces, so a gap or depth is uncertain by up to twice this.
    angular_deflection : float
        Angular deflection of the tessellation, radians.
    """

    items: list[tuple[str, trimesh.Trimesh, np.ndarray]]
    unit: str
    deflection: float
    angular_deflection: float


def read_step(
    path: str,
    *,
    deflection: float | None = None,
    deflection_unit: str | None = None,
    unit: str | None = None,
    angular_deflection: float | None = None,
    cache: TessellationCache | None = None,
    max_triangles: int | None = None,
) -> StepAssembly:
    """Tessellate the solids of a STEP file, in the unit the file declares.

    Parameters
    ----------
    path : str
        A STEP (ISO 10303-21) file.
    deflection : float, optional
        Largest distance between a curved face and its triangles, in ``deflection_unit``.
        Default ``DEFAULT_DEFLECTION_MM`` millimetres, or ``DEFAULT_RELATIVE_DEFLECTION`` of
        the largest solid's diagonal when that is more.
    deflection_unit : str, optional
        Unit of ``deflection``, a key of ``meshcheck.units.METRES``; default the file's own unit.
    unit : str, optional
        The unit the file's lengths really are in (``--units FILE=UNIT``): deflections are
        meant in it; the assembly keeps the file's numbers and declared unit.
    angular_deflection : float, optional
        Largest angle between neighbouring facets, radians; default
        ``DEFAULT_ANGULAR_DEFLECTION``.
    cache : TessellationCache, optional
        Where tessellations are kept, by file content and settings.
    max_triangles : int, optional
        Triangles the file may be tessellated into (distinct products once); default and upper
        bound ``MAX_STEP_TRIANGLES``.

    Returns
    -------
    StepAssembly

    Raises
    ------
    InputError
        The file cannot be read, is not STEP, holds no solid, has an assembly cycle, a dangling
        or an external reference, a solid outside every placed product, or the deflection cannot
        be honoured (see the module docstring).
    ValueError
        ``deflection`` or ``angular_deflection`` is not a positive finite number, or
        ``deflection_unit`` is unknown (options are the caller's to validate).

    Examples
    --------
    >>> asm = read_step("sample_meshes/assembly.step")
    >>> asm.unit, [name for name, _, _ in asm.items][:3]
    ('mm', ['bolt_m6', 'bolt_m6_1', 'bolt_m6_2'])
    """
    _check_deflections(deflection, deflection_unit, angular_deflection)
    angular = (
        DEFAULT_ANGULAR_DEFLECTION if angular_deflection is None else float(angular_deflection)
    )
    data = _read_bytes(path)
    declared = _declared_unit(data)
    real_unit = unit
    unit = declared or "mm"
    scale = UNIT_METRES[unit]  # metres per file unit
    deflection_mm, ratio = _deflection_mm(deflection, deflection_unit, unit, real_unit)
    budget = MAX_STEP_TRIANGLES if max_triangles is None else min(max_triangles, MAX_STEP_TRIANGLES)

    key = tessellation_key(data, deflection_mm, angular, default_scale=ratio) if cache else ""
    found = cache.get(key) if cache is not None else None
    if found is None or found.unit != unit:
        instances = _document(data, path).instances
        used_mm = _tessellate(instances, path, deflection_mm, angular, budget, unit, ratio)
        items = _items(instances, path, 1e-3 / scale, used_mm * 1e-3 / scale)
        found = Tessellation(items, unit, used_mm * 1e-3 / scale, angular)
        if cache is not None:
            cache.put(key, found)
    if declared is None and real_unit is None:
        _warn_no_unit(path)
    return StepAssembly(*found)


def _deflection_mm(deflection, deflection_unit, unit: str, real_unit: str | None):
    """(the deflection in OpenCASCADE's millimetres or None for the default, OpenCASCADE's
    millimetres per real millimetre): the ratio is not 1 when the user says the file's lengths
    are in ``real_unit``, not the ``unit`` it declares."""
    ratio = (
        1.0 if real_unit is None else UNIT_METRES[unit] / UNIT_METRES[units_.unit_name(real_unit)]
    )
    if deflection is None:
        return None, ratio  # the default, at least DEFAULT_RELATIVE_DEFLECTION of the parts
    given_unit = (real_unit or unit) if deflection_unit is None else deflection_unit
    return float(deflection) * UNIT_METRES[given_unit] / 1e-3 * ratio, ratio


def _check_deflections(deflection, deflection_unit, angular_deflection) -> None:
    """Refuse (ValueError) an unknown unit or a deflection that is not a positive number."""
    if deflection_unit is not None and deflection_unit not in UNIT_METRES:
        raise ValueError(f"unknown length unit {deflection_unit!r}")
    for value in (deflection, angular_deflection):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"deflection must be a positive number, not {value!r}")


def brep_solids(path: str) -> dict[str, object]:
    """The exact solids of a STEP file, by part node name, placed, in millimetres.

    The names are ``read_step``'s, from the same walk of the same file. The shapes are
    OpenCASCADE ``TopoDS_Shape`` objects in the assembly's frame, lengths in millimetres
    (OpenCASCADE's unit whatever the file declares). The last file read is kept, by content.

    Raises
    ------
    InputError
        As ``read_step``.
    """
    data = _read_bytes(path)
    document = _document(data, path)
    return {name: shape for name, shape in _named(document.instances)}


def _read_bytes(path: str) -> bytes:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if not data:
        raise InputError(path, "empty file")
    return data


# --------------------------------------------------------------------------------------------
# Reading: the document, its structure, its instances


@dataclass
class _Instance:
    """One placed solid: its product's name, shape (shared by instances) and placement (mm)."""

    name: str
    product: object  # TopoDS_Shape in the product's frame
    product_key: str  # the product's label entry: instances of one product share it
    trsf: object  # gp_Trsf, product frame -> assembly frame, mm
    matrix: np.ndarray  # the same, (4, 4) float64


@dataclass
class _Document:
    digest: bytes
    instances: list[_Instance]


_LAST: list[_Document] = []  # the last document read: verify asks for the file load just read


def _document(data: bytes, path: str) -> _Document:
    """Read, check and transfer ``data`` (the content of ``path``); kept for the next call."""
    digest = hashlib.sha256(data).digest()
    if _LAST and _LAST[0].digest == digest:
        return _LAST[0]
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document

    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    with tempfile.TemporaryDirectory() as tmp, _captured_output() as messages:
        # Read the bytes hashed (a file changing under us cannot give another file's parts).
        copy = os.path.join(tmp, "input.step")
        with open(copy, "wb") as f:
            f.write(data)
        reader = STEPCAFControl_Reader()
        reader.SetNameMode(True)
        is_read = reader.ReadFile(copy) == IFSelect_ReturnStatus.IFSelect_RetDone
        if is_read:
            counts = check_structure(reader.Reader().StepModel(), path)
            is_read = reader.Transfer(doc)
    if not is_read:  # the messages are read back once the streams are restored
        raise InputError(path, f"cannot be read as STEP: {_first_error(messages())}")
    instances = _walk(doc)
    _check_all_solids_placed(instances, counts, path)
    document = _Document(digest, instances)
    _LAST[:] = [document]
    return document


def check_structure(model, path: str) -> int:
    """Refuse assembly cycles, dangling references and external references; count solids.

    Parameters
    ----------
    model : OCP.StepData.StepData_StepModel
        The file's entities, as read (nothing transferred yet).
    path : str
        The file, for messages.

    Returns
    -------
    int
        The solids (``MANIFOLD_SOLID_BREP`` and its kinds) the file holds.

    Raises
    ------
    InputError
        Naming the product that is its own ancestor, the occurrence whose reference is missing,
        or the files the parts are kept in.
    """
    from OCP.StepBasic import StepBasic_DocumentFile, StepBasic_ProductDefinition
    from OCP.StepRepr import StepRepr_NextAssemblyUsageOccurrence
    from OCP.StepShape import StepShape_ManifoldSolidBrep

    entities = [model.Value(i) for i in range(1, model.NbEntities() + 1)]
    number = {id(e): k + 1 for k, e in enumerate(entities)}
    children: dict[int, list[int]] = {}
    solids, documents = 0, []
    for e in entities:
        if isinstance(e, StepShape_ManifoldSolidBrep):
            solids += 1
        elif isinstance(e, StepBasic_DocumentFile):
            documents.append(_text(e.Id()) or _text(e.Name()))
        elif isinstance(e, StepRepr_NextAssemblyUsageOccurrence):
            parent, child = e.RelatingProductDefinition(), e.RelatedProductDefinition()
            if parent is None or child is None or id(parent) not in number:
                raise InputError(
                    path,
                    f"assembly occurrence {_text(e.Id())!r} (NEXT_ASSEMBLY_USAGE_OCCURRENCE) "
                    "refers to an entity the file does not hold (a dangling reference): parts "
                    "would be missing",
                )
            children.setdefault(number[id(parent)], []).append(number[id(child)])
    if documents:
        shown = ", ".join(sorted(set(documents))[:4]) + (" ..." if len(set(documents)) > 4 else "")
        raise InputError(
            path,
            f"keeps its parts in other files ({shown}: AP214 external references); meshcheck "
            "reads one file: export the assembly as a single STEP file",
        )
    cycle = _cycle(children)
    if cycle is not None:
        names = {
            number[id(e)]: _product_name(e)
            for e in entities
            if isinstance(e, StepBasic_ProductDefinition)
        }
        shown = " -> ".join(repr(names.get(n, "?")) for n in cycle)
        raise InputError(
            path, f"assembly cycle: {shown}: a product contains itself, so no part can be placed"
        )
    return solids


def _cycle(children: dict[int, list[int]]) -> list[int] | None:
    """A cycle of the graph, as its nodes from the first repeated one, or None (iterative DFS)."""
    state: dict[int, int] = {}  # 1 on the path, 2 done
    for root in sorted(children):
        if state.get(root):
            continue
        path, stack = [root], [iter(children.get(root, ()))]
        state[root] = 1
        while stack:
            child = next(stack[-1], None)
            if child is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(child) == 1:
                return [*path[path.index(child) :], child]
            elif not state.get(child):
                state[child] = 1
                path.append(child)
                stack.append(iter(children.get(child, ())))
    return None


def _product_name(definition) -> str:
    with contextlib.suppress(Exception):
        return _text(definition.Formation().OfProduct().Name())
    return "?"


def _text(value) -> str:
    """The text of an OpenCASCADE string handle (None when absent)."""
    if value is None:
        return ""
    return _safe_name(value.ToCString()) if hasattr(value, "ToCString") else _safe_name(value)


def _walk(doc) -> list[_Instance]:
    """Every solid instance of the document: free shapes down through components."""
    from OCP.gp import gp_Trsf
    from OCP.OCP.collections import Sequence_TDF_Label
    from OCP.TCollection import TCollection_AsciiString
    from OCP.TDF import TDF_Label, TDF_Tool
    from OCP.XCAFDoc import XCAFDoc_DocumentTool, XCAFDoc_ShapeTool

    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    free = Sequence_TDF_Label()
    tool.GetFreeShapes(free)
    out: list[_Instance] = []
    stack = [(free.Value(i), gp_Trsf()) for i in range(free.Length(), 0, -1)]
    while stack:
        label, trsf = stack.pop()
        if XCAFDoc_ShapeTool.IsReference_s(label):
            referred = TDF_Label()
            XCAFDoc_ShapeTool.GetReferredShape_s(label, referred)
            local = XCAFDoc_ShapeTool.GetLocation_s(label).Transformation()
            stack.append((referred, trsf.Multiplied(local)))
        elif XCAFDoc_ShapeTool.IsAssembly_s(label):
            components = Sequence_TDF_Label()
            XCAFDoc_ShapeTool.GetComponents_s(label, components)
            stack.extend((components.Value(i), trsf) for i in range(components.Length(), 0, -1))
        else:
            shape = XCAFDoc_ShapeTool.GetShape_s(label)
            if shape.IsNull():
                continue
            entry = TCollection_AsciiString()
            TDF_Tool.Entry_s(label, entry)
            out.append(_Instance(_label_name(label), shape, entry.ToCString(), trsf, _matrix(trsf)))
    return out


def _label_name(label) -> str:
    from OCP.TDataStd import TDataStd_Name

    attribute = TDataStd_Name()
    if label.FindAttribute(TDataStd_Name.GetID_s(), attribute):
        return _safe_name(attribute.Get().ToExtString())
    return "solid"


def _matrix(trsf) -> np.ndarray:
    out = np.eye(4)
    for row in range(3):
        for col in range(4):
            out[row, col] = trsf.Value(row + 1, col + 1)
    return out


def _check_all_solids_placed(instances: list[_Instance], solids: int, path: str) -> None:
    """Refuse a file with solids no placed product holds, or none at all."""
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID

    if not instances or not any(_count(i.product, TopAbs_FACE) for i in instances):
        raise InputError(path, "holds no solids (nothing OpenCASCADE could place)")
    placed = sum(
        _count(shape, TopAbs_SOLID)
        for shape in {i.product_key: i.product for i in instances}.values()
    )
    if placed < solids:
        raise InputError(
            path,
            f"only {placed} of its {solids} solids are in a placed product (the others are "
            "unreachable from the assembly or failed to read); refusing to check a part of it",
        )


def _count(shape, kind) -> int:
    from OCP.TopExp import TopExp_Explorer

    explorer, n = TopExp_Explorer(shape, kind), 0
    while explorer.More():
        n += 1
        explorer.Next()
    return n


def _named(instances: list[_Instance]) -> list[tuple[str, object]]:
    """(unique part node name, placed shape) per instance, in ``read_step``'s order."""
    from OCP.TopLoc import TopLoc_Location

    order = sorted(range(len(instances)), key=lambda k: _order_key(instances[k]))
    used: set[str] = set()
    out = []
    for k in order:
        inst = instances[k]
        out.append((_unique(inst.name, used), inst.product.Moved(TopLoc_Location(inst.trsf))))
    return out


def _order_key(instance: _Instance) -> tuple[str, bytes]:
    """Deterministic order whatever the hash seed: by product name, then placement."""
    return instance.name, instance.matrix.tobytes()


# --------------------------------------------------------------------------------------------
# Tessellation


def _tessellate(
    instances: list[_Instance],
    path: str,
    deflection_mm: float | None,
    angular: float,
    budget: int,
    unit: str,
    default_scale: float = 1.0,
) -> float:
    """Mesh every distinct product at ``deflection_mm`` (None: the default for their size,
    ``DEFAULT_DEFLECTION_MM`` times ``default_scale``, OpenCASCADE's millimetres per real one)
    once its cost is known to fit; return the deflection used, mm."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools

    products = list({i.product_key: i.product for i in instances}.values())
    diagonal = max(shape_diagonal(shape) for shape in products)
    floor = max(MIN_DEFLECTION_MM, MIN_RELATIVE_DEFLECTION * diagonal)
    if deflection_mm is None:
        deflection_mm = max(
            DEFAULT_DEFLECTION_MM * default_scale, DEFAULT_RELATIVE_DEFLECTION * diagonal
        )
    to_unit = 1e-3 / UNIT_METRES[unit]
    if deflection_mm < floor:
        raise InputError(
            path,
            f"STEP deflection {deflection_mm * to_unit:.3g} {unit} is finer than meshcheck can "
            f"honour (OpenCASCADE's precision, or 1e-6 of the largest part): use "
            f"{floor * to_unit:.3g} {unit} or more",
        )
    # Estimate before meshing fine: a doubly curved face needs triangles in proportion to
    # 1/deflection, a cylinder or a plane's curved border to 1/sqrt(deflection); counting
    # 1/deflection from a coarse mesh overestimates, which is the safe side.
    coarse = max(deflection_mm, 1e-3 * diagonal)
    with _captured_output():
        estimate = 0.0
        for shape in products:
            BRepTools.Clean_s(shape)  # the document may be meshed already (read again)
            BRepMesh_IncrementalMesh(shape, coarse, False, angular, False)
            estimate += _triangle_count(shape) * coarse / deflection_mm
        if estimate > budget:
            fits = coarse * max(1.0, sum(map(_triangle_count, products)) / budget)
            raise InputError(
                path,
                f"STEP deflection {deflection_mm * to_unit:.3g} {unit} would make about "
                f"{estimate:.3g} triangles (budget {budget}): use {fits * to_unit:.3g} {unit} "
                "or more, or raise --max-triangles",
            )
        if coarse != deflection_mm:
            for shape in products:
                BRepTools.Clean_s(shape)
                BRepMesh_IncrementalMesh(shape, deflection_mm, False, angular, False)
    return deflection_mm


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


def _face_arrays(shape) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) float64 mm, faces (m, 3) int64) of a meshed shape, one copy per face,
    wound by each face's orientation (outward for a solid)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    vertices, faces, offset = [], [], 0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        location = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, location)
        if tri is None or tri.NbTriangles() == 0:
            continue
        trsf = location.Transformation()
        nodes = np.array(
            [tri.Node(i).Transformed(trsf).Coord() for i in range(1, tri.NbNodes() + 1)],
            dtype=np.float64,
        )
        triangles = np.array(
            [tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64
        )
        if face.Orientation() == TopAbs_REVERSED:
            triangles = triangles[:, ::-1]
        vertices.append(nodes)
        faces.append(triangles - 1 + offset)
        offset += len(nodes)
    if not faces:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(vertices), np.concatenate(faces)


def _items(
    instances: list[_Instance], path: str, to_unit: float, deflection: float
) -> list[tuple[str, trimesh.Trimesh, np.ndarray]]:
    """(unique product name, closed local mesh, transform) per solid instance, file units."""
    meshes: dict[str, trimesh.Trimesh] = {}  # one closed mesh per product
    items = []
    used: set[str] = set()
    for inst in sorted(instances, key=_order_key):
        if inst.product_key not in meshes:
            vertices, faces = _face_arrays(inst.product)
            if not np.all(np.isfinite(vertices)):
                raise InputError(f"{path}#{inst.name}", "vertices have NaN or infinite coordinates")
            meshes[inst.product_key] = close_mesh(vertices * to_unit, faces, deflection)
        transform = inst.matrix.copy()
        transform[:3, 3] *= to_unit
        if not np.all(np.isfinite(transform)):
            raise InputError(
                f"{path}#{inst.name}", "placement transform holds NaN or infinite values"
            )
        if len(meshes[inst.product_key].faces):
            items.append((_unique(inst.name, used), meshes[inst.product_key], transform))
        else:
            used.add(_unique(inst.name, used))  # keep names in step with brep_solids
    if not items:
        raise InputError(path, "holds no solids (nothing OpenCASCADE could tessellate)")
    items.sort(key=lambda item: item[0])
    return items


def close_mesh(vertices: np.ndarray, faces: np.ndarray, deflection: float) -> trimesh.Trimesh:
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

    Returns
    -------
    trimesh.Trimesh
        Vertices merged (the lowest index of each cluster stands for it), triangles with a
        repeated vertex dropped; inverted when it is closed and encloses a negative volume.

    Examples
    --------
    >>> box = trimesh.creation.box()
    >>> split = box.vertices[box.faces].reshape(-1, 3) + 1e-9  # every face its own vertices
    >>> mesh = close_mesh(split, np.arange(36).reshape(-1, 3), 1e-3)
    >>> bool(mesh.is_watertight), len(mesh.vertices), round(float(mesh.volume), 9)
    (True, 8, 1.0)
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    extent = float(np.abs(vertices).max()) if len(vertices) else 0.0
    size = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0
    tol = max(min(0.01 * deflection, 1e-3 * size), 2.0**-40 * extent)
    rep = np.arange(len(vertices))
    for group in trimesh.grouping.clusters(vertices, tol):
        group = np.asarray(group, dtype=np.int64)
        rep[group] = group.min()
    faces = rep[faces]
    keep = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    mesh = trimesh.Trimesh(vertices, faces[keep], process=False)
    mesh.remove_unreferenced_vertices()
    if mesh.is_watertight and mesh.is_winding_consistent and mesh.volume < 0:
        mesh.invert()
    return mesh


def _safe_name(name: str) -> str:
    """A product name fit for a part name: printable, bounded, never empty."""
    text = "".join(c if c.isprintable() else "?" for c in str(name)).strip()
    return text[:_NAME_LIMIT] or "solid"


def _unique(name: str, used: set[str]) -> str:
    """``name``, or ``name_1``, ``name_2``... whichever is not yet in ``used`` (then add it)."""
    candidate, k = name, 0
    while candidate in used:
        k += 1
        candidate = f"{name}_{k}"
    used.add(candidate)
    return candidate


# --------------------------------------------------------------------------------------------
# Units

_ENTITY = r"#{}\s*=\s*((?:'(?:[^']|'')*'|[^;'])*);"
_CONTEXT_UNITS = re.compile(r"GLOBAL_UNIT_ASSIGNED_CONTEXT\s*\(\s*\(([#\d\s,]*)\)")
_SI_LENGTH = re.compile(r"SI_UNIT\s*\(\s*(\$|\.[A-Z]+\.)\s*,\s*\.METRE\.\s*\)")
_CONVERSION = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'((?:[^']|'')*)'")


def step_unit(data: bytes, path: str = "") -> str:
    """The length unit a STEP file declares, a key of ``UNIT_METRES``.

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
    unit = _declared_unit(data)
    if unit is None:
        _warn_no_unit(path)
    return unit or "mm"


def _warn_no_unit(path: str) -> None:
    warnings.warn(
        MeshcheckWarning(f"{path}: declares no length unit meshcheck knows; reading millimetres"),
        stacklevel=3,
    )


def _declared_unit(data: bytes) -> str | None:
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
            return units_.unit_name(conversion.group(1).replace("''", "'"))
        except ValueError:
            return None
    si = _SI_LENGTH.search(body)
    if si is not None:
        prefix = si.group(1).strip(".")
        return "m" if prefix == "$" else units_.SI_PREFIXES.get(prefix)
    return None


# --------------------------------------------------------------------------------------------
# Messages of the C++ library


@contextlib.contextmanager
def _captured_output() -> Iterator[Callable[[], str]]:
    """Send file descriptors 1 and 2 to a temporary file; yield a function reading it back."""
    with tempfile.TemporaryFile() as sink:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            text: list[str] = []

            def read() -> str:
                return "".join(text)

            yield read
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            sink.seek(0)
            text.append(sink.read(1 << 16).decode("utf-8", "replace"))


def _first_error(messages: str) -> str:
    """The first error line OpenCASCADE printed, without colours and decoration."""
    clean = re.sub(r"\x1b\[[0-9;]*m", "", messages)
    lines = [line.strip(" *\t") for line in clean.splitlines()]
    errors = [line for line in lines if "ERR" in line or "rror" in line]
    if not errors:
        return "not a STEP file OpenCASCADE can read"
    # "**** ERR StepFile : Undefined Parsing: Line 7: Incorrect syntax: ..." -> "Line 7: ..."
    reason = re.sub(r"^ERR\s+StepFile\s*:\s*(Undefined Parsing\s*:\s*)?", "", errors[0])
    return _one_line(reason)


def _one_line(text) -> str:
    text = " ".join(str(text).split()) or "unknown error"
    text = "".join(c if c.isprintable() else "?" for c in text)
    return text if len(text) <= 160 else text[:157] + "..."
