"""Files -> bodies: every body in world coordinates, with the name the reports use.

A part's name is the path exactly as given; a body inside a file that holds several is named
``PATH#NODE``, NODE being its scene-graph node name.
"""

from __future__ import annotations

import functools
import hashlib
import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import trimesh

from .errors import InputError

SUPPORTED_EXTENSIONS = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf", ".3mf")


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


def load_bodies(paths: Sequence[str]) -> list[Body]:
    """Load every body of every file, in world coordinates.

    Parameters
    ----------
    paths : sequence of str
        Mesh files, as the user gave them.

    Returns
    -------
    bodies : list of Body
        In the order of ``paths``, bodies of one file in scene-graph order.
    """
    bodies: list[Body] = []
    for path in paths:
        bodies.extend(load_file(path))
    return bodies


def load_file(path: str) -> list[Body]:
    """Load the bodies of one mesh file; raise ``InputError`` naming the file when it is unusable."""
    if not os.path.exists(path):
        raise InputError(path, "no such file")
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise InputError(path, f"unsupported file type {ext or '(none)'}")
    try:
        scene = trimesh.load_scene(path)
    except Exception as exc:
        raise InputError(path, f"cannot be read as a mesh ({exc})") from None

    items = []
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry[geom_name]
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            items.append((node, geom, np.asarray(transform, dtype=np.float64)))
    if not items:
        raise InputError(path, "holds no triangles")
    if len(items) == 1:
        node, geom, transform = items[0]
        return [Body(path, path, geom, transform)]
    return [Body(f"{path}#{node}", path, geom, transform) for node, geom, transform in items]
