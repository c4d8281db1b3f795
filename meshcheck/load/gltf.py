"""glTF and GLB: the JSON checked against the budget and walked here, buffers decoded by trimesh.

glTF declares every size before its data: buffer, view and accessor sizes, the node tree and
the meshes each node places. All of it is checked (sizes within the buffers and the limits, the
nodes a tree, the triangles and parts within the run's budget) before trimesh decodes a byte.
The node tree is walked here, in time linear in its size, so placements and names do not
depend on trimesh's scene graph.
"""

from __future__ import annotations

import functools
import io
import json
import math
import os
import struct

import numpy as np
import trimesh
from trimesh.exchange import gltf as trimesh_gltf

from ..errors import InputError
from .limits import Budget, Limits
from .scene import one_line

Item = tuple[str, trimesh.Trimesh, np.ndarray]

_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_SIZE = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_TRIANGLES, _STRIP, _FAN = 4, 5, 6
_TRANSFORM_KEYS = frozenset(("matrix", "translation", "rotation", "scale"))


#: How far a node's rotation quaternion may be from unit length (exporters round it to float32;
#: trimesh normalises it). A zero or far-off quaternion is refused: taken as it is, it would
#: place the part where its author did not.
UNIT_QUATERNION_SLACK = 1e-3


class _Malformed(Exception):
    pass


def read_gltf(path: str, data: bytes, ext: str, budget: Budget) -> list[Item]:
    """(node name, local mesh, placement) of every triangle primitive a glTF/GLB scene places.

    A node is named by its ``name``, else by its index; a name used by an earlier node gets
    ``_2``, ``_3``... A node whose mesh has one triangle primitive is one item named NODE; a mesh
    with several gives ``NODE/0``, ``NODE/1``... by primitive index.
    """
    limits = budget.limits
    try:
        if ext == ".glb":
            header, bin_length = _glb_header(data)
        else:
            header, bin_length = json.loads(data.decode("utf-8")), None
        if not isinstance(header, dict):
            raise _Malformed("the JSON is not an object")
        placed = _check_header(path, header, bin_length, limits, budget)
    except InputError:
        raise
    except (_Malformed, ValueError, TypeError, KeyError, IndexError, AttributeError) as exc:
        raise InputError(path, f"cannot be read as glTF: {one_line(exc)}") from None

    # trimesh decodes the meshes only: it gets one flat node per mesh the scene places, so its
    # work does not grow with the node tree, and the tree (walked above) is never handed to it.
    used = sorted({m for _, m, _ in placed})
    flat = {
        k: v
        for k, v in header.items()
        if k not in ("nodes", "scenes", "scene", "animations", "skins", "cameras")
    }
    flat["nodes"] = [{"mesh": m, "name": f"mesh{m}"} for m in used]
    flat["scenes"] = [{"nodes": list(range(len(used)))}]
    flat["scene"] = 0
    try:
        resolver = trimesh.resolvers.FilePathResolver(path)
        if ext == ".glb":
            kwargs = trimesh_gltf.load_glb(
                io.BytesIO(_glb_with_json(data, flat)), resolver=resolver, skip_materials=True
            )
        else:
            text = json.dumps(flat).encode()
            kwargs = trimesh_gltf.load_gltf(
                io.BytesIO(text), resolver=resolver, skip_materials=True
            )
    except Exception as exc:
        raise InputError(path, f"cannot be read as a mesh: {one_line(exc)}") from None

    primitives = _primitive_geometry({f"mesh{m}": m for m in used}, kwargs)
    node_names = _node_names(header)
    meshes: dict[str, trimesh.Trimesh] = {}
    items = []
    for node, m, transform in placed:
        geoms = primitives.get(m, [])
        for k, geom_name in geoms:
            if geom_name not in meshes:
                geom = kwargs["geometry"][geom_name]
                faces = geom.get("faces") if isinstance(geom, dict) else None
                if faces is None or not len(faces):
                    continue
                meshes[geom_name] = trimesh.Trimesh(geom["vertices"], faces, process=False)
            name = node_names[node]
            items.append((name if len(geoms) == 1 else f"{name}/{k}", meshes[geom_name], transform))
    if not items:
        raise InputError(path, "holds no triangles")
    return items


def _glb_header(data: bytes) -> tuple[dict, int | None]:
    """The JSON chunk of a GLB container, and the length of its BIN chunk (None when absent)."""
    if len(data) < 20 or data[:4] != b"glTF":
        raise _Malformed("not a GLB container (no 'glTF' magic)")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise _Malformed(f"GLB version {version}, only 2 is supported")
    if length > len(data):
        raise _Malformed(f"GLB header says {length} bytes, file has {len(data)}")
    json_length, json_type = struct.unpack_from("<II", data, 12)
    if json_type != 0x4E4F534A or 20 + json_length > length:
        raise _Malformed("the first GLB chunk is not a JSON chunk within the file")
    header = json.loads(data[20 : 20 + json_length].decode("utf-8"))
    bin_length = None
    at = 20 + json_length
    if at + 8 <= length:
        chunk_length, chunk_type = struct.unpack_from("<II", data, at)
        if chunk_type == 0x004E4942:
            bin_length = min(chunk_length, length - at - 8)
    return header, bin_length


