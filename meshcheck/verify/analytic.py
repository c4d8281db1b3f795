"""A solid whose B-spline faces and edges are planes, cylinders, circles and lines -> the same
solid written with those (no I/O).

CAD exports often store analytic geometry as B-splines (a bolt's shank, a bore, the circle
bounding it). OpenCASCADE intersects two B-spline faces tens of times slower than two
cylinders, and integrates a B-spline solid's volume with a fixed rule that can be far off. A
face or edge whose B-spline lies within ``RELATIVE_TOLERANCE`` of the solid's box diagonal of a
plane, cylinder, cone, sphere or torus (``GeomConvert_SurfToAnaSurf``), a line, circle or
ellipse (``GeomConvert_CurveToAnaCurve``) is rebuilt on it, with the same vertices and
topology; ``ShapeFix_Shape`` lays the edges' curves on the new faces. The rebuilt solid is used
only when OpenCASCADE's checker calls it valid, it is one closed solid with as many faces,
edges and vertices, and its volume (adaptive integration) matches the original's within
``VOLUME_MATCH``; otherwise the solid is kept as it is.
"""

from __future__ import annotations

from .volumes import volume

#: A B-spline within this fraction of the solid's box diagonal of an analytic surface or curve
#: is rebuilt on it.
RELATIVE_TOLERANCE = 1e-7
#: The rebuilt solid's volume matches the original's within this fraction.
VOLUME_MATCH = 1e-6


def analytic(shape):
    """``shape`` (one solid, or a compound of solids) with its analytic B-spline faces and
    edges rebuilt on analytic geometry; ``shape`` itself when it has none, or when the rebuilt
    solid fails a check (see the module docstring).

    Examples
    --------
    >>> from OCP.BRepAdaptor import BRepAdaptor_Surface
    >>> from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert
    >>> from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    >>> from OCP.TopAbs import TopAbs_FACE
    >>> from OCP.TopoDS import TopoDS
    >>> nurbs = BRepBuilderAPI_NurbsConvert(BRepPrimAPI_MakeCylinder(2.0, 5.0).Shape()).Shape()
    >>> def kinds(shape):
    ...     faces = _explore(shape, TopAbs_FACE)
    ...     return sorted(BRepAdaptor_Surface(TopoDS.Face(f)).GetType().name for f in faces)
    >>> kinds(nurbs)
    ['GeomAbs_BSplineSurface', 'GeomAbs_BSplineSurface', 'GeomAbs_BSplineSurface']
    >>> kinds(analytic(nurbs))
    ['GeomAbs_Cylinder', 'GeomAbs_Plane', 'GeomAbs_Plane']
    """
    from OCP.Standard import Standard_Failure

    if not _has_free_form(shape):
        return shape
    tolerance = RELATIVE_TOLERANCE * _diagonal(shape)
    try:
        rebuilt = _rebuilt(shape, tolerance)
    except Standard_Failure:
        return shape
    return rebuilt if rebuilt is not None and _same_solid(shape, rebuilt) else shape


_FREE_SURFACES = ("GeomAbs_BSplineSurface", "GeomAbs_BezierSurface")
_FREE_CURVES = ("GeomAbs_BSplineCurve", "GeomAbs_BezierCurve")


def _has_free_form(shape) -> bool:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopoDS import TopoDS

    return any(
        BRepAdaptor_Surface(TopoDS.Face(face), False).GetType().name in _FREE_SURFACES
        for face in _explore(shape, TopAbs_FACE)
    )


def _explore(shape, kind):
    from OCP.TopExp import TopExp_Explorer

    explorer = TopExp_Explorer(shape, kind)
    while explorer.More():
        yield explorer.Current()
        explorer.Next()


def _children(shape):
    from OCP.TopoDS import TopoDS_Iterator

    iterator = TopoDS_Iterator(shape, False, False)
    while iterator.More():
        yield iterator.Value()
        iterator.Next()


class _Shapes:
    """Sub-shapes by identity (TShape and location, not orientation) -> what replaces them."""

    def __init__(self):
        self._buckets: dict[int, list] = {}

    def get(self, shape):
        for other, value in self._buckets.get(hash(_forward(shape)), ()):
            if other.IsSame(shape):
                return value
        return None

    def put(self, shape, value) -> None:
        self._buckets.setdefault(hash(_forward(shape)), []).append((_forward(shape), value))


