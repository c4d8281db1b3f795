"""Results -> one self-contained HTML file: a 3D view of the clashes, the findings, the verdict.

The file opens offline in any current browser, from ``file://``: three.js (vendored in
``assets/``, built by ``scripts/build_three.sh`` at a pinned version) and the viewer are inlined,
and a Content-Security-Policy allows only those two scripts and no network at all.

Geometry is stored once per distinct display mesh: instances of one mesh share it, and so do
copies of one mesh that differ only by a translation (STL files of repeated parts, each written in
world coordinates). Vertices are quantized to 16 bits around each mesh's own box centre (which
also becomes the part's position, so three.js sorts translucent parts by their centres), then the
whole geometry is gzipped and base64-encoded; the browser inflates it with ``DecompressionStream``.

Everything that comes from the inputs (part names, paths, approval reasons, warnings, units) is
data: it travels as JSON with ``<``, ``>``, ``&`` and every non-ASCII character escaped, and the
viewer puts it into the page with ``textContent`` only, showing control characters as escapes.
Part names are shown below the folder every part shares (``common.shared_prefix``, named once in
the header), as in the text report, and wrap only after a ``/``; figures are the text every
format prints (``common.figures``: lengths to the report's one resolution).

A run of clash tests also carries its ``tests`` (name, sides and settings, verdict, findings) and
each finding's ``test``; ``tests.js`` and ``tests.css`` (inlined in such a report only) list the
tests in the header and add a filter by test beside the status filters.
"""

from __future__ import annotations

import base64
import gzip
import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from typing import TYPE_CHECKING

import numpy as np

from ..outcome import CheckResult
from ..results import Finding, Verdict, clash_groups
from .common import (
    View,
    audit_rows,
    clash_test_settings,
    elements_text,
    figures,
    ordered,
    pose_text,
    resolution,
    sections,
    shared_prefix,
    summary,
    sweep_rows,
    tolerance_text,
)

if TYPE_CHECKING:
    from ..load import Body

INTERFERENCE, TOUCHING, CLEARANCE = Verdict.INTERFERENCE, Verdict.TOUCHING, Verdict.CLEARANCE

# Two copies of a mesh count as one display mesh when their vertices, each taken relative to its
# own box centre, agree to this fraction of the mesh's size: far below a pixel at any zoom that
# shows the whole part, and above the float32 rounding of an STL copy written 10^4 sizes away.
SAME_SHAPE = 1e-4
# The view holds at most this many part triangles (each distinct mesh counted once): about 20 bytes
# each once quantized, gzipped and base64-encoded, so a report stays near 12 MB whatever the
# input, and a browser draws it smoothly. Larger assemblies are decimated for display only.
DISPLAY_TRIANGLES = 600_000
_CANDIDATES = 8  # earlier distinct meshes a new mesh is compared with, per topology
MIN_TRIANGLES = 500  # a mesh this small is never decimated: it would lose its shape
_QUANT = 32767  # signed 16-bit vertex grid over half of each mesh's largest extent
_SEVERITY = (
    Verdict.DUPLICATE,
    INTERFERENCE,
    CLEARANCE,
    TOUCHING,
)  # colour of a part in several findings


@dataclass
class _Mesh:
    """A distinct display mesh: quantized vertices, faces, and its grid (centre and step)."""

    grid: np.ndarray  # (n, 3) int16
    faces: np.ndarray  # (m, 3) int64
    centre: np.ndarray  # (3,) float64, centre of the mesh's box, frame-local
    step: float


@dataclass
class _Shapes:
    """The distinct display meshes, frame-local, each found once per instance or copy."""

    meshes: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # (vertices, faces)
    relatives: list[np.ndarray] = field(default_factory=list)  # vertices - box centre
    by_topology: dict[tuple, list[int]] = field(default_factory=dict)  # key -> mesh indices
    by_mesh: dict[int, int] = field(default_factory=dict)  # id(Body.mesh) -> mesh index

    def index(self, body: Body) -> tuple[int, np.ndarray]:
        """Index of the body's display mesh, and the frame-local box centre of this copy."""
        v = np.asarray(body.mesh.vertices, dtype=np.float64)
        centre = _box_centre(v)
        k = self.by_mesh.get(id(body.mesh))  # instances of one mesh share it
        if k is None:
            k = self.by_mesh[id(body.mesh)] = self._find_or_add(v, centre, body.mesh.faces)
        return k, centre

    def _find_or_add(self, v: np.ndarray, centre: np.ndarray, faces) -> int:
        """A mesh equal to ``v`` up to a translation (``SAME_SHAPE``), else a new one."""
        f = np.asarray(faces, dtype=np.int64)
        relative = v - centre
        size = float(np.ptp(v, axis=0).max())
        # Same vertex count, faces and (rounded) extents; then at most _CANDIDATES vertex
        # comparisons, so a thousand distinct parts of one topology do not cost n^2.
        extents = np.rint(np.ptp(v, axis=0) / (SAME_SHAPE * max(size, 1e-300)))
        key = (len(v), hashlib.sha256(f.tobytes()).hexdigest(), extents.tobytes())
        same = (
            j
            for j in self.by_topology.get(key, [])[-_CANDIDATES:]
            if np.abs(self.relatives[j] - relative).max(initial=0.0) <= SAME_SHAPE * size
        )
        k = next(same, None)
        if k is None:
            k = len(self.meshes)
            self.meshes.append((v, f))
            self.relatives.append(relative)
            self.by_topology.setdefault(key, []).append(k)
        return k