def _count(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise _Malformed(f"{what} is {value!r}, not a count")
    return value


def _check_header(path: str, header: dict, bin_length, limits: Limits, budget: Budget):
    """Check sizes and the node tree; return (node index, mesh index, world placement) placed."""
    max_bytes = limits.max_file_bytes
    buffers = header.get("buffers", [])
    buffer_bytes = []
    for i, buf in enumerate(buffers):
        n = _count(buf.get("byteLength"), f"buffer {i} byteLength")
        if n > max_bytes:
            raise InputError(
                path, f"glTF buffer {i} declares {n} bytes, over the limit of {max_bytes}"
            )
        available = _buffer_available(path, buf.get("uri"), bin_length if i == 0 else None)
        if available is not None and available < n:
            raise InputError(
                path, f"glTF buffer {i} declares {n} bytes, its data holds only {available}"
            )
        buffer_bytes.append(n)
    views = header.get("bufferViews", [])
    for i, view in enumerate(views):
        b = _count(view.get("buffer"), f"bufferView {i} buffer")
        start = _count(view.get("byteOffset", 0), f"bufferView {i} byteOffset")
        length = _count(view.get("byteLength"), f"bufferView {i} byteLength")
        if b >= len(buffer_bytes) or start + length > buffer_bytes[b]:
            raise InputError(path, f"glTF bufferView {i} lies outside its buffer")
    accessors = header.get("accessors", [])
    for i, acc in enumerate(accessors):
        count = _count(acc.get("count"), f"accessor {i} count")
        item = _COMPONENT_BYTES[acc["componentType"]] * _TYPE_SIZE[acc["type"]]
        if "bufferView" in acc:
            v = _count(acc["bufferView"], f"accessor {i} bufferView")
            view = views[v]
            stride = _count(view.get("byteStride", item), f"bufferView {v} byteStride")
            start = _count(acc.get("byteOffset", 0), f"accessor {i} byteOffset")
            need = start + (count - 1) * max(stride, item) + item if count else 0
            if need > view["byteLength"]:
                raise InputError(
                    path,
                    f"glTF accessor {i} needs {need} bytes, its bufferView holds "
                    f"{view['byteLength']}",
                )
        elif count * item > max_bytes:
            raise InputError(
                path,
                f"glTF accessor {i} declares {count * item} bytes without a buffer, "
                f"over the limit of {max_bytes}",
            )

    meshes = header.get("meshes", [])
    triangles_of = []
    for mesh in meshes:
        total = 0
        for p in mesh.get("primitives", []):
            mode = p.get("mode", _TRIANGLES)
            index = p["indices"] if "indices" in p else p["attributes"]["POSITION"]
            n = accessors[index]["count"]
            total += (
                n // 3 if mode == _TRIANGLES else max(n - 2, 0) if mode in (_STRIP, _FAN) else 0
            )
        triangles_of.append((total, len(mesh.get("primitives", []))))

    placed = _walk_nodes(path, header)
    triangles = sum(triangles_of[m][0] for _, m, _ in placed)
    parts = sum(triangles_of[m][1] for _, m, _ in placed)
    budget.check_triangles(path, triangles)
    budget.check_parts(path, parts, "placed primitives")
    return placed


def _buffer_available(path: str, uri, bin_length: int | None) -> int | None:
    """Bytes the data behind a buffer holds: the GLB chunk, a data URI, or a file's size."""
    if uri is None:
        return bin_length if bin_length is not None else 0
    if not isinstance(uri, str):
        raise _Malformed(f"buffer uri is {type(uri).__name__}, not a string")
    if uri.startswith("data:"):
        comma = uri.find(",")
        if comma < 0:
            raise _Malformed("data URI without a comma")
        payload = len(uri) - comma - 1
        return payload * 3 // 4 if uri[:comma].endswith(";base64") else payload
    try:  # a file beside the glTF; trimesh's resolver refuses one outside its folder
        from urllib.parse import unquote

        return os.path.getsize(os.path.join(os.path.dirname(os.path.abspath(path)), unquote(uri)))
    except (OSError, ValueError):
        return None  # trimesh reports it


def _node_names(header: dict) -> list[str]:
    """Each node's name: its ``name``, else its index; later repeats get ``_2``, ``_3``..."""
    names, used = [], set()
    for i, node in enumerate(header.get("nodes", [])):
        base = node.get("name")
        base = str(i) if not isinstance(base, str) or not base else base
        name, k = base, 1
        while name in used:
            k += 1
            name = f"{base}_{k}"
        used.add(name)
        names.append(name)
    return names


def _walk_nodes(path: str, header: dict) -> list[tuple[int, int, np.ndarray]]:
    """(node, mesh, world placement) of every node with a mesh under the scene's roots.

    Refuses a node graph that is not a tree (a node reached twice: a cycle or shared child).
    """
    nodes = header.get("nodes", [])
    scenes = header.get("scenes")
    if scenes:
        roots = scenes[_count(header.get("scene", 0), "scene")].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    n_meshes = len(header.get("meshes", []))
    seen = set()
    placed = []
    stack = [(_count(r, "scene node"), np.eye(4)) for r in reversed(roots)]
    while stack:
        i, parent = stack.pop()
        if i >= len(nodes):
            raise _Malformed(f"node {i} does not exist")
        if i in seen:
            raise InputError(path, f"glTF node {i} is reached twice: the nodes do not form a tree")
        seen.add(i)
        node = nodes[i]
        if not node.keys() & _TRANSFORM_KEYS:
            world = parent  # never changed in place: shared by reference
        elif node.keys() & _TRANSFORM_KEYS == {"translation"}:  # the common case, made cheap
            world = parent.copy()
            world[:3, 3] += parent[:3, :3] @ _numbers(node["translation"], 3, "translation")
        else:
            try:
                world = parent @ _local_matrix(node)
            except _Malformed as exc:
                raise _Malformed(f"node {i}: {exc}") from None
        if "mesh" in node:
            m = _count(node["mesh"], f"node {i} mesh")
            if m >= n_meshes:
                raise _Malformed(f"node {i} refers to mesh {m}, which does not exist")
            placed.append((i, m, world))
        stack.extend(
            (_count(c, f"node {i} child"), world) for c in reversed(node.get("children", []))
        )
    return placed


def _local_matrix(node: dict) -> np.ndarray:
    """A node's transform: ``matrix``, else translation @ rotation @ scale (glTF's T * R * S)."""
    if "matrix" in node:
        out = _numbers(node["matrix"], 16, "matrix").reshape(4, 4).T
    else:
        out = np.eye(4)
    if "translation" in node:
        t = np.eye(4)
        t[:3, 3] = _numbers(node["translation"], 3, "translation")
        out = out @ t
    if "rotation" in node:
        out = out @ _rotation_matrix(*(float(c) for c in _numbers(node["rotation"], 4, "rotation")))
    if "scale" in node:
        out = out @ np.diag([*_numbers(node["scale"], 3, "scale"), 1.0])
    return out


@functools.lru_cache(maxsize=4096)
def _rotation_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    """The rotation of a unit quaternion ``(x, y, z, w)`` (glTF's order), 4 x 4; computed once
    per distinct rotation (instances repeat a few). Read-only: callers multiply, never write."""
    if abs(np.linalg.norm([x, y, z, w]) - 1.0) > UNIT_QUATERNION_SLACK:
        raise _Malformed("rotation is not a unit quaternion")
    out = trimesh.transformations.quaternion_matrix([w, x, y, z])
    out.setflags(write=False)
    return out


def _numbers(value, n: int, what: str) -> np.ndarray:
    """``n`` JSON numbers as float64 (JSON numbers are ints and floats; true is not one)."""
    if not isinstance(value, list) or len(value) != n:
        raise _Malformed(f"node {what} is not {n} numbers")
    for x in value:
        if type(x) is not float and type(x) is not int:
            raise _Malformed(f"node {what} is not {n} numbers")
    try:
        out = np.array(value, dtype=np.float64)
    except OverflowError:  # an integer beyond the float range
        raise _Malformed(f"node {what} holds NaN or infinite values") from None
    if not all(map(math.isfinite, out.tolist())):
        raise _Malformed(f"node {what} holds NaN or infinite values")
    return out


def _primitive_geometry(names: dict[str, int], kwargs: dict) -> dict[int, list[tuple[int, str]]]:
    """For each mesh, (primitive position, trimesh geometry name) in primitive order.

    ``names`` maps the node names given to trimesh to mesh indices. trimesh hangs a mesh with
    several primitives under its node through frames with random names; the graph entries, in
    order, identify each node's geometries whatever those frames are called.
    """
    out: dict[int, list[tuple[int, str]]] = {}
    for edge in kwargs.get("graph", []):
        if "geometry" not in edge:
            continue
        to, frm = edge.get("frame_to"), edge.get("frame_from")
        if to in names:
            mesh = names[to]
        elif frm in names:  # a primitive's frame under its multi-primitive node
            mesh = names[frm]
        else:
            continue
        geoms = out.setdefault(mesh, [])
        geoms.append((len(geoms), edge["geometry"]))
    return out


def _glb_with_json(data: bytes, header: dict) -> bytes:
    """The GLB container ``data`` with its JSON chunk replaced by ``header``."""
    json_length = struct.unpack_from("<I", data, 12)[0]
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + json_length :]
    return (
        b"glTF"
        + struct.pack("<II", 2, 20 + len(text) + len(rest))
        + struct.pack("<II", len(text), 0x4E4F534A)
        + text
        + rest
    )
