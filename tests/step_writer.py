"""Write STEP assemblies with OpenCASCADE (cadquery-ocp), for tests, benchmarks and samples.

Products are OpenCASCADE solids built from primitives, named, and placed by transforms in an
assembly whose instances share their product (as CAD systems write repeated parts). Lengths are
in the file's unit: the document is given that unit, so nothing is scaled on the way out.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Sequence

# metres per unit, and the name OpenCASCADE writes in the file
UNITS = {"MM": 1e-3, "INCH": 0.0254, "M": 1.0, "CM": 1e-2, "FT": 0.3048}


def box(lower, upper):
    """A solid box from corner ``lower`` to corner ``upper``."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt

    (x0, y0, z0), (x1, y1, z1) = lower, upper
    return BRepPrimAPI_MakeBox(gp_Pnt(x0, y0, z0), gp_Pnt(x1, y1, z1)).Shape()


def cylinder(radius: float, z0: float, z1: float, x: float = 0.0, y: float = 0.0):
    """A solid cylinder along z from ``z0`` to ``z1``, axis through (x, y)."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    axis = gp_Ax2(gp_Pnt(x, y, z0), gp_Dir(0, 0, 1))
    return BRepPrimAPI_MakeCylinder(axis, radius, z1 - z0).Shape()


def cut(shape, *tools):
    """``shape`` minus every tool."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut

    for tool in tools:
        shape = BRepAlgoAPI_Cut(shape, tool).Shape()
    return shape


def fuse(shape, *others):
    """The union of the shapes."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse

    for other in others:
        shape = BRepAlgoAPI_Fuse(shape, other).Shape()
    return shape


def fillet(shape, radius: float):
    """``shape`` with every edge rounded by ``radius``."""
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    maker = BRepFilletAPI_MakeFillet(shape)
    explorer = TopExp_Explorer(shape, TopAbs_EDGE)
    while explorer.More():
        maker.Add(radius, TopoDS.Edge(explorer.Current()))
        explorer.Next()
    return maker.Shape()


def annulus_volume(hole: float, pin: float, height: float) -> float:
    """Volume a pin of radius ``pin`` on the axis of a hole of radius ``hole`` shares with the
    plate ``height`` thick the hole goes through: the annulus between the circles, in closed
    form (0 when the pin is no wider than the hole). The oracle for fits, independent of the
    OpenCASCADE booleans meshcheck's B-rep stage makes."""
    return math.pi * max(pin * pin - hole * hole, 0.0) * height


def rounded_box_volume(extents, radius: float) -> float:
    """Volume of a box of ``extents`` with every edge rounded by ``radius`` (``fillet``), in
    closed form: the inner box, its six faces' slabs, its twelve edges' quarter cylinders (three
    whole cylinders) and its eight corners' eighth spheres (one sphere)."""
    a, b, c = (e - 2.0 * radius for e in extents)
    slabs = 2.0 * radius * (a * b + b * c + c * a)
    return a * b * c + slabs + math.pi * radius**2 * (a + b + c) + 4.0 / 3.0 * math.pi * radius**3


