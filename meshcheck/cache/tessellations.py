"""Tessellated STEP files: a signed ``.npz`` per file content and tessellation setting.

A tessellation is the parts' geometry, which nothing cheaper than tessellating again could check:
an entry is used only with a valid signature under the run's key (see ``meshcheck.cache``), read
with ``allow_pickle=False`` after its arrays' sizes are checked against its bytes.
"""

from __future__ import annotations

import io
import json
import re
import zipfile
from typing import NamedTuple

import numpy as np
import trimesh

from ..units import METRES
from .store import Store, checksum, npz_sizes_agree, package_version

# Bump when an entry's layout or the meaning of its meshes changes (the welding, the naming):
# 8 each mesh's product B-rep digest, 7 each product meshed from its BRep text, 6 faces mended
# from four deflections inside, 5 a deflection per product, 4 each solid welded on its own, 3
# welded along shared edges, 2 XCAF.
FORMAT_VERSION = 8
#: A tessellation cache entry larger than this is a miss (an assembly's is megabytes).
MAX_TESSELLATION_BYTES = 1 << 30
#: A mesh's product B-rep digest (``metadata["brep"]``): hex SHA-256, or empty (none known).
_BREP_DIGEST = re.compile(r"(?:[0-9a-f]{64})?")

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
_SHAPES = {  # dtype and number of dimensions of each array
    "header": (np.uint8, 1),
    "vertices": (np.float64, 2),
    "faces": (np.int64, 2),
    "vertex_starts": (np.int64, 1),
    "face_starts": (np.int64, 1),
    "mesh_of": (np.int64, 1),
    "transforms": (np.float64, 3),
    "checksum": (np.uint8, 1),
}


class Tessellation(NamedTuple):
    """The tessellated solids of a STEP file, as an entry keeps them.

    Attributes
    ----------
    items : list of (str, trimesh.Trimesh, (4, 4) float64)
        ``(name, mesh, transform)`` per solid instance; instances of one product share a mesh,
        whose ``metadata`` keeps its own ``deflection`` and its product's ``brep`` digest
        (``load.step.tessellate``).
    unit : str
        The file's length unit, a key of ``meshcheck.units.METRES``.
    deflection : float
        Linear deflection of the tessellation, ``unit``.
    angular_deflection : float
        Angular deflection, radians.
    """

    items: list[tuple[str, trimesh.Trimesh, np.ndarray]]
    unit: str
    deflection: float
    angular_deflection: float


def tessellation_key(
    data: bytes, deflection_mm: float | None, angular: float, *, default_scale: float = 1.0
) -> str:
    """Key of a tessellation: hex SHA-256 of the file's content, settings and library versions
    (and, for a file whose unit the user gave, the scale of the default deflection)."""
    payload = {
        "format": FORMAT_VERSION,
        "ocp": package_version("cadquery-ocp-novtk"),
        "trimesh": package_version("trimesh"),
        "content": checksum(data).hex(),
        "deflection_mm": None if deflection_mm is None else float(deflection_mm).hex(),
        "angular": float(angular).hex(),
    }
    if default_scale != 1.0 and deflection_mm is None:
        payload["default_scale"] = float(default_scale).hex()
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return checksum(text.encode()).hex()


class TessellationCache:
    """Tessellated STEP files stored under ``directory``, one ``.npz`` per file and setting,
    looked up by ``tessellation_key``, signed with the run's key.

    Parameters
    ----------
    directory : str
        Cache root (shared with the other caches); created on the first write.
    secret : bytes
        Key of the entries' HMAC-SHA256 (``pair_secret``); an entry signed with another key is
        a miss.
    """

    def __init__(self, directory: str, *, secret: bytes):
        self.store = Store(directory, f"tessellations-v{FORMAT_VERSION}", secret=secret)

    def path(self, key: str) -> str:
        """File of the entry for ``key``."""
        return self.store.path(key, ".npz")

    def get(self, key: str) -> Tessellation | None:
        """The tessellation stored for ``key``, or None when missing or unusable."""
        raw = self.store.read(self.path(key), MAX_TESSELLATION_BYTES)  # a FIFO or link: a miss
        if raw is None:
            return None
        try:
            if not npz_sizes_agree(io.BytesIO(raw)):
                return None
            with np.load(io.BytesIO(raw), allow_pickle=False) as data:
                if sorted(data.files) != _ARRAYS:
                    return None
                arrays = {name: data[name] for name in _ARRAYS}
        except (OSError, ValueError, EOFError, KeyError, MemoryError, zipfile.BadZipFile):
            return None
        if not self.store.is_signed(arrays["checksum"].tobytes(), *_signed_parts(arrays, key)):
            return None
        try:
            return _unpack(arrays)
        except (ValueError, KeyError, TypeError, IndexError, UnicodeDecodeError):
            return None

    def put(self, key: str, tessellation: Tessellation) -> None:
        """Store ``tessellation`` for ``key`` atomically; a failure to write only costs a
        re-read."""
        arrays = _pack(tessellation)
        signature = self.store.sign(*_signed_parts(arrays, key))
        arrays["checksum"] = np.frombuffer(signature, dtype=np.uint8)
        self.store.write(self.path(key), lambda f: np.savez(f, **arrays))


