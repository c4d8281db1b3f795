"""STL, OBJ, PLY and OFF files through trimesh, after checking the counts their headers declare."""

from __future__ import annotations

import io
import re
from typing import NamedTuple

import numpy as np
import trimesh

from ..errors import InputError
from .limits import Budget

STL_HEADER = 84  # 80-byte header + uint32 triangle count
STL_RECORD = 50  # 12 float32 (normal + 3 vertices) + uint16 attribute

Item = tuple[str, trimesh.Trimesh, np.ndarray]  # (node name, local mesh, placement)


def read_scene(path: str, data: bytes, ext: str, budget: Budget) -> list[Item]:
    """(node name, local mesh, placement) of every triangle mesh in an STL/OBJ/PLY/OFF file.

    Node names are trimesh's: STL ``solid`` names, OBJ ``o``/``g`` names, made unique in file
    order; a file that holds one mesh has one item whatever its node is called.
    """
    kwargs = {}
    if ext == ".stl":
        if not _check_stl(path, data, budget):
            return [("geometry_0", _binary_stl(data), np.eye(4))]
        data = _as_utf8(data)
    elif ext == ".ply":
        _check_ply(path, data, budget)
    elif ext == ".off":
        _check_off(path, data, budget)
        data = _as_utf8(data)
    elif ext == ".obj":
        kwargs = {"split_objects": True, "split_groups": True}
        data = absolute_obj_indices(path, _as_utf8(data))
    try:
        scene = trimesh.load_scene(io.BytesIO(data), file_type=ext[1:], process=False, **kwargs)
    except InputError:
        raise
    except Exception as exc:
        raise InputError(path, f"cannot be read as a mesh: {one_line(exc)}") from None
    items = []
    has_points = False
    for node in sorted(scene.graph.nodes_geometry):
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


_RELATIVE_INDEX = re.compile(rb"^[ \t]*[flp][ \t][^\n]*-[0-9]", re.MULTILINE)
_ELEMENT = {b"v": 0, b"vt": 1, b"vn": 2}


def absolute_obj_indices(path: str, data: bytes) -> bytes:
    r"""An OBJ file's text with every relative (negative) index made absolute.

    The format counts ``-k`` back from the elements read *so far* (``v``, ``vt`` and ``vn``
    each in its own list), so an object written as its own vertices then ``f -8 ... -1`` refers
    to those vertices. trimesh resolves negatives against the whole file's lists (trimesh issue
    2364), which would give every such object the last object's vertices; absolute indices mean
    the same to both. Text without a negative index in a face, line or point statement is
    returned as it is.

    Raises
    ------
    InputError
        A relative index reaches before the first element read so far.

    Examples
    --------
    >>> text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nvn 0 0 1\nf 1 -3//-1 4\n"
    >>> absolute_obj_indices("x.obj", text).decode().splitlines()[3::3]
    ['f 1 2 3', 'f 1 2//1 4']
    """
    if not _RELATIVE_INDEX.search(data):
        return data
    counts = [0, 0, 0]
    lines = data.split(b"\n")
    for k, line in enumerate(lines):
        words = line.split()
        if not words:
            continue
        kind = _ELEMENT.get(words[0])
        if kind is not None:
            counts[kind] += 1
        elif words[0] in (b"f", b"l", b"p") and b"-" in line:
            lines[k] = b" ".join([words[0], *(_absolute(w, counts, path, k) for w in words[1:])])
    return b"\n".join(lines)


def _absolute(word: bytes, counts: list[int], path: str, line: int) -> bytes:
    """One ``v/vt/vn`` reference with its negative parts counted from ``counts``."""
    parts = word.split(b"/")
    for n, part in enumerate(parts[:3]):
        if part.startswith(b"-") and part[1:].isdigit():
            index = counts[n] + 1 + int(part)
            if index < 1:
                raise InputError(
                    path,
                    f"line {line + 1}: index {part.decode()} reaches before the first "
                    f"{('vertex', 'texture coordinate', 'normal')[n]}",
                )
            parts[n] = b"%d" % index
    return b"/".join(parts)


class Soup(NamedTuple):
    """A mesh as arrays, before cleaning (what ``clean_arrays`` reads of a ``trimesh.Trimesh``)."""

    vertices: np.ndarray
    faces: np.ndarray


def _binary_stl(data: bytes) -> Soup:
    """The triangles of a binary STL ``_check_stl`` accepted, parsed by trimesh's reader alone
    (the scene trimesh would build around them costs more than the parse)."""
    from trimesh.exchange.stl import load_stl_binary

    loaded = load_stl_binary(io.BytesIO(data))
    return Soup(loaded["vertices"], loaded["faces"])