def _forward(shape):
    from OCP.TopAbs import TopAbs_FORWARD

    return shape.Oriented(TopAbs_FORWARD)


def _rebuilt(shape, tolerance: float):
    """The solids of ``shape`` rebuilt face by face (None: a face or edge does not fit, or
    none is analytic)."""
    from OCP.BRep import BRep_Builder, BRep_Tool
    from OCP.ShapeFix import ShapeFix_Shape
    from OCP.TopAbs import TopAbs_COMPOUND, TopAbs_SOLID
    from OCP.TopoDS import (
        TopoDS,
        TopoDS_Compound,
        TopoDS_Face,
        TopoDS_Shell,
        TopoDS_Solid,
        TopoDS_Wire,
    )

    builder = BRep_Builder()
    edges, faces = _Shapes(), _Shapes()
    converted = 0
    if shape.ShapeType() == TopAbs_SOLID:
        solids = [shape]
    elif shape.ShapeType() == TopAbs_COMPOUND:
        solids = list(_children(shape))
    else:
        return None
    rebuilt = []
    for solid in solids:
        if solid.ShapeType() != TopAbs_SOLID:
            return None
        new_solid = TopoDS_Solid()
        builder.MakeSolid(new_solid)
        for shell in _children(solid):
            new_shell = TopoDS_Shell()
            builder.MakeShell(new_shell)
            for face in _children(shell):
                made = faces.get(face)
                if made is None:
                    forward = TopoDS.Face(_forward(face))
                    surface, location, flip, changed = _surface(forward, tolerance)
                    converted += changed
                    new_face = TopoDS_Face()
                    builder.MakeFace(new_face, surface, location, BRep_Tool.Tolerance_s(forward))
                    for wire in _children(forward):
                        new_wire = TopoDS_Wire()
                        builder.MakeWire(new_wire)
                        for edge in _children(wire):
                            new_edge = edges.get(edge)
                            if new_edge is None:
                                new_edge = _edge(TopoDS.Edge(_forward(edge)), tolerance, builder)
                                if new_edge is None:
                                    return None
                                edges.put(edge, new_edge)
                            builder.Add(new_wire, new_edge.Oriented(edge.Orientation()))
                        new_wire.Closed(wire.Closed())
                        # a surface whose normal is the other way round: the face is reversed,
                        # its wires too, so that every edge is walked as before
                        oriented = new_wire.Oriented(wire.Orientation())
                        builder.Add(new_face, oriented.Reversed() if flip else oriented)
                    made = (new_face, flip)
                    faces.put(face, made)
                new_face, flip = made
                new_face = new_face.Oriented(face.Orientation())
                builder.Add(new_shell, new_face.Reversed() if flip else new_face)
            new_shell.Closed(BRep_Tool.IsClosed_s(shell))
            builder.Add(new_solid, new_shell.Oriented(shell.Orientation()))
        rebuilt.append(new_solid.Oriented(solid.Orientation()))
    if not converted:
        return None
    if shape.ShapeType() == TopAbs_SOLID:
        result = rebuilt[0]
    else:
        result = TopoDS_Compound()
        builder.MakeCompound(result)
        for solid in rebuilt:
            builder.Add(result, solid)
    fix = ShapeFix_Shape(result)
    fix.Perform()
    return fix.Shape()