@dataclass(frozen=True)
class _Placed:
    """A drawn part: its row in the data, its body, display mesh and this copy's box centre."""

    row: dict
    body: Body
    mesh: int
    centre: np.ndarray


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    """The report format's entry (``reports.render``): ``render_html`` of the result's bodies,
    with the installed meshcheck's version."""
    from .. import __version__

    return render_html(
        result, result.bodies, units=result.units, inputs=tuple(inputs), version=__version__
    )


def render_html(
    result: CheckResult,
    bodies: Sequence[Body],
    *,
    units: str = "mm",
    inputs: Sequence[str] = (),
    version: str,
) -> str:
    """Render ``result`` as one HTML document with a 3D view of ``bodies``.

    Parameters
    ----------
    result : CheckResult
        The check's findings and settings; each interference's shared solid and each clearance
        finding's closest points come from its verdict (nothing is computed here).
    bodies : sequence of Body
        The parts the check loaded (``load.load_bodies`` on the same paths); parts are matched to
        findings by name.
    units : str
        Name of the model units, shown beside every length.
    inputs : sequence of str
        The files and directories the user named, listed in the header as given.
    version : str
        meshcheck's version, shown in the header.

    Returns
    -------
    str
        The document, UTF-8 text, ending with a newline. Byte-identical for identical arguments.

    Examples
    --------
    >>> import trimesh
    >>> from meshcheck.load import Body
    >>> from meshcheck.pipeline import check_bodies
    >>> cube = trimesh.creation.box(extents=[1, 1, 1])
    >>> a = Body("a.stl", "a.stl", cube)
    >>> b = Body("b.stl", "b.stl", cube.copy().apply_translation([0.7, 0, 0]))
    >>> result = check_bodies([a, b], jobs=1)
    >>> page = render_html(result, [a, b], inputs=["a.stl", "b.stl"], version="0.1")
    >>> page.startswith("<!DOCTYPE html>"), len(page) < 1_000_000
    (True, True)
    """
    origin = _scene_origin(bodies)
    by_name = {b.name: b for b in bodies}
    shapes = _Shapes()
    parts, placed = _parts(result, bodies, by_name, shapes)
    shown = _simplified(shapes.meshes, budget=DISPLAY_TRIANGLES, tiers=_tiers(placed))
    meshes = [
        _quantize(v, f, centre=_box_centre(original))
        for (v, f), (original, _) in zip(shown, shapes.meshes, strict=True)
    ]
    mesh_rows: list[dict] = [{"matrix": None} for _ in meshes]
    for p in placed:
        step = meshes[p.mesh].step
        local = _translate(p.centre) @ np.diag([step, step, step, 1.0])
        p.row["mesh"] = p.mesh
        p.row["matrix"] = _columns(_translate(-origin) @ np.asarray(p.body.transform) @ local)
    findings = []
    tolerance = resolution(result)
    for f in ordered(result):
        solid = line = None
        if f.a in by_name and f.b in by_name:
            solid = _add_clash(f, origin, meshes, mesh_rows)
            if f.closest is not None:
                line = [_point(p - origin) for p in f.closest]
        row = _finding_row(result, f, origin, solid=solid, line=line)
        row["text"] = figures(f, tolerance)  # as every other format prints them
        if f.elements:
            row["elements"] = elements_text(f)
        findings.append(row)
    blob, layout = _pack(meshes)
    for row, place in zip(mesh_rows, layout, strict=True):
        row.update(place)
    triangles = {
        "parts": sum(len(f) for _, f in shapes.meshes),
        "shown": sum(len(f) for _, f in shown),
    }
    data = _data(result, units, inputs, version, mesh_rows, parts, findings, triangles)
    return _document(_json_for_script(data), blob, has_tests=bool(result.tests))


