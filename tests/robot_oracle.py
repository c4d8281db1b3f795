"""An independent reading of a URDF robot for the tests and benchmarks to check meshcheck's
sweeps and audits against: its own forward kinematics (the standard library's XML parser,
scipy's rotations), each link's collision meshes read by trimesh directly, python-fcl for
contact, the generalized winding number (``meshes.winding_inside``) for one link buried in
another. Nothing here imports meshcheck.

Only for trusted files (the repository's own robots and robots the tests build): the standard
library's parser expands entities, which meshcheck's refuses.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation


@dataclass
class OracleJoint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    mimic: tuple[str, float, float] | None


@dataclass
class OracleRobot:
    links: list[str]
    joints: dict[str, OracleJoint]
    #: each link's collision meshes in the link frame
    meshes: dict[str, list[trimesh.Trimesh]] = field(default_factory=dict)

    @property
    def movable(self) -> list[OracleJoint]:
        """Joints a pose sets: revolute, continuous, prismatic, not mimicking."""
        return [
            j
            for j in self.joints.values()
            if j.type in ("revolute", "continuous", "prismatic") and j.mimic is None
        ]


def _frame(el) -> np.ndarray:
    out = np.eye(4)
    origin = el.find("origin") if el is not None else None
    if origin is not None:
        xyz = [float(x) for x in origin.get("xyz", "0 0 0").split()]
        rpy = [float(x) for x in origin.get("rpy", "0 0 0").split()]
        out[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x, y, z
        out[:3, 3] = xyz
    return out


def read_robot(path: str, packages: dict[str, str] | None = None) -> OracleRobot:
    """The robot of a URDF: joints, and each link's collision meshes in its frame.

    ``packages`` maps a package name to its folder for ``package://`` file names.
    """
    root = ET.parse(path).getroot()
    folder = os.path.dirname(os.path.abspath(path))
    robot = OracleRobot([link.get("name") for link in root.findall("link")], {})
    for el in root.findall("joint"):
        axis_el = el.find("axis")
        axis = np.array([float(x) for x in (axis_el.get("xyz") if axis_el is not None
                                            else "1 0 0").split()])  # fmt: skip
        limit = el.find("limit")
        lower = float(limit.get("lower", 0)) if limit is not None else -math.inf
        upper = float(limit.get("upper", 0)) if limit is not None else math.inf
        if el.get("type") == "continuous":
            lower, upper = -math.pi, math.pi
        mimic_el = el.find("mimic")
        mimic = None
        if mimic_el is not None:
            mimic = (mimic_el.get("joint"), float(mimic_el.get("multiplier", 1)),
                     float(mimic_el.get("offset", 0)))  # fmt: skip
        robot.joints[el.get("name")] = OracleJoint(
            el.get("name"), el.get("type"), el.find("parent").get("link"),
            el.find("child").get("link"), _frame(el), axis / (np.linalg.norm(axis) or 1.0),
            lower, upper, mimic,
        )  # fmt: skip
    for link in root.findall("link"):
        meshes = []
        for col in link.findall("collision"):
            geometry = col.find("geometry")[0]
            placement = _frame(col)
            if geometry.tag == "mesh":
                name = geometry.get("filename")
                if name.startswith("package://"):
                    package, _, rel = name[len("package://") :].partition("/")
                    name = os.path.join((packages or {})[package], rel)
                elif not os.path.isabs(name):
                    name = os.path.join(folder, name)
                mesh = trimesh.load(name, force="mesh", process=False)
                scale = [float(x) for x in geometry.get("scale", "1 1 1").split()]
                mesh.apply_scale(scale)
            elif geometry.tag == "box":
                mesh = trimesh.creation.box([float(x) for x in geometry.get("size").split()])
            elif geometry.tag == "cylinder":
                radius, length = float(geometry.get("radius")), float(geometry.get("length"))
                mesh = trimesh.creation.cylinder(radius, length, sections=64)
            else:
                mesh = trimesh.creation.icosphere(3, float(geometry.get("radius")))
            meshes.append(mesh.apply_transform(placement))
        robot.meshes[link.get("name")] = meshes
    return robot


def link_poses(robot: OracleRobot, values: dict[str, float]) -> dict[str, np.ndarray]:
    """Each link's placement in the root frame with the leading joints at ``values`` (the
    others at 0, mimics following)."""
    full = dict(values)
    for j in robot.joints.values():
        if j.mimic is not None:
            leader, multiplier, offset = j.mimic
            full[j.name] = multiplier * full.get(leader, 0.0) + offset
    by_child = {j.child: j for j in robot.joints.values()}
    out: dict[str, np.ndarray] = {}

    def place(link: str) -> np.ndarray:
        if link not in out:
            joint = by_child.get(link)
            if joint is None:
                out[link] = np.eye(4)
            else:
                motion = np.eye(4)
                q = full.get(joint.name, 0.0)
                if joint.type in ("revolute", "continuous"):
                    motion[:3, :3] = Rotation.from_rotvec(joint.axis * q).as_matrix()
                elif joint.type == "prismatic":
                    motion[:3, 3] = joint.axis * q
                out[link] = place(joint.parent) @ joint.origin @ motion
        return out[link]

    for link in robot.links:
        place(link)
    return out


def posed(robot: OracleRobot, link: str, poses: dict[str, np.ndarray]) -> list[trimesh.Trimesh]:
    """A link's collision meshes placed at ``poses`` (``link_poses``)."""
    return [m.copy().apply_transform(poses[link]) for m in robot.meshes[link]]


def collide(robot: OracleRobot, a: str, b: str, values: dict[str, float], tolerance=1e-5):
    """How two links meet at ``values``: ``"contact"`` when python-fcl sees their meshes
    collide or come within ``tolerance`` (metres), ``"buried"`` when a vertex of one lies
    inside the other (winding number), else None."""
    import fcl
    from meshes import fcl_object, winding_inside

    poses = link_poses(robot, values)
    for ma in posed(robot, a, poses):
        for mb in posed(robot, b, poses):
            oa, ob = fcl_object(ma), fcl_object(mb)
            if fcl.collide(oa, ob, fcl.CollisionRequest(), fcl.CollisionResult()):
                return "contact"
            if fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult()) <= tolerance:
                return "contact"
            for inner, outer in ((ma, mb), (mb, ma)):
                if outer.is_watertight and winding_inside(outer, inner.vertices[:1])[0]:
                    return "buried"
    return None