def _pack(tessellation: Tessellation) -> dict[str, np.ndarray]:
    """The arrays of an entry, its signature left out: each distinct mesh once."""
    items = tessellation.items
    meshes: list[trimesh.Trimesh] = []
    index: dict[int, int] = {}
    for _, mesh, _ in items:
        if id(mesh) not in index:
            index[id(mesh)] = len(meshes)
            meshes.append(mesh)
    header = {
        "names": [name for name, _, _ in items],
        "unit": tessellation.unit,
        "deflection": float(tessellation.deflection).hex(),
        "deflections": [
            float(m.metadata.get("deflection", tessellation.deflection)).hex() for m in meshes
        ],
        "breps": [str(m.metadata.get("brep", "")) for m in meshes],
        "angular_deflection": float(tessellation.angular_deflection).hex(),
    }
    return {
        "header": np.frombuffer(json.dumps(header).encode(), dtype=np.uint8),
        "vertices": np.concatenate([np.asarray(m.vertices, dtype=np.float64) for m in meshes]),
        "faces": np.concatenate([np.asarray(m.faces, dtype=np.int64) for m in meshes]),
        "vertex_starts": np.cumsum([0] + [len(m.vertices) for m in meshes], dtype=np.int64),
        "face_starts": np.cumsum([0] + [len(m.faces) for m in meshes], dtype=np.int64),
        "mesh_of": np.array([index[id(m)] for _, m, _ in items], dtype=np.int64),
        "transforms": np.array([t for _, _, t in items], dtype=np.float64).reshape(-1, 4, 4),
    }


def _signed_parts(arrays: dict[str, np.ndarray], key: str) -> list[bytes]:
    """What an entry's signature covers: its key, then each array's name and bytes."""
    parts = [key.encode()]
    for name in _ARRAYS:
        if name != "checksum":
            parts += [name.encode(), np.ascontiguousarray(arrays[name]).tobytes()]
    return parts


def _unpack(arrays: dict[str, np.ndarray]) -> Tessellation | None:
    """The tessellation of a signed entry's arrays, or None when they do not fit together."""
    for name, (dtype, ndim) in _SHAPES.items():
        if arrays[name].dtype != dtype or arrays[name].ndim != ndim:
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
        or header["unit"] not in METRES
        or len(header["deflections"]) != n_meshes
        or len(header["breps"]) != n_meshes
        or not all(_BREP_DIGEST.fullmatch(str(d)) for d in header["breps"])
    ):
        return None
    meshes = []
    for k in range(n_meshes):
        faces = arrays["faces"][fs[k] : fs[k + 1]]  # indices into this mesh's own vertices
        vertices = arrays["vertices"][vs[k] : vs[k + 1]]
        if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
            return None
        mesh = trimesh.Trimesh(vertices.copy(), faces.copy(), process=False)
        mesh.metadata["deflection"] = float.fromhex(header["deflections"][k])
        mesh.metadata["brep"] = header["breps"][k]
        meshes.append(mesh)
    items = [
        (str(name), meshes[int(m)], arrays["transforms"][i].copy())
        for i, (name, m) in enumerate(zip(names, mesh_of, strict=True))
    ]
    return Tessellation(
        items,
        header["unit"],
        float.fromhex(header["deflection"]),
        float.fromhex(header["angular_deflection"]),
    )
