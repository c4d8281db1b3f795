"""Files -> bodies: every body in world coordinates, with the name the reports use.

Naming
------
- A part's name is the path exactly as given (``plate.stl``).
- A body inside a file that holds several (GLB/GLTF nodes, 3MF build items, OBJ ``o``/``g``
  objects) is named ``PATH#NODE``, NODE being its scene-graph node name; bodies of one file are
  listed sorted by NODE. A geometry instanced by two nodes gives two parts that share one local
  mesh (``Body.mesh``) and differ by ``Body.transform``.
- A directory argument stands for every supported mesh file below it, recursively, sorted by
  relative path, hidden files and folders skipped; each is named ``os.path.join(ARG, RELPATH)``.
- With ``split=True`` a body made of several disconnected shells becomes one part per shell,
  named ``NAME#1``, ``NAME#2``... in the order of each shell's first triangle in the file. A closed
  inward-facing shell (a cavity lining) inside another shell stays with that shell.

Validation
----------
Every input problem the user can fix is an ``InputError`` (``error: PATH: reason``): missing
paths, unknown extensions, empty or truncated files, binary STL headers that claim more
triangles than the file holds (checked before anything is allocated), files without triangles
(point clouds), NaN or infinite coordinates. Degenerate triangles (repeated vertices or exactly
zero area) are dropped, and meshes that are not closed are kept; both raise a
``MeshcheckWarning`` whose message starts with the part name.
"""

from __future__ import annotations

import functools
import hashlib
import os
import warnings
import zipfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from xml.etree import ElementTree

import numpy as np
import trimesh

from .errors import InputError, MeshcheckWarning

SUPPORTED_EXTENSIONS = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf", ".3mf")

_STL_HEADER = 84  # 80-byte header + uint32 triangle count
_STL_RECORD = 50  # 12 float32 (normal + 3 vertices) + uint16 attribute


@dataclass(frozen=True, eq=False)
class Body:
    """One part of the assembly.

    Attributes
    ----------
    name : str
        ``PATH`` or ``PATH#NODE``.
    path : str
        The file the body came from, as given.
    mesh : trimesh.Trimesh
        Geometry in its own frame, as stored in the file (shared between instances).
    transform : (4, 4) float64
        Homogeneous transform from the mesh's frame to world coordinates.
    """

    name: str
    path: str
    mesh: trimesh.Trimesh
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))

    @functools.cached_property
    def world(self) -> trimesh.Trimesh:
        """The mesh in world coordinates, model units."""
        if np.allclose(self.transform, np.eye(4), rtol=0.0, atol=0.0):
            return self.mesh
        return self.mesh.copy().apply_transform(self.transform)

    @functools.cached_property
    def digest(self) -> str:
        """Hex SHA-256 of the body's own geometry (vertices and faces, frame-local)."""
        return mesh_digest(self.mesh)

    @property
    def is_closed(self) -> bool:
        """True when the mesh is watertight and consistently wound, so it bounds a volume."""
        return bool(self.mesh.is_watertight and self.mesh.is_winding_consistent)


def mesh_digest(mesh: trimesh.Trimesh) -> str:
    """Hash a mesh's vertices and faces (float64 / int64 bytes) into a hex SHA-256."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    return h.hexdigest()


def warn(name: str, reason: str) -> None:
    """Issue a ``MeshcheckWarning`` reading ``NAME: reason``."""
    warnings.warn(MeshcheckWarning(f"{name}: {reason}"), stacklevel=3)


# --------------------------------------------------------------------------------------------
# Paths


def expand_paths(paths: Iterable[str]) -> list[str]:
    """Replace each directory in ``paths`` by the supported mesh files below it.

    Parameters
    ----------
    paths : iterable of str
        Files and directories, as the user gave them.

    Returns
    -------
    files : list of str
        Files in argument order; a directory's files sorted by relative path and joined to it.

    Raises
    ------
    InputError
        A path does not exist, or a directory holds no supported mesh file.
    """
    files: list[str] = []
    for path in paths:
        if os.path.isdir(path):
            found = sorted(_walk_meshes(path))
            if not found:
                exts = ", ".join(SUPPORTED_EXTENSIONS)
                raise InputError(path, f"directory holds no mesh files ({exts})")
            files.extend(os.path.join(path, rel) for rel in found)
        elif os.path.exists(path):
            files.append(path)
        else:
            raise InputError(path, "no such file or directory")
    return files


def _walk_meshes(root: str) -> list[str]:
    """Relative paths of supported mesh files below ``root``, skipping hidden entries."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if not d.startswith(".")]
        rel_dir = os.path.relpath(dirpath, root)
        for name in filenames:
            ext = os.path.splitext(name)[1].lower()
            if name.startswith(".") or ext not in SUPPORTED_EXTENSIONS:
                continue
            out.append(name if rel_dir == os.curdir else os.path.join(rel_dir, name))
    return out


