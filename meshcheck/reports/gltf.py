"""Findings -> a glTF file (.glb binary, or .gltf JSON with embedded buffers) a person opens in
any viewer to see the clashes.

The file is in metres, as glTF defines its lengths: every coordinate is converted from the
report's unit, which the scene's ``extras`` keep (``{"meshcheck": {"report_units": "mm"}}``), so
the file opens at its true size in any viewer and reads back into meshcheck without a size
warning.

Every part becomes a node named after it: parts in an interference in orange, the others in
translucent grey. Every interference becomes its own red node, named after the finding, holding
the shared solid the verify stage computed (manifold3d intersection of the two closed meshes) or,
when a mesh is not closed, the box of the finding's location. Nothing is computed here.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import trimesh

from .. import results
from ..errors import ConfigError
from ..load import Body
from ..output import check_output, write_output
from ..units import scale

# RGBA, 0-255.
PART_COLOR = (160, 160, 160, 90)
CLASHING_PART_COLOR = (255, 140, 0, 200)
CLASH_COLOR = (230, 0, 0, 255)
#: Least extent of a drawn location box, model units: a flat contact region still draws as a
#: (thin) box rather than a degenerate one viewers drop.
MIN_BOX_EXTENT = 1e-9


def _painted(
    mesh: trimesh.Trimesh, rgba: tuple[int, int, int, int], metres: float
) -> trimesh.Trimesh:
    """``mesh`` scaled by ``metres`` (metres per report unit) with one colour."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64) * metres
    out = trimesh.Trimesh(vertices=vertices, faces=mesh.faces.copy(), process=False)
    material = trimesh.visual.material.PBRMaterial(
        baseColorFactor=list(rgba),
        alphaMode="BLEND" if rgba[3] < 255 else "OPAQUE",
        metallicFactor=0.0,
        roughnessFactor=0.8,
        doubleSided=True,
    )
    out.visual = trimesh.visual.TextureVisuals(material=material)
    return out


def clash_mesh(finding: results.Finding) -> trimesh.Trimesh | None:
    """What draws an interference, world coordinates: its shared solid (``Finding.solid``, from
    the verify stage); the location's box when a mesh is not closed or the boolean failed; None
    when there is neither."""
    if finding.solid is not None:
        solid = finding.solid
        return trimesh.Trimesh(vertices=solid.vertices, faces=solid.faces, process=False)
    loc = finding.location
    if loc is None:
        return None
    extent = np.maximum(np.asarray(loc.upper) - np.asarray(loc.lower), MIN_BOX_EXTENT)
    box = trimesh.creation.box(extents=extent)
    box.apply_translation(0.5 * (np.asarray(loc.lower) + np.asarray(loc.upper)))
    return box


#: File name extension -> trimesh export type.
EXPORT_TYPES = {".glb": "glb", ".gltf": "gltf"}


def export_type(path: str) -> str:
    """``"glb"`` or ``"gltf"`` from the file name, checked with the output rules
    (``output.check_output``) before any work.

    Raises
    ------
    ConfigError
        Another extension, or a path meshcheck does not write to.
    """
    extension = os.path.splitext(path)[1].lower()
    if extension not in EXPORT_TYPES:
        raise ConfigError(path, "the export is written as .glb or .gltf: name the file so")
    check_output(path, what="export")
    return EXPORT_TYPES[extension]


def export_clashes(
    path: str, bodies: Sequence[Body], findings: Sequence[results.Finding], *, units: str
) -> None:
    """Write the assembly with its interferences marked to a glTF file, in metres.

    Parameters
    ----------
    path : str
        Output file: ``.glb`` (binary) or ``.gltf`` (JSON, buffers embedded as data URIs).
    bodies : sequence of Body
        Every part of the assembly.
    findings : sequence of results.Finding
        The check's findings; interference ones are drawn.
    units : str
        The unit of the bodies' world coordinates (the report's, ``CheckResult.units``): the
        file is converted to metres and keeps it in its scene's ``extras``.

    Raises
    ------
    ConfigError
        The extension is neither .glb nor .gltf.
    OutputError
        The file cannot be written.
    """
    file_type = export_type(path)
    by_name = {b.name: b for b in bodies}
    clashes = [f for f in findings if f.status == results.Verdict.INTERFERENCE]
    clashing = {name for f in clashes for name in (f.a, f.b)}
    metres = scale(units, "m")
    scene = trimesh.Scene()
    scene.metadata["meshcheck"] = {"report_units": units}
    for body in bodies:
        color = CLASHING_PART_COLOR if body.name in clashing else PART_COLOR
        painted = _painted(body.world, color, metres)
        scene.add_geometry(painted, node_name=body.name, geom_name=body.name)
    for f in clashes:
        if f.a not in by_name or f.b not in by_name:
            continue
        mesh = clash_mesh(f)
        if mesh is None:
            continue
        name = f"interference {f.a} x {f.b}" + (f" [{f.id}]" if f.id else "")
        name += f" in {f.test}" if f.test else ""  # a clash test's: one node per test
        scene.add_geometry(_painted(mesh, CLASH_COLOR, metres), node_name=name, geom_name=name)
    if file_type == "glb":
        data = scene.export(file_type="glb")
    else:
        data = scene.export(file_type="gltf", embed_buffers=True)["model.gltf"]
    write_output(path, data, what="export")
