"""A URDF's collision meshes at zero joints -> GLB, for a peer that reads no URDF.

Used only by ``bench/real_assemblies.py prepare`` to turn moveit_resources' PR2 into one file
both meshcheck and trimesh's CollisionManager read (CollisionManager reads no URDF). Every
``<collision>`` with a ``<mesh>`` becomes a glTF node named after its link (``LINK`` or
``LINK.K`` for a link's K-th mesh), placed by the joint origins from the root down with every
joint at 0; one glTF mesh per file, so a mesh used by several links is one geometry placed
several times. Primitive collision shapes (box, cylinder, sphere) are left out: the benchmark is
about meshes.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import numpy as np
import trimesh


def _origin(element) -> np.ndarray:
    """The 4x4 transform of an ``<origin xyz rpy>`` child (identity when absent)."""
    origin = element.find("origin") if element is not None else None
    origin = {} if origin is None else origin.attrib
    xyz = [float(s) for s in origin.get("xyz", "0 0 0").split()]
    rpy = [float(s) for s in origin.get("rpy", "0 0 0").split()]
    matrix = trimesh.transformations.euler_matrix(*rpy, axes="sxyz")
    matrix[:3, 3] = xyz
    return matrix


def link_poses(root: ET.Element) -> dict[str, np.ndarray]:
    """World pose of every link with every joint at zero (joint origins chained from the root)."""
    parent_of = {}
    for joint in root.findall("joint"):
        child = joint.find("child").get("link")
        parent_of[child] = (joint.find("parent").get("link"), _origin(joint))
    poses: dict[str, np.ndarray] = {}

    def pose(link: str) -> np.ndarray:
        if link not in poses:
            if link in parent_of:
                parent, offset = parent_of[link]
                poses[link] = pose(parent) @ offset
            else:
                poses[link] = np.eye(4)
        return poses[link]

    for link in root.findall("link"):
        pose(link.get("name"))
    return poses


def urdf_to_glb(urdf: str, package_dir: str, out: str) -> int:
    """Write the collision meshes of ``urdf`` at zero joints as a GLB scene; return the node count.

    ``package://NAME/`` in mesh file names resolves to ``package_dir``.
    """
    root = ET.parse(urdf).getroot()
    poses = link_poses(root)
    scene = trimesh.Scene()
    loaded: dict[str, str] = {}
    count = 0
    for link in root.findall("link"):
        name = link.get("name")
        meshes = [c for c in link.findall("collision") if c.find("geometry/mesh") is not None]
        for k, collision in enumerate(meshes):
            element = collision.find("geometry/mesh")
            filename = element.get("filename")
            path = os.path.join(package_dir, filename.split("://", 1)[-1].split("/", 1)[1])
            scale = np.eye(4)
            if element.get("scale"):
                scale[[0, 1, 2], [0, 1, 2]] = [float(s) for s in element.get("scale").split()]
            node = name if len(meshes) == 1 else f"{name}.{k}"
            matrix = poses[name] @ _origin(collision) @ scale
            if path not in loaded:  # the first use adds the geometry with its node
                loaded[path] = os.path.splitext(os.path.relpath(path, package_dir))[0]
                scene.add_geometry(
                    trimesh.load_mesh(path),
                    geom_name=loaded[path],
                    node_name=node,
                    transform=matrix,
                )
            else:
                scene.graph.update(
                    frame_to=node,
                    frame_from=scene.graph.base_frame,
                    matrix=matrix,
                    geometry=loaded[path],
                )
            count += 1
    scene.export(out)
    return count