def _surface(face, tolerance: float):
    """``face``'s surface, its location, whether its normal is reversed and whether it is new:
    the analytic surface it lies on, or its own when it is not a B-spline within ``tolerance``
    of one."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepTools import BRepTools
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.GeomConvert import GeomConvert_SurfToAnaSurf
    from OCP.GeomLProp import GeomLProp_SLProps
    from OCP.TopLoc import TopLoc_Location

    location = TopLoc_Location()
    surface = BRep_Tool.Surface_s(face, location)
    if BRepAdaptor_Surface(face, False).GetType().name not in _FREE_SURFACES:
        return surface, location, False, False
    converted = GeomConvert_SurfToAnaSurf(surface).ConvertToAnalytical(tolerance)
    if converted is None:
        return surface, location, False, False
    u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
    old = GeomLProp_SLProps(surface, 0.5 * (u0 + u1), 0.5 * (v0 + v1), 1, 1e-12)
    projection = GeomAPI_ProjectPointOnSurf(old.Value(), converted)
    if not projection.NbPoints() or projection.LowerDistance() > tolerance:
        return surface, location, False, False
    new = GeomLProp_SLProps(converted, *projection.LowerDistanceParameters(), 1, 1e-12)
    if not (old.IsNormalDefined() and new.IsNormalDefined()):
        return surface, location, False, False
    return converted, location, old.Normal().Dot(new.Normal()) < 0.0, True


def _edge(edge, tolerance: float, builder):
    """A new edge between ``edge``'s vertices, walked the same way: on the analytic curve its
    B-spline lies within ``tolerance`` of, or on its own curve; without curves on faces (None:
    the edge is degenerate, or its converted curve does not run through its ends)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAPI import GeomAPI_ProjectPointOnCurve
    from OCP.GeomConvert import GeomConvert_CurveToAnaCurve
    from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
    from OCP.TopExp import TopExp
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS_Edge, TopoDS_Vertex

    if BRep_Tool.Degenerated_s(edge):
        return None
    adaptor = BRepAdaptor_Curve(edge)
    first, last = adaptor.FirstParameter(), adaptor.LastParameter()
    location = TopLoc_Location()
    curve = BRep_Tool.Curve_s(edge, location, 0.0, 0.0)
    if curve is None:
        return None
    new, new_first, new_last = curve, first, last
    if adaptor.GetType().name in _FREE_CURVES:
        converted = GeomConvert_CurveToAnaCurve.ComputeCurve_s(
            curve, tolerance, first, last, 0.0, 0.0, 0.0
        )
        if converted is not None:
            start, end = curve.Value(first), curve.Value(last)
            middle = curve.Value(0.5 * (first + last))
            a = GeomAPI_ProjectPointOnCurve(start, converted).LowerDistanceParameter()
            b = GeomAPI_ProjectPointOnCurve(end, converted).LowerDistanceParameter()
            if converted.IsPeriodic():
                period = converted.Period()
                if start.Distance(end) <= tolerance:
                    b = a + period
                else:
                    while b <= a:
                        b += period
            checks = ((a, start), (b, end), (0.5 * (a + b), middle))
            if b <= a or any(converted.Value(t).Distance(p) > tolerance for t, p in checks):
                return None
            new, new_first, new_last = converted, a, b
    start_vertex, end_vertex = TopoDS_Vertex(), TopoDS_Vertex()
    TopExp.Vertices_s(edge, start_vertex, end_vertex)
    out = TopoDS_Edge()
    builder.MakeEdge(out, new, location, BRep_Tool.Tolerance_s(edge))
    builder.Add(out, start_vertex.Oriented(TopAbs_FORWARD))
    builder.Add(out, end_vertex.Oriented(TopAbs_REVERSED))
    builder.Range(out, new_first, new_last)
    return out


def _same_solid(original, rebuilt) -> bool:
    """Whether ``rebuilt`` is valid, closed, of the same topology and volume as ``original``."""
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SOLID, TopAbs_VERTEX

    if rebuilt.ShapeType() != original.ShapeType() or not _closed(rebuilt):
        return False
    for kind in (TopAbs_SOLID, TopAbs_FACE, TopAbs_EDGE, TopAbs_VERTEX):
        if _count(original, kind) != _count(rebuilt, kind):
            return False
    if not BRepCheck_Analyzer(rebuilt).IsValid():
        return False
    before, after = volume(original), volume(rebuilt)
    return abs(before - after) <= VOLUME_MATCH * max(abs(before), abs(after))


def _closed(shape) -> bool:
    """Whether every shell of ``shape`` is closed (each edge shared by two of its faces)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_SHELL

    return all(BRep_Tool.IsClosed_s(shell) for shell in _explore(shape, TopAbs_SHELL))


def _diagonal(shape) -> float:
    """Diagonal of a shape's bounding box."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)
    return 0.0 if box.IsVoid() else float(box.CornerMin().Distance(box.CornerMax()))


def _count(shape, kind) -> int:
    """Distinct sub-shapes of ``kind`` (a shared edge once)."""
    seen = _Shapes()
    count = 0
    for sub in _explore(shape, kind):
        if seen.get(sub) is None:
            seen.put(sub, True)
            count += 1
    return count