def _parts(
    result: CheckResult, bodies: Sequence[Body], by_name: Mapping[str, Body], shapes: _Shapes
) -> tuple[list[dict], list[_Placed]]:
    """A row per part (in the result's order), and the parts that have triangles to draw."""
    part_status = _part_statuses(result.findings)
    parts, placed = [], []
    names = [p.name for p in result.parts] or [b.name for b in bodies]
    for name in names:
        body = by_name.get(name)
        row = {"name": name, "mesh": None, "matrix": None, "status": part_status.get(name)}
        if body is not None and len(body.mesh.faces):
            placed.append(_Placed(row, body, *shapes.index(body)))
        parts.append(row)
    return parts, placed


def _tiers(placed: Sequence[_Placed]) -> dict[int, int]:
    """What each display mesh may lose first: 0 in no finding, 1 only touching or approved,
    2 otherwise."""
    tiers: dict[int, int] = {}
    for p in placed:
        tier = {None: 0, TOUCHING: 1, "approved": 1}.get(p.row["status"], 2)
        tiers[p.mesh] = max(tiers.get(p.mesh, 0), tier)
    return tiers


def _add_clash(
    finding: Finding, origin: np.ndarray, meshes: list[_Mesh], mesh_rows: list[dict]
) -> int | None:
    """Add an interference's shared solid (or its box) to the meshes; its index, or None."""
    if finding.status != INTERFERENCE:
        return None
    from .gltf import clash_mesh  # here: trimesh is not imported for the command line's start

    shared = clash_mesh(finding)
    if shared is None or not len(shared.faces):
        return None
    v = np.asarray(shared.vertices, dtype=np.float64) - origin
    mesh = _quantize(v, np.asarray(shared.faces, dtype=np.int64))
    s = mesh.step
    meshes.append(mesh)
    mesh_rows.append({"matrix": _columns(_translate(mesh.centre) @ np.diag([s, s, s, 1.0]))})
    return len(meshes) - 1


def _finding_row(
    result: CheckResult, f: Finding, origin: np.ndarray, *, solid: int | None, line
) -> dict:
    box = None
    if f.location is not None:
        box = [
            _point(np.asarray(f.location.lower) - origin),
            _point(np.asarray(f.location.upper) - origin),
        ]
    return {
        "id": f.id,
        "a": f.a,
        "b": f.b,
        "status": str(f.status),
        "distance": _number(f.distance),
        "depth": _number(f.depth),
        "volume": _number(f.volume),
        "surface_only": f.is_surface_only,
        "approved": f.approval_reason,
        "fails": result.is_failing(f),
        "box": box,
        "solid": solid,
        "line": line,
        **({"test": f.test} if f.test else {}),
    }


def _data(result, units, inputs, version, mesh_rows, parts, findings, triangles) -> dict:
    """Everything the viewer shows but the geometry, as one JSON document."""
    s = summary(result)
    s["tolerance"] = _number(s["tolerance"])
    s["required_clearance"] = _number(s["required_clearance"])
    settings = {  # as the text report's summary prints them
        "tolerance": tolerance_text(result),
        "clearance": None if result.clearance is None else f"{result.clearance:g}",
    }
    if result.tests:  # each test has its own (the header lists them): "per test, in mm"
        settings = {"tolerance": "per test, in", "clearance": "per test, in"}
        s["fail_on"] = ["per test"]
    data = {
        "version": str(version),
        "units": str(units),
        "inputs": [str(x) for x in inputs],
        "prefix": shared_prefix([p["name"] for p in parts]),
        "summary": s,
        "settings_text": settings,
        "meshes": mesh_rows,
        "parts": parts,
        "findings": findings,
        "groups": [g.to_dict() for g in clash_groups(ordered(result))],
        "triangles": triangles,
        "sweeps": _sweeps(result),
        "poses": [{"robot": str(p.path), "text": p.text()} for p in result.poses],
        "audit": _audit(result),
    }
    if result.tests:
        data["tests"] = [
            {
                "name": section.test.name,
                "settings": clash_test_settings(section.test),
                "passed": section.passed,
                "findings": len(section.findings),
            }
            for section in sections(result)
        ]
    return data


def _audit(result: CheckResult) -> dict | None:
    """The SRDF audit as the viewer shows it: its summary line and the entries not proven
    never (``audit_rows``), failing ones first."""
    if result.audit is None:
        return None
    return {
        "summary": result.audit.summary(),
        "rows": [
            {
                "a": str(pair.a),
                "b": str(pair.b),
                "reason": pair.reason or "no reason",
                "line": pair.line,
                "status": str(pair.status),
                "pose": pose_text(pair.sweep),
                "failed": fails,
            }
            for pair, fails in audit_rows(result)
        ],
    }