def _check_stl(path: str, data: bytes, budget: Budget) -> bool:
    """Check a binary STL's count against its size and the budget; True for an ASCII STL."""
    size = len(data)
    head = data[:STL_HEADER]
    count = int.from_bytes(head[80:84], "little") if len(head) == STL_HEADER else None
    if count is not None and size == STL_HEADER + STL_RECORD * count:
        if count == 0:
            raise InputError(path, "holds no triangles")
        budget.check_triangles(path, count)
        return False  # a well-formed binary STL
    if head.lstrip()[:5].lower() == b"solid" and _is_text(data[: 1 << 16]):
        return True  # ASCII STL: the parser reports what is wrong with it
    if count is None:
        raise InputError(path, f"truncated binary STL: {size} bytes, less than its 84-byte header")
    needed = STL_HEADER + STL_RECORD * count
    what = "truncated" if size < needed else "corrupt"
    raise InputError(
        path,
        f"{what} binary STL: header says {count} triangles ({needed} bytes), file has {size} bytes",
    )


def stores_float32(ext: str, data: bytes) -> bool:
    """Whether an STL/OBJ/PLY/OFF file stores its coordinates as float32: a binary STL (its
    size matches its triangle count), a PLY whose vertex ``x`` is ``float``/``float32``.
    Text coordinates (ASCII STL, OBJ, OFF, ASCII PLY) are read in double."""
    if ext == ".stl":
        head = data[:STL_HEADER]
        count = int.from_bytes(head[80:84], "little") if len(head) == STL_HEADER else -1
        return len(data) == STL_HEADER + STL_RECORD * count
    if ext == ".ply":
        header = data[: max(data.find(b"end_header", 0, 1 << 20), 0)]
        return re.search(rb"property[ \t]+float(32)?[ \t]+x\s", header) is not None
    return False


def _is_text(block: bytes) -> bool:
    """True when a block holds no NUL or other control bytes but tab, CR, LF, FF."""
    return not re.search(rb"[\x00-\x08\x0b\x0e-\x1f\x7f]", block)


def _as_utf8(data: bytes) -> bytes:
    """Text bytes as UTF-8: bytes that are not UTF-8 are read as Latin-1 (every byte is one)."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")
    return data


_PLY_SIZES = {
    "char": 1, "uchar": 1, "int8": 1, "uint8": 1,
    "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
    "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
    "double": 8, "float64": 8,
}  # fmt: skip


def _check_ply(path: str, data: bytes, budget: Budget) -> None:
    """Refuse a PLY whose header declares more elements than its body can hold, or than allowed."""
    end = data.find(b"end_header", 0, 1 << 20)
    if not data.startswith(b"ply") or end < 0:
        raise InputError(path, "not a PLY file (no 'ply' ... 'end_header' header)")
    lines = data[:end].decode("latin-1").splitlines()
    binary = any(
        line.split()[:2] in (["format", "binary_little_endian"], ["format", "binary_big_endian"])
        for line in lines
    )
    elements: list[list] = []  # [name, count, minimal bytes per element]
    try:
        for line in lines:
            words = line.split()
            if words[:1] == ["element"]:
                elements.append([words[1], int(words[2]), 0])
            elif words[:1] == ["property"] and elements:
                if words[1] == "list":  # a count, then possibly no items
                    elements[-1][2] += _PLY_SIZES[words[2]]
                else:
                    elements[-1][2] += _PLY_SIZES[words[1]]
    except (IndexError, ValueError, KeyError):
        raise InputError(path, f"malformed PLY header line {line[:60]!r}") from None
    body = len(data) - end - len("end_header")
    need = sum(count * (per if binary else 2) for _, count, per in elements)
    if any(count < 0 for _, count, _ in elements) or need > body:
        declared = ", ".join(f"{count} {name}" for name, count, _ in elements)
        raise InputError(
            path, f"PLY header declares {declared} (at least {need} bytes), file holds {body}"
        )
    faces = sum(count for name, count, _ in elements if name == "face")
    budget.check_triangles(path, faces, "faces")


def _check_off(path: str, data: bytes, budget: Budget) -> None:
    """Refuse an OFF whose header counts exceed what its body can hold, or what is allowed."""
    words = []
    for line in data[: 1 << 16].split(b"\n"):
        line = line.split(b"#")[0].strip()
        if line:
            words.extend(line.split())
        if len(words) >= 3 + (words[:1] and words[0].upper().endswith(b"OFF")):
            break
    if words and words[0].upper().endswith(b"OFF"):
        words = words[1:]
    try:
        n_vertices, n_faces = int(words[0]), int(words[1])
    except (IndexError, ValueError):
        raise InputError(path, "malformed OFF header (no vertex and face counts)") from None
    if n_vertices < 0 or n_faces < 0 or 2 * (n_vertices + n_faces) > len(data):
        raise InputError(
            path,
            f"OFF header declares {n_vertices} vertices and {n_faces} faces, "
            f"more than its {len(data)} bytes can hold",
        )
    budget.check_triangles(path, n_faces, "faces")


def one_line(exc: BaseException) -> str:
    """An exception's message on one line, at most 160 characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."
