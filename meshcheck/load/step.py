"""STEP files -> solids: tessellated by OpenCASCADE (``cascadio``), closed, in the file's own unit.

Reading
-------
``cascadio`` (OpenCASCADE's STEP reader and mesher) turns the file into a GLB, which trimesh
loads as a Scene: one geometry per solid instance, keyed by the STEP product name (made unique by
trimesh in document order: ``bolt``, ``bolt_1``...), placed by the assembly's transforms. The
Scene's node names are OCAF labels (``=>[0:1:1:3]``), so names come from the geometry keys.

Units
-----
OpenCASCADE converts every length to millimetres and the GLB to metres. ``read_step`` converts
back to the length unit the file declares (its ``GLOBAL_UNIT_ASSIGNED_CONTEXT``), read from the
file's text, so that a millimetre STEP gives millimetres. The GLB stores coordinates as float32:
every coordinate carries a relative rounding error of at most 2**-24 (60 nm on a part 1 m from
its origin).

Tessellation
------------
The chords of a curved face lie inside it, by at most the linear deflection: a pin in a hole,
both faceted, shows a gap up to one deflection wider (or an overlap up to two deflections
shallower) than the CAD model. The default, ``DEFAULT_DEFLECTION_MM``, keeps a 0.1 mm clearance
within 0.01 mm and a 0.2 mm interference within 0.03 mm (tests/test_step.py); the value used is
``StepAssembly.deflection``, in the file's unit.

Closed solids
-------------
Faces are tessellated one by one: each face has its own copy of the vertices of the edges it
shares, and a few triangles collapse to slivers. Vertices closer than a tolerance far below the
deflection are merged (in float64), degenerate triangles dropped, and a closed solid comes out
closed: every edge used by exactly two triangles, consistently wound, facing out.

Messages
--------
OpenCASCADE prints its diagnostics on the process's standard output and error streams (file
descriptors 1 and 2), where the report goes. They are captured while cascadio runs, and the first
error line becomes the reason of the ``InputError`` for a broken file.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import hmac
import io
import json
import os
import re
import sys
import tempfile
import warnings
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import trimesh

from ..errors import InputError, MeshcheckWarning

STEP_EXTENSIONS = (".step", ".stp")

# Linear deflection used when none is given: the largest distance between a curved face and its
# triangles. 0.005 mm keeps a measured 0.1 mm clearance within 0.01 mm (a pin and its hole are
# both faceted: the gap can widen by the hole's sag) and a 0.2 mm depth within 0.03 mm; see
# bench/step.py for what it costs.
DEFAULT_DEFLECTION_MM = 0.005
# Angular deflection, radians: the largest angle between neighbouring facets' normals. cascadio's
# default; it only refines small radii, where the linear deflection already holds.
DEFAULT_ANGULAR_DEFLECTION = 0.5

# Length units a STEP file can declare, by the names meshcheck reports: metres per unit.
UNIT_METRES = {
    "nm": 1e-9,
    "um": 1e-6,
    "mm": 1e-3,
    "cm": 1e-2,
    "dm": 1e-1,
    "m": 1.0,
    "km": 1e3,
    "in": 0.0254,
    "ft": 0.3048,
    "yd": 0.9144,
    "mi": 1609.344,
    "mil": 2.54e-5,
}
_SI_PREFIX = {
    "$": "m",
    ".NANO.": "nm",
    ".MICRO.": "um",
    ".MILLI.": "mm",
    ".CENTI.": "cm",
    ".DECI.": "dm",
    ".KILO.": "km",
}
_CONVERSION_NAMES = {
    "INCH": "in",
    "INCHES": "in",
    "FOOT": "ft",
    "FEET": "ft",
    "YARD": "yd",
    "MILE": "mi",
    "MIL": "mil",
    "THOU": "mil",
    "MILLIMETRE": "mm",
    "MILLIMETER": "mm",
    "CENTIMETRE": "cm",
    "CENTIMETER": "cm",
    "METRE": "m",
    "METER": "m",
    "MICRON": "um",
}
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
        The length unit the file declares, a key of ``UNIT_METRES`` (``"mm"`` when it declares
        none that is recognised, with a warning).
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
    angular_deflection: float | None = None,
    cache: TessellationCache | None = None,
) -> StepAssembly:
    """Tessellate the solids of a STEP file, in the unit the file declares.

    Parameters
    ----------
    path : str
        A STEP (ISO 10303-21) file.
    deflection : float, optional
        Largest distance between a curved face and its triangles, in ``deflection_unit``.
        Default ``DEFAULT_DEFLECTION_MM`` millimetres.
    deflection_unit : str, optional
        Unit of ``deflection``, a key of ``UNIT_METRES``; default the file's own unit.
    angular_deflection : float, optional
        Largest angle between neighbouring facets, radians; default
        ``DEFAULT_ANGULAR_DEFLECTION``.
    cache : TessellationCache, optional
        Where tessellations are kept, by file content and settings.

    Returns
    -------
    StepAssembly

    Raises
    ------
    InputError
        The file cannot be read, is not STEP, or holds no solid.
    ValueError
        ``deflection`` or ``angular_deflection`` is not a positive finite number, or
        ``deflection_unit`` is unknown (options are the caller's to validate).

    Examples
    --------
    >>> asm = read_step("sample_meshes/assembly.step")
    >>> asm.unit, [name for name, _, _ in asm.items][:3]
    ('mm', ['bolt_m6', 'bolt_m6_1', 'bolt_m6_2'])
    """
    if deflection_unit is not None and deflection_unit not in UNIT_METRES:
        raise ValueError(f"unknown length unit {deflection_unit!r}")
    for value in (deflection, angular_deflection):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"deflection must be a positive number, not {value!r}")
    angular = (
        DEFAULT_ANGULAR_DEFLECTION if angular_deflection is None else float(angular_deflection)
    )
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if not data:
        raise InputError(path, "empty file")

    declared = _declared_unit(data)
    unit = declared or "mm"
    scale = UNIT_METRES[unit]  # metres per file unit
    if deflection is None:
        deflection_mm = DEFAULT_DEFLECTION_MM
    else:
        given_unit = unit if deflection_unit is None else deflection_unit
        deflection_mm = float(deflection) * UNIT_METRES[given_unit] / 1e-3
    deflection_file = deflection_mm * 1e-3 / scale

    key = tessellation_key(data, deflection_mm, angular) if cache is not None else ""
    assembly = cache.get(key) if cache is not None else None
    if assembly is None or assembly.unit != unit:
        scene = _tessellate(data, path, deflection_mm, angular)
        items = _items(scene, path, scale, deflection_file)
        assembly = StepAssembly(items, unit, deflection_file, angular)
        if cache is not None:
            cache.put(key, assembly)
    if declared is None:
        _warn_no_unit(path)
    return assembly


# --------------------------------------------------------------------------------------------
# Tessellation


def _tessellate(data: bytes, path: str, deflection_mm: float, angular: float) -> trimesh.Scene:
    """The GLB Scene cascadio makes of ``data`` (lengths in metres); InputError when unreadable."""
    import cascadio

    with _captured_output() as messages:
        # OpenCASCADE works in millimetres whatever the file's unit: the deflection is in mm.
        # One thread: the same file gives the same triangles, so finding IDs stay put.
        glb = cascadio.load(
            data,
            file_type="step",
            tol_linear=deflection_mm,
            tol_angular=angular,
            tol_relative=False,
            merge_primitives=True,
            use_parallel=False,
        )
    if not glb:
        raise InputError(path, f"cannot be read as STEP: {_first_error(messages())}")
    try:
        return trimesh.load_scene(io.BytesIO(glb), file_type="glb", process=False)
    except Exception as exc:  # the GLB comes from cascadio: a failure here is its bug or ours
        raise InputError(path, f"cannot be read as STEP: {_one_line(exc)}") from None


def _items(
    scene: trimesh.Scene, path: str, scale: float, deflection: float
) -> list[tuple[str, trimesh.Trimesh, np.ndarray]]:
    """(unique product name, closed local mesh, transform) per solid instance, file units."""
    instances = []
    for node in scene.graph.nodes_geometry:
        transform, key = scene.graph[node]
        geom = scene.geometry[key]
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            instances.append((_safe_name(key), geom, np.array(transform, dtype=np.float64)))
    if not instances:
        raise InputError(path, "holds no solids (nothing OpenCASCADE could tessellate)")
    # Deterministic order whatever the hash seed: by product name, then placement.
    instances.sort(key=lambda item: (item[0], item[2].tobytes()))

    meshes: dict[bytes, trimesh.Trimesh] = {}  # one closed mesh per distinct geometry
    items = []
    used: set[str] = set()
    for name, geom, transform in instances:
        vertices = _from_metres(geom.vertices, scale)
        faces = np.asarray(geom.faces, dtype=np.int64)
        if not np.all(np.isfinite(vertices)):
            raise InputError(f"{path}#{name}", "vertices have NaN or infinite coordinates")
        digest = hashlib.sha256(vertices.tobytes() + faces.tobytes()).digest()
        if digest not in meshes:
            meshes[digest] = close_mesh(vertices, faces, deflection)
        transform[:3, 3] = _from_metres(transform[:3, 3], scale)
        if not np.all(np.isfinite(transform)):
            raise InputError(f"{path}#{name}", "placement transform holds NaN or infinite values")
        items.append((_unique(name, used), meshes[digest], transform))
    items.sort(key=lambda item: item[0])
    return items


def _from_metres(values, scale: float) -> np.ndarray:
    """Float32 metres (as the GLB holds them) -> float64 file units, at float32 precision.

    Rounding to the nearest float32 in the file's unit gives back the CAD value when that value
    is a float32 (30 mm, not 29.9999993 mm), and stays within 2**-23 of it otherwise.
    """
    return (np.asarray(values, dtype=np.float64) / scale).astype(np.float32).astype(np.float64)


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
        (or than the float32 resolution of the coordinates, if larger) are one point.

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
    tol = max(0.01 * deflection, 2.0**-20 * extent)
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
        return _CONVERSION_NAMES.get(conversion.group(1).strip().upper())
    si = _SI_LENGTH.search(body)
    if si is not None:
        return _SI_PREFIX.get(si.group(1))
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


# --------------------------------------------------------------------------------------------
# Cache

# Bump when an entry's layout or the meaning of its meshes changes (the welding, the naming).
FORMAT_VERSION = 1


def tessellation_key(data: bytes, deflection_mm: float, angular: float) -> str:
    """Key of a tessellation: hex SHA-256 of the file's content, settings and library versions."""
    payload = {
        "format": FORMAT_VERSION,
        "cascadio": _version("cascadio"),
        "trimesh": _version("trimesh"),
        "content": hashlib.sha256(data).hexdigest(),
        "deflection_mm": float(deflection_mm).hex(),
        "angular": float(angular).hex(),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@functools.cache
def _version(package: str) -> str:
    import importlib.metadata

    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover - required dependencies
        return "unknown"


_ARRAYS = [
    "checksum",
    "face_starts",
    "faces",
    "header",
    "mesh_of",
    "transforms",
    "vertex_starts",
    "vertices",
]


#: A tessellation cache entry larger than this is a miss (an assembly's is megabytes).
MAX_TESSELLATION_BYTES = 1 << 30


class TessellationCache:
    """Tessellated STEP files stored under ``directory``, one ``.npz`` per file and setting.

    Like ``meshcheck.cache.DecompositionCache``: entries named by ``tessellation_key``, written
    to a temporary file then moved into place, read with ``allow_pickle=False``; an entry that
    is unreadable, malformed or fails its checksum is a miss.

    Parameters
    ----------
    directory : str
        Cache root (shared with the decompositions); created on the first write.
    """

    def __init__(self, directory: str, *, secret: bytes):
        self.root = os.path.join(os.fspath(directory), f"tessellations-v{FORMAT_VERSION}")
        self._secret = bytes(secret)

    def path(self, key: str) -> str:
        """File of the entry for ``key``."""
        return os.path.join(self.root, key[:2], f"{key}.npz")

    def get(self, key: str) -> StepAssembly | None:
        """The assembly stored for ``key``, or None when missing or unusable."""
        from ..cache import _sizes_agree, read_entry

        raw = read_entry(self.path(key), MAX_TESSELLATION_BYTES)  # a FIFO or link: a miss
        if raw is None:
            return None
        try:
            if not _sizes_agree(io.BytesIO(raw)):
                return None
            with np.load(io.BytesIO(raw), allow_pickle=False) as data:
                if sorted(data.files) != _ARRAYS:
                    return None
                arrays = {name: data[name] for name in _ARRAYS}
        except (OSError, ValueError, EOFError, KeyError, MemoryError, zipfile.BadZipFile):
            return None
        try:
            return _unpack(arrays, key, self._secret)
        except (ValueError, KeyError, TypeError, IndexError, UnicodeDecodeError):
            return None

    def put(self, key: str, assembly: StepAssembly) -> None:
        """Store ``assembly`` for ``key`` atomically; a failure to write only costs a re-read."""
        arrays = _pack(assembly, key, self._secret)
        from ..cache import write_atomically

        write_atomically(self.path(key), ".npz", lambda f: np.savez(f, **arrays))


def _pack(assembly: StepAssembly, key: str, secret: bytes) -> dict[str, np.ndarray]:
    meshes: list[trimesh.Trimesh] = []
    index: dict[int, int] = {}
    for _, mesh, _ in assembly.items:
        if id(mesh) not in index:
            index[id(mesh)] = len(meshes)
            meshes.append(mesh)
    header = {
        "names": [name for name, _, _ in assembly.items],
        "unit": assembly.unit,
        "deflection": float(assembly.deflection).hex(),
        "angular_deflection": float(assembly.angular_deflection).hex(),
    }
    arrays = {
        "header": np.frombuffer(json.dumps(header).encode(), dtype=np.uint8),
        "vertices": np.concatenate([np.asarray(m.vertices, dtype=np.float64) for m in meshes]),
        "faces": np.concatenate([np.asarray(m.faces, dtype=np.int64) for m in meshes]),
        "vertex_starts": np.cumsum([0] + [len(m.vertices) for m in meshes], dtype=np.int64),
        "face_starts": np.cumsum([0] + [len(m.faces) for m in meshes], dtype=np.int64),
        "mesh_of": np.array([index[id(m)] for _, m, _ in assembly.items], dtype=np.int64),
        "transforms": np.array([t for _, _, t in assembly.items], dtype=np.float64).reshape(
            -1, 4, 4
        ),
    }
    arrays["checksum"] = np.frombuffer(_checksum(arrays, key, secret), dtype=np.uint8)
    return arrays


def _checksum(arrays: dict[str, np.ndarray], key: str, secret: bytes) -> bytes:
    """HMAC-SHA256 of the entry under the cache's secret: a tessellation is the part's geometry,
    which nothing cheaper than tessellating again could check, so an entry not signed with this
    machine's (or CI's) key is a miss."""
    h = hmac.new(secret, key.encode(), hashlib.sha256)
    for name in _ARRAYS:
        if name != "checksum":
            h.update(name.encode())
            h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.digest()


def _unpack(arrays: dict[str, np.ndarray], key: str, secret: bytes) -> StepAssembly | None:
    expected = {
        "header": (np.uint8, 1),
        "vertices": (np.float64, 2),
        "faces": (np.int64, 2),
        "vertex_starts": (np.int64, 1),
        "face_starts": (np.int64, 1),
        "mesh_of": (np.int64, 1),
        "transforms": (np.float64, 3),
        "checksum": (np.uint8, 1),
    }
    for name, (dtype, ndim) in expected.items():
        if arrays[name].dtype != dtype or arrays[name].ndim != ndim:
            return None
    if not hmac.compare_digest(arrays["checksum"].tobytes(), _checksum(arrays, key, secret)):
        return None
    header = json.loads(arrays["header"].tobytes().decode())
    vs, fs, mesh_of = arrays["vertex_starts"], arrays["face_starts"], arrays["mesh_of"]
    names = header["names"]
    n_meshes = len(vs) - 1
    if (
        len(fs) != len(vs)
        or vs[0] != 0
        or fs[0] != 0
        or vs[-1] != len(arrays["vertices"])
        or fs[-1] != len(arrays["faces"])
        or len(names) != len(mesh_of)
        or arrays["transforms"].shape != (len(names), 4, 4)
        or np.any(mesh_of < 0)
        or np.any(mesh_of >= n_meshes)
        or header["unit"] not in UNIT_METRES
    ):
        return None
    meshes = []
    for k in range(n_meshes):
        faces = arrays["faces"][fs[k] : fs[k + 1]]  # indices into this mesh's own vertices
        vertices = arrays["vertices"][vs[k] : vs[k + 1]]
        if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
            return None
        meshes.append(trimesh.Trimesh(vertices.copy(), faces.copy(), process=False))
    items = [
        (str(name), meshes[int(m)], arrays["transforms"][i].copy())
        for i, (name, m) in enumerate(zip(names, mesh_of, strict=True))
    ]
    return StepAssembly(
        items,
        header["unit"],
        float.fromhex(header["deflection"]),
        float.fromhex(header["angular_deflection"]),
    )