# --------------------------------------------------------------------------------------------
# Loading


def load_bodies(
    paths: Sequence[str],
    *,
    split: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> list[Body]:
    """Load every body of every file, in world coordinates.

    Parameters
    ----------
    paths : sequence of str
        Mesh files and directories, as the user gave them.
    split : bool
        Make every disconnected shell of a body its own part (cavity linings stay with the
        shell around them).
    progress : callable, optional
        Called as ``progress(done, total)`` after each file, counting files.

    Returns
    -------
    bodies : list of Body
        In the order of ``paths``, bodies of one file sorted by node name.

    Raises
    ------
    InputError
        An input cannot be checked; see the module docstring. Two inputs giving the same part
        name are an error too.
    """
    bodies: list[Body] = []
    seen: set[str] = set()
    files = expand_paths(paths)
    for done, path in enumerate(files, start=1):
        for body in load_file(path):
            for part in split_body(body) if split else [body]:
                if part.name in seen:
                    raise InputError(part.name, "given more than once")
                seen.add(part.name)
                bodies.append(part)
        if progress is not None:
            progress(done, len(files))
    return bodies


def load_file(path: str) -> list[Body]:
    """Load the bodies of one mesh file; raise ``InputError`` naming the file when it is unusable.

    Parameters
    ----------
    path : str
        A mesh file with one of ``SUPPORTED_EXTENSIONS``.

    Returns
    -------
    bodies : list of Body
        One body (named ``path``) or, when the file holds several, one per node (``path#NODE``),
        sorted by node name.
    """
    if not os.path.exists(path):
        raise InputError(path, "no such file or directory")
    if os.path.isdir(path):
        raise InputError(path, "is a directory")
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise InputError(
            path, f"unsupported file type {ext or '(no extension)'}; "
            f"supported: {', '.join(SUPPORTED_EXTENSIONS)}"
        )
    try:
        size = os.path.getsize(path)
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if size == 0:
        raise InputError(path, "empty file")
    if ext == ".stl":
        _check_stl_size(path, size)

    if ext == ".3mf":
        items = _read_3mf(path)
    else:
        items = _read_scene(path, ext)

    meshes: dict[int, trimesh.Trimesh] = {}  # cleaned once per geometry, shared by its instances
    bodies = []
    multi = len(items) > 1
    for node, geom, transform in sorted(items, key=lambda item: item[0]):
        name = f"{path}#{node}" if multi else path
        if not np.all(np.isfinite(transform)):
            raise InputError(name, "placement transform holds NaN or infinite values")
        if id(geom) not in meshes:
            meshes[id(geom)] = _clean(geom, name)
        mesh = meshes[id(geom)]
        body = Body(name, path, mesh, transform)
        if not body.is_closed:
            warn(name, "mesh is not closed (not watertight); its findings rest on surfaces only")
        bodies.append(body)
    return bodies


def _check_stl_size(path: str, size: int) -> None:
    """Reject a binary STL whose triangle count disagrees with its size, before reading it."""
    with open(path, "rb") as f:
        head = f.read(_STL_HEADER)
    count = int.from_bytes(head[80:84], "little") if len(head) == _STL_HEADER else None
    if count is not None and size == _STL_HEADER + _STL_RECORD * count:
        if count == 0:
            raise InputError(path, "holds no triangles")
        return  # a well-formed binary STL
    if head.lstrip()[:5].lower() == b"solid":
        return  # ASCII STL: the parser reports what is wrong with it
    if count is None:
        raise InputError(path, f"truncated binary STL: {size} bytes, less than its 84-byte header")
    needed = _STL_HEADER + _STL_RECORD * count
    what = "truncated" if size < needed else "corrupt"
    raise InputError(
        path,
        f"{what} binary STL: header says {count} triangles ({needed} bytes), file has {size} bytes",
    )


def _read_scene(path: str, ext: str) -> list[tuple[str, trimesh.Trimesh, np.ndarray]]:
    """(node name, local mesh, world transform) of every triangle mesh in a file trimesh reads."""
    kwargs = {"split_objects": True, "split_groups": True} if ext == ".obj" else {}
    try:
        scene = trimesh.load_scene(path, process=False, **kwargs)
    except Exception as exc:
        raise InputError(path, f"cannot be read as a mesh: {_one_line(exc)}") from None
    items = []
    has_points = False
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry[geom_name]
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            items.append((str(node), geom, np.asarray(transform, dtype=np.float64)))
        elif isinstance(geom, trimesh.PointCloud) or len(getattr(geom, "vertices", ())):
            has_points = True
    if not items:
        reason = "holds no triangles"
        if has_points:
            reason += " (only points: a point cloud is not a surface)"
        raise InputError(path, reason)
    return items


def _clean(geom: trimesh.Trimesh, name: str) -> trimesh.Trimesh:
    """Validated copy of a mesh: finite, vertices merged, degenerate triangles dropped."""
    vertices = np.asarray(geom.vertices, dtype=np.float64)
    faces = np.asarray(geom.faces, dtype=np.int64)
    if not np.all(np.isfinite(vertices)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(vertices), axis=1)))
        raise InputError(name, f"{bad} vertices have NaN or infinite coordinates")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(name, "triangles refer to vertices that do not exist")
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    f = mesh.faces
    v = mesh.vertices
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    degenerate = repeated | ~np.any(cross != 0.0, axis=1)
    if degenerate.any():
        count = int(degenerate.sum())
        if count == len(f):
            raise InputError(name, "every triangle is degenerate (zero area)")
        warn(name, f"dropped {count} degenerate triangles (zero area or repeated vertices)")
        mesh.update_faces(~degenerate)
        mesh.remove_unreferenced_vertices()
    return mesh


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