def wavy_ring(inner: float, outer: float, height: float, amplitude: float, waves: int):
    """A ring about the z axis from radius ``inner`` out to a wall that waves ``amplitude``
    about ``outer`` ``waves`` times over its ``height``: the wall is revolved from a cubic
    B-spline of 60 poles on the wave (58 knots), as CAD systems write a knurl or a rolled
    profile. Returns (solid, its volume in closed form): Pappus, 2 pi times the profile's
    first moment about the axis, the line integral of x^2/2 dz around the profile taken span by
    span by Gauss-Legendre (exact: the integrand is a polynomial of degree 8 on each span)."""
    import numpy as np
    from OCP.BRepBuilderAPI import (
        BRepBuilderAPI_MakeEdge,
        BRepBuilderAPI_MakeFace,
        BRepBuilderAPI_MakeWire,
    )
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeRevol
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt, gp_Vec
    from OCP.OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int

    count = 60  # poles, clamped cubic on uniform knots: 58 knots
    poles = Array1_gp_Pnt(1, count)
    knots, multiplicities = Array1_double(1, count - 2), Array1_int(1, count - 2)
    for i in range(count):
        z = height * i / (count - 1)
        x = outer + amplitude * math.sin(2.0 * math.pi * waves * z / height)
        poles.SetValue(i + 1, gp_Pnt(x, 0.0, z))
    for i in range(count - 2):
        knots.SetValue(i + 1, float(i))
        multiplicities.SetValue(i + 1, 4 if i in (0, count - 3) else 1)
    wall = Geom_BSplineCurve(poles, knots, multiplicities, 3)
    bottom, top = wall.Value(wall.FirstParameter()), wall.Value(wall.LastParameter())
    corners = [top, gp_Pnt(inner, 0.0, top.Z()), gp_Pnt(inner, 0.0, bottom.Z()), bottom]
    wire = BRepBuilderAPI_MakeWire()
    wire.Add(BRepBuilderAPI_MakeEdge(wall).Edge())
    for start, end in itertools.pairwise(corners):
        wire.Add(BRepBuilderAPI_MakeEdge(start, end).Edge())
    face = BRepBuilderAPI_MakeFace(wire.Wire(), True).Face()
    solid = BRepPrimAPI_MakeRevol(face, gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1))).Shape()

    nodes, weights = np.polynomial.legendre.leggauss(8)
    breaks = [wall.Knot(i) for i in range(1, wall.NbKnots() + 1)]
    moment = 0.5 * inner**2 * (bottom.Z() - top.Z())  # down the inner wall; the caps: dz = 0
    for a, b in itertools.pairwise(breaks):
        for node, weight in zip(nodes, weights, strict=True):
            point, tangent = gp_Pnt(), gp_Vec()
            wall.D1(0.5 * (a + b) + 0.5 * (b - a) * node, point, tangent)
            moment += 0.5 * (b - a) * weight * 0.5 * point.X() ** 2 * tangent.Z()
    return solid, 2.0 * math.pi * moment


def placement(translation=(0.0, 0.0, 0.0), angle_deg: float = 0.0, axis=(0.0, 0.0, 1.0)):
    """(4, 4) transform: rotate by ``angle_deg`` about ``axis`` through the origin, then move."""
    import numpy as np

    axis = np.asarray(axis, dtype=np.float64)
    axis /= np.linalg.norm(axis)
    a = np.radians(angle_deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    out = np.eye(4)
    out[:3, :3] = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * (k @ k)
    out[:3, 3] = translation
    return out


def write_step(
    path: str,
    products: dict,
    instances: Sequence[tuple[str, object]],
    *,
    unit: str = "MM",
    assembly: str = "assembly",
    external: bool = False,
) -> str:
    """Write an assembly of named products placed by (4, 4) rigid transforms to a STEP file.

    Parameters
    ----------
    path : str
        Output file.
    products : dict of str -> TopoDS_Shape
        Product name -> solid, in the product's own frame, ``unit``.
    instances : sequence of (str, (4, 4) array)
        Product name and placement of each instance, in order.
    unit : str
        A key of ``UNITS``: the length unit the file declares and its coordinates are in.
    assembly : str
        Product name of the top assembly.
    external : bool
        Write each product to a sibling file (``PATH`` without its extension, then ``_NAME``...)
        that the assembly file references (AP214 external references), as some CAD systems do.
    """
    import numpy as np
    from OCP.gp import gp_Trsf
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopLoc import TopLoc_Location
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    STEPCAFControl_Controller.Init_s()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, UNITS[unit])
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    top = tool.NewShape()
    TDataStd_Name.Set_s(top, TCollection_ExtendedString(assembly))
    labels = {}
    for name, shape in products.items():
        labels[name] = tool.AddShape(shape, False)
        TDataStd_Name.Set_s(labels[name], TCollection_ExtendedString(name))
    for name, transform in instances:
        m = np.asarray(transform, dtype=np.float64)
        trsf = gp_Trsf()
        trsf.SetValues(*m[0], *m[1], *m[2])
        tool.AddComponent(top, labels[name], TopLoc_Location(trsf))
    tool.UpdateAssemblies()
    Interface_Static.SetCVal_s("write.step.unit", unit)
    Interface_Static.SetCVal_s("write.step.product.name", assembly)
    writer = STEPCAFControl_Writer()
    prefix = os.path.splitext(str(path))[0] if external else None
    writer.Transfer(doc, STEPControl_AsIs, prefix)
    if writer.Write(str(path)) != IFSelect_ReturnStatus.IFSelect_RetDone:
        raise OSError(f"{path}: OpenCASCADE could not write the STEP file")
    return str(path)