def _sweeps(result: CheckResult) -> list[dict]:
    """The swept link pairs not proven never (``sweep_rows``), failing ones first, as the
    viewer lists them: names and the witness pose as text (``--pose`` form)."""
    return [
        {
            "robot": str(robot),
            "a": str(pair.a),
            "b": str(pair.b),
            "status": str(pair.status),
            "adjacent": bool(pair.is_adjacent),
            "pose": pose_text(pair),
            "approved": pair.approval_reason,
            "failed": fails,
        }
        for robot, pair, fails in sweep_rows(result)
    ]


# ---------------------------------------------------------------------------------------------
# geometry


def _scene_origin(bodies: Sequence[Body]) -> np.ndarray:
    """Centre of the assembly's box, world coordinates: the view works relative to it, so
    float32 on the GPU keeps its digits for assemblies far from the origin."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for body in bodies:
        if not len(body.mesh.vertices):
            continue
        corners = np.array(np.meshgrid(*np.asarray(body.mesh.bounds).T)).reshape(3, -1).T
        world = corners @ np.asarray(body.transform)[:3, :3].T + np.asarray(body.transform)[:3, 3]
        lo, hi = np.minimum(lo, world.min(axis=0)), np.maximum(hi, world.max(axis=0))
    return 0.5 * (lo + hi) if np.all(np.isfinite(lo)) else np.zeros(3)


def _simplified(
    shapes: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    budget: int,
    tiers: Mapping[int, int] | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The display meshes, within about ``budget`` triangles together.

    First each mesh over ``MIN_TRIANGLES`` is decimated to its share (quadric error,
    fast_simplification); that stops early on long thin CAD triangles, so if the total is still
    over, meshes are drawn as their convex hulls until it is not: those of tier 0 (parts in no
    finding, shown for context) largest first, then tier 1 (parts only touching or approved).
    Meshes of higher tiers (parts in an interference or clearance finding) keep their shape.
    """
    tiers = {} if tiers is None else tiers
    total = sum(len(f) for _, f in shapes)
    if total <= budget:
        return list(shapes)
    small = sum(len(f) for _, f in shapes if len(f) <= MIN_TRIANGLES)
    share = max(budget - small, 0) / max(total - small, 1)
    out = []
    for v, f in shapes:
        target = max(MIN_TRIANGLES, int(len(f) * share))
        if len(f) > target:
            import trimesh

            mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
            mesh = mesh.simplify_quadric_decimation(face_count=target)
            v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
        out.append((v, f))
    total = sum(len(f) for _, f in out)
    for k in sorted(range(len(out)), key=lambda k: (tiers.get(k, 0), -len(out[k][1]))):
        if total <= budget or tiers.get(k, 0) > 1:
            break
        hull = _hull(out[k][0])
        if hull is not None and len(hull[1]) < len(out[k][1]):
            total += len(hull[1]) - len(out[k][1])
            out[k] = hull
    return out