# --------------------------------------------------------------------------------------------
# 3MF (zip of XML), read with the standard library


def _read_3mf(path: str) -> list[tuple[str, trimesh.Trimesh, np.ndarray]]:
    """(node name, local mesh, world transform) of every build item of a 3MF file.

    A build item is named by its object's ``name`` attribute (else ``object<ID>``); an object
    made of components gives one body per mesh it reaches, named ``ITEM/COMPONENT``.
    """
    try:
        with zipfile.ZipFile(path) as z:
            model_name = _3mf_model_name(z)
            root = ElementTree.fromstring(z.read(model_name))
    except (zipfile.BadZipFile, KeyError, ElementTree.ParseError, OSError) as exc:
        raise InputError(path, f"cannot be read as 3MF: {_one_line(exc)}") from None

    ns = root.tag[: root.tag.index("}") + 1] if root.tag.startswith("{") else ""
    objects = {}
    for obj in root.iter(f"{ns}object"):
        objects[obj.get("id")] = obj
    meshes: dict[str, trimesh.Trimesh] = {}

    def mesh_of(obj) -> trimesh.Trimesh | None:
        oid = obj.get("id")
        if oid not in meshes:
            m = obj.find(f"{ns}mesh")
            if m is None:
                return None
            try:
                verts = np.array(
                    [[float(v.get(k)) for k in "xyz"] for v in m.iter(f"{ns}vertex")],
                    dtype=np.float64,
                ).reshape(-1, 3)
                tris = np.array(
                    [[int(t.get(k)) for k in ("v1", "v2", "v3")] for t in m.iter(f"{ns}triangle")],
                    dtype=np.int64,
                ).reshape(-1, 3)
            except (TypeError, ValueError) as exc:
                raise InputError(path, f"malformed 3MF mesh: {_one_line(exc)}") from None
            meshes[oid] = trimesh.Trimesh(verts, tris, process=False)
        return meshes[oid]

    def leaves(obj, transform, label, depth=0):
        if depth > 32:
            raise InputError(path, "3MF components nest too deep (a cycle?)")
        mesh = mesh_of(obj)
        if mesh is not None:
            yield label, mesh, transform
            return
        comps = obj.find(f"{ns}components")
        for k, comp in enumerate([] if comps is None else comps.iter(f"{ns}component")):
            child = objects.get(comp.get("objectid"))
            if child is None:
                missing = comp.get("objectid")
                raise InputError(path, f"3MF component refers to missing object {missing}")
            sub = child.get("name") or f"component{k + 1}"
            yield from leaves(
                child, transform @ _3mf_transform(path, comp.get("transform")), f"{label}/{sub}",
                depth + 1,
            )

    items = []
    build = root.find(f"{ns}build")
    for item in [] if build is None else build.iter(f"{ns}item"):
        obj = objects.get(item.get("objectid"))
        if obj is None:
            missing = item.get("objectid")
            raise InputError(path, f"3MF build item refers to missing object {missing}")
        label = obj.get("name") or f"object{obj.get('id')}"
        placement = _3mf_transform(path, item.get("transform"))
        for node, mesh, transform in leaves(obj, placement, label):
            if len(mesh.faces):
                items.append((node, mesh, transform))
    # unique node names: a name used twice gets _2, _3...
    counts: dict[str, int] = {}
    named = []
    for node, mesh, transform in items:
        counts[node] = counts.get(node, 0) + 1
        named.append((node if counts[node] == 1 else f"{node}_{counts[node]}", mesh, transform))
    if not named:
        raise InputError(path, "holds no triangles")
    return named


def _3mf_model_name(z: zipfile.ZipFile) -> str:
    """The archive member holding the 3D model (from _rels/.rels, else 3D/3dmodel.model)."""
    try:
        rels = ElementTree.fromstring(z.read("_rels/.rels"))
        for rel in rels.iter():
            target = rel.get("Target")
            if target and target.lower().endswith(".model"):
                return target.lstrip("/")
    except (KeyError, ElementTree.ParseError):
        pass
    return "3D/3dmodel.model"


def _3mf_transform(path: str, text: str | None) -> np.ndarray:
    """3MF ``transform`` attribute (12 numbers, row-vector convention) -> (4, 4) float64."""
    out = np.eye(4)
    if not text:
        return out
    try:
        m = np.array([float(x) for x in text.split()], dtype=np.float64)
    except ValueError:
        m = np.empty(0)
    if m.shape != (12,):
        raise InputError(path, f"malformed 3MF transform {text!r}")
    m = m.reshape(4, 3)
    out[:3, :3] = m[:3].T
    out[:3, 3] = m[3]
    return out


# --------------------------------------------------------------------------------------------
# Splitting bodies into shells


def split_body(body: Body) -> list[Body]:
    """One body per disconnected shell of ``body`` (see ``split_shells``), named ``NAME#k``."""
    shells = split_shells(body.mesh)
    if len(shells) == 1:
        return [body]
    return [
        Body(f"{body.name}#{k}", body.path, shell, body.transform)
        for k, shell in enumerate(shells, start=1)
    ]


def split_shells(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """Split a mesh into its connected shells, keeping cavity linings with their outer shell.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Vertices merged.

    Returns
    -------
    shells : list of trimesh.Trimesh
        In the order of each part's first triangle in ``mesh``. A closed shell with negative
        signed volume (facing inward) that lies inside a closed outward shell is merged into the
        smallest such shell; every other shell is a part of its own.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(mesh.faces, dtype=np.int64)
    n_v = len(mesh.vertices)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_v, n_v))
    n_comp, vertex_label = connected_components(graph, directed=False)
    face_label = vertex_label[faces[:, 0]]
    if len(np.unique(face_label)) == 1:
        return [mesh]
    # relabel components by first appearance in the face list
    _, first = np.unique(face_label, return_index=True)
    order = np.argsort(first)
    rank = np.empty(n_comp, dtype=np.int64)
    rank[np.unique(face_label)[order]] = np.arange(len(order))
    face_label = rank[face_label]
    n = len(order)

    shells = [mesh.submesh([np.flatnonzero(face_label == k)], append=True) for k in range(n)]
    closed = [bool(s.is_watertight and s.is_winding_consistent) for s in shells]
    volume = [float(s.volume) if c else 0.0 for s, c in zip(shells, closed, strict=True)]
    owner = list(range(n))
    for k in range(n):
        if not closed[k] or volume[k] >= 0.0:
            continue
        point = shells[k].vertices[0]
        containers = [
            j for j in range(n)
            if j != k and closed[j] and volume[j] > 0.0 and _winding_number(shells[j], point) > 0.5
        ]
        if containers:
            owner[k] = min(containers, key=lambda j: volume[j])
    out = []
    for k in range(n):
        if owner[k] != k:
            continue
        members = [j for j in range(n) if owner[j] == k]
        idx = np.flatnonzero(np.isin(face_label, members))
        out.append(mesh.submesh([idx], append=True) if len(members) > 1 else shells[k])
    return out


def _winding_number(mesh: trimesh.Trimesh, point: np.ndarray) -> float:
    """Generalised winding number of a closed mesh around ``point`` (1 inside, 0 outside).

    Sum of the triangles' signed solid angles (Van Oosterom and Strackee, 1983) over 4 pi.
    """
    tri = mesh.vertices[mesh.faces] - np.asarray(point, dtype=np.float64)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (
        la * lb * lc
        + np.einsum("ij,ij->i", a, b) * lc
        + np.einsum("ij,ij->i", b, c) * la
        + np.einsum("ij,ij->i", c, a) * lb
    )
    return float(np.sum(2.0 * np.arctan2(det, den)) / (4.0 * np.pi))