def _hull(v: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Convex hull (vertices, faces) of a point set; None when it is flat. Faces are not
    consistently wound: the view draws both sides."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        simplices = ConvexHull(v).simplices
    except (QhullError, ValueError):
        return None
    used, faces = np.unique(simplices, return_inverse=True)
    return np.asarray(v[used], np.float64), faces.reshape(-1, 3).astype(np.int64)


def _box_centre(v: np.ndarray) -> np.ndarray:
    return 0.5 * (v.min(axis=0) + v.max(axis=0)) if len(v) else np.zeros(3)


def _quantize(v: np.ndarray, f: np.ndarray, *, centre: np.ndarray | None = None) -> _Mesh:
    """Vertices on a signed 16-bit grid around ``centre`` (default: the box centre), one step for
    all three axes (a uniform scale keeps angles, so flat shading and edges see the true shape)."""
    centre = _box_centre(v) if centre is None else centre
    relative = v - centre
    half = float(np.abs(relative).max(initial=0.0))
    step = half / _QUANT if half > 0 else 1.0
    grid = np.clip(np.rint(relative / step), -_QUANT, _QUANT).astype(np.int16)
    return _Mesh(grid, f, centre, step)


def _pack(meshes: Sequence[_Mesh]) -> tuple[str, list[dict]]:
    """All meshes in one gzipped, base64-encoded buffer, and where each one's arrays start."""
    chunks, layout, offset = [], [], 0

    def put(array: np.ndarray) -> int:
        nonlocal offset
        start = offset
        raw = array.tobytes()
        pad = -len(raw) % 4  # typed-array views need aligned offsets
        chunks.append(raw + b"\0" * pad)
        offset += len(raw) + pad
        return start

    for m in meshes:
        is_wide = len(m.grid) > 65536
        faces = m.faces.astype(np.uint32 if is_wide else np.uint16)
        pos = put(np.ascontiguousarray(m.grid, dtype="<i2"))
        idx = put(np.ascontiguousarray(faces, dtype="<u4" if is_wide else "<u2"))
        layout.append(
            {"pos": pos, "idx": idx, "nv": len(m.grid), "nf": len(m.faces), "wide": is_wide}
        )
    packed = gzip.compress(b"".join(chunks), compresslevel=9, mtime=0)
    return base64.b64encode(packed).decode("ascii"), layout


def _part_statuses(findings: Sequence[Finding]) -> dict[str, str]:
    """Each part's colour: its most severe unapproved finding, else ``approved``."""
    status: dict[str, str] = {}
    for f in findings:
        key = "approved" if f.is_approved else str(f.status)
        for name in (f.a, f.b):
            old = status.get(name)
            if old is None or _rank(key) < _rank(old):
                status[name] = key
    return status


def _rank(status: str) -> int:
    return _SEVERITY.index(status) if status in _SEVERITY else len(_SEVERITY)


def _translate(t: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


def _columns(m: np.ndarray) -> list[float]:
    """A 4x4 matrix column-major, as three.js reads it."""
    return [float(f"{x:.10g}") for x in np.asarray(m, dtype=np.float64).T.ravel()]


def _point(p: np.ndarray) -> list[float]:
    return [float(f"{x:.10g}") for x in p]


def _number(x: float | None) -> float | None:
    """JSON has no infinity or NaN: those become null (shown as a dash)."""
    return None if x is None or not math.isfinite(x) else float(x)


# ---------------------------------------------------------------------------------------------
# the document


def _json_for_script(data: dict) -> str:
    """JSON that cannot end its <script> element or be read as HTML: ``<``, ``>``, ``&`` and
    every non-ASCII character (U+2028 and U+2029 included) as ``\\uXXXX`` escapes."""
    text = json.dumps(data, ensure_ascii=True, allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _asset(name: str) -> str:
    return (resources.files(__package__) / "assets" / name).read_text(encoding="utf-8")


def _script(text: str) -> str:
    """A script's text, checked to be inlinable: no ``</script`` and no ``<!--`` inside."""
    lowered = text.lower()
    if "</script" in lowered or "<!--" in lowered:
        raise ValueError("an inlined script contains '</script' or '<!--'")
    return text


def _csp_hash(text: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def _document(data_json: str, blob: str, *, has_tests: bool = False) -> str:
    license_text = _asset("three.LICENSE").replace("*/", "* /")
    three = _script(f"/*\n{license_text}*/\n" + _asset("three.min.js"))
    viewer = _script(_asset("viewer.js"))
    style = _asset("viewer.css")
    scripts, styles = [three, viewer], [style]
    if has_tests:  # a run of clash tests: its tests in the header, the filter by test
        scripts.append(_script(_asset("tests.js")))
        styles.append(_asset("tests.css"))
    csp = "; ".join(
        [
            "default-src 'none'",
            "script-src " + " ".join(_csp_hash(text) for text in scripts),
            "style-src " + " ".join(_csp_hash(text) for text in styles),
            "img-src data:",
        ]
    )
    style_tags = "".join(f"<style>{text}</style>" for text in styles)
    script_tags = "".join(f"<script>{text}</script>\n" for text in scripts)
    headings = "".join(
        f"<th>{h}</th>"
        for h in ("ID", "Status", "Parts", "Depth", "Volume", "Distance", "Approved")
    )
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{csp}">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>meshcheck report</title>
{style_tags}
</head>
<body>
<header id="header"></header>
<div id="main">
<div id="view"><button id="home" type="button">Reset view</button><span class="hint">drag: \
rotate &middot; right-drag: pan &middot; wheel: zoom &middot; click a finding or a group to \
frame it</span></div>
<div id="side"><div id="filters"></div><div id="table-wrap"><table id="findings">
<thead><tr>{headings}</tr></thead><tbody></tbody></table><div id="groups"></div></div></div>
</div>
<script type="application/json" id="meshcheck-data">{data_json}</script>
<script type="application/octet-stream" id="meshcheck-geometry">{blob}</script>
{script_tags}</body>
</html>
"""


__all__ = ["render", "render_html"]
