"""URDF robots -> placed collision geometry: each link's collision elements at a pose.

A robot is a tree of links joined by joints (``load.robot``, which also poses it). The
collision geometry of every link becomes parts named ``ROBOT.urdf#LINK`` (``#LINK/1``,
``#LINK/2``... for a link's second, third... collision element), placed at the pose
(``Motion.pose``, zero by default). URDF lengths are metres: the file declares ``m``. The parsed
robot goes down with the parts (``urdf_mechanism``): no later stage reads the URDF again.

Meshes (STL, OBJ, PLY, OFF; DAE when pycollada is installed) are read by the same readers as
mesh files, each once however many links use it, scaled by the element's ``scale``; boxes,
cylinders (``CYLINDER_SECTIONS``-gons) and spheres (icospheres, ``SPHERE_SUBDIVISIONS``) become
meshes. ``package://NAME/REL`` is looked up in the folders of ``Motion.package_paths``, then the
URDF's folder and its ancestors (see ``package_roots``).

The XML is read by expat with a document type declaration refused outright, so no entity is ever
declared or expanded (the "billion laughs" and external-entity attacks the standard library's
ElementTree parser lets through), and with bounded element count and depth.

Every problem is an ``InputError`` naming the URDF (exit 3): malformed XML, a DOCTYPE, a joint
whose parent or child link is missing, a link with two parents, a cycle, several root links, an
unknown joint type, a missing or unreadable mesh, non-finite numbers. A pose problem (a joint not
in the robot, a value beyond the joint's limits, degrees for a slide, a value for a mimic joint)
is a ``ConfigError`` naming the joint (exit 2).
"""

from __future__ import annotations

import math
import os
import re
import warnings
import xml.parsers.expat
from collections.abc import Sequence
from xml.etree import ElementTree

import numpy as np

from ..errors import ConfigError, InputError
from ..mesh import warn
from .limits import Budget, read_file
from .robot import (
    HELD,
    MOVABLE,
    Collision,
    Joint,
    Mechanism,
    Robot,
    adjacent_links,
    joint_values,
    link_transforms,
    rpy_matrix,
)
from .scene import Item, Soup, one_line, read_scene

#: Regular polygon sides of a URDF cylinder's mesh (inscribed: its surface lies within
#: radius * (1 - cos(pi / 64)) = 0.12 % of the radius inside the true cylinder).
CYLINDER_SECTIONS = 64
#: Icosphere subdivisions of a URDF sphere's mesh (1280 triangles; inscribed, within 0.3 %).
SPHERE_SUBDIVISIONS = 3
#: Elements in one URDF and their nesting depth: real robots have a few thousand, a few deep.
MAX_ELEMENTS = 200_000
MAX_DEPTH = 64
MESH_EXTENSIONS = (".stl", ".obj", ".ply", ".off", ".dae")


# --------------------------------------------------------------------------------------------
# Reading


def read_urdf(path: str, data: bytes, budget: Budget, motion=None) -> tuple[Robot, list[Item]]:
    """The robot a URDF describes, and (node, local mesh, placement) of every collision element,
    posed.

    Parameters
    ----------
    path : str
        The URDF, as given.
    data : bytes
        Its content.
    budget : Budget
        The run's; meshes are checked against it as mesh files are.
    motion : motion.Motion, optional
        The pose and package paths; default zero pose, no extra package paths.

    Returns
    -------
    robot : Robot
    items : list of (str, mesh, (4, 4) float64)
        Placements in metres: link placement @ collision origin @ scale.
    """
    robot = parse_robot(path, data)
    pose = ()
    if motion is not None:  # the values of [[joint]] tables are load.joints' to place
        ours = {spec.name for spec in motion.joints}
        pose = tuple(v for v in motion.pose if v.joint not in ours)
        clash = sorted(ours & {j.name for j in robot.joints})
        if clash:
            raise ConfigError(
                path, f"joint {clash[0]!r} is also a [[joint]] of the configuration: rename one"
            )
    values = joint_values(robot, pose)
    links = link_transforms(robot, values)
    package_paths = tuple(motion.package_paths) if motion is not None else ()
    meshes: dict = {}
    items = []
    for c in robot.collisions:
        mesh, scale = _geometry(robot, c, package_paths, budget, meshes)
        placement = links[c.link] @ c.origin
        if scale is not None:
            placement = placement @ np.diag([*scale, 1.0])
        items.append((c.node, mesh, placement))
    if not items:
        raise InputError(path, "no link has collision geometry")
    return robot, items


def urdf_mechanism(robot: Robot, bodies: Sequence) -> Mechanism:
    """The ``Mechanism`` of a URDF robot: each link's parts among ``bodies``.

    The robot's parts are the bodies of its file (``Body.path`` is ``robot.path``), named
    ``PATH#NODE`` after their collision element (``Collision.node``), or ``PATH#NODE#k`` for
    the shells of a split part (``load.split_body``).
    """
    node_link = {c.node: c.link for c in robot.collisions}
    prefix = f"{robot.path}#"
    parts: dict[str, list[int]] = {}
    for k, body in enumerate(bodies):
        if body.path != robot.path:
            continue
        node = body.name.removeprefix(prefix)
        if node not in node_link:  # a shell of a split part
            node = node.rpartition("#")[0]
        parts.setdefault(node_link[node], []).append(k)
    return Mechanism(robot, parts, adjacent=adjacent_links(robot))


def parse_robot(path: str, data: bytes) -> Robot:
    """The kinematic tree and collision elements of a URDF's bytes (no mesh is read).

    Raises
    ------
    InputError
        The URDF is malformed (see the module docstring).
    """
    root = parse_xml(path, data)
    if root.tag != "robot":
        raise InputError(path, f"root element is <{root.tag}>, not <robot>: not a URDF")
    if any(el.tag.startswith("xacro:") for el in root.iter()):
        raise InputError(path, "holds xacro macros: expand it first (xacro FILE > robot.urdf)")
    links, collisions = [], []
    for el in root.findall("link"):
        name = _attr(path, el, "name")
        if name in links:
            raise InputError(path, f"link {name!r} is defined twice")
        links.append(name)
        for k, col in enumerate(el.findall("collision")):
            collisions.append(
                Collision(name, k, _origin(path, col), _shape(path, col, f"link {name!r}"))
            )
    joints = [_joint(path, el) for el in root.findall("joint")]
    root_link, ordered = _tree(path, links, joints)
    _check_mimics(path, ordered)
    return Robot(
        path,
        root.get("name", ""),
        root_link,
        tuple(links),
        tuple(ordered),
        tuple(collisions),
    )


class _Refused(Exception):
    pass


def parse_xml(path: str, data: bytes) -> ElementTree.Element:
    """An XML document's element tree, read by expat with no DOCTYPE and no entities.

    Raises
    ------
    InputError
        Not well-formed, declares a document type or entity, or exceeds ``MAX_ELEMENTS`` or
        ``MAX_DEPTH``.
    """
    parser = xml.parsers.expat.ParserCreate()
    builder = ElementTree.TreeBuilder()
    depth = [0, 0]  # current depth, elements seen

    def refuse(*_):
        raise _Refused("declares a document type or entities (refused: entity expansion)")

    def start(tag, attrs):
        depth[0] += 1
        depth[1] += 1
        if depth[0] > MAX_DEPTH or depth[1] > MAX_ELEMENTS:
            raise _Refused(f"more than {MAX_ELEMENTS} elements or {MAX_DEPTH} levels deep")
        builder.start(tag, attrs)

    def end(tag):
        depth[0] -= 1
        builder.end(tag)

    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.UnparsedEntityDeclHandler = refuse
    parser.ExternalEntityRefHandler = refuse
    parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
        return builder.close()
    except _Refused as exc:
        raise InputError(path, str(exc)) from None
    except (xml.parsers.expat.ExpatError, AssertionError, ValueError) as exc:
        raise InputError(path, f"is not well-formed XML ({one_line(exc)})") from None


def _attr(path: str, el: ElementTree.Element, key: str) -> str:
    value = el.get(key)
    if value is None or not value.strip():
        raise InputError(path, f"<{el.tag}> without a {key!r} attribute")
    return value.strip()


def _numbers(path: str, text: str | None, count: int, what: str, default=None) -> np.ndarray:
    """``count`` finite numbers from a space-separated attribute (``default`` when absent)."""
    if text is None:
        if default is None:
            raise InputError(path, f"{what} is missing")
        return np.asarray(default, dtype=np.float64)
    try:
        values = np.array([float(t) for t in text.split()], dtype=np.float64)
    except ValueError:
        raise InputError(path, f"{what} {text!r} is not {count} numbers") from None
    if len(values) != count:
        raise InputError(path, f"{what} {text!r} is not {count} numbers")
    if not np.all(np.isfinite(values)):
        raise InputError(path, f"{what} {text!r} holds NaN or infinite values")
    return values


def _number(path: str, text: str | None, what: str, default: float | None = None) -> float:
    return float(_numbers(path, text, 1, what, None if default is None else [default])[0])


def _origin(path: str, el: ElementTree.Element) -> np.ndarray:
    """The ``<origin xyz rpy>`` of an element as a (4, 4) transform (identity when absent)."""
    origin = el.find("origin")
    out = np.eye(4)
    if origin is None:
        return out
    xyz = _numbers(path, origin.get("xyz"), 3, f"<{el.tag}> origin xyz", (0.0, 0.0, 0.0))
    rpy = _numbers(path, origin.get("rpy"), 3, f"<{el.tag}> origin rpy", (0.0, 0.0, 0.0))
    out[:3, :3] = rpy_matrix(*rpy)
    out[:3, 3] = xyz
    return out


def _shape(path: str, col: ElementTree.Element, owner: str) -> tuple:
    geometry = col.find("geometry")
    if geometry is None or len(geometry) == 0:
        raise InputError(path, f"{owner}: <collision> without a <geometry>")
    el = geometry[0]
    what = f"{owner} <{el.tag}>"
    if el.tag == "mesh":
        scale = _numbers(path, el.get("scale"), 3, f"{what} scale", (1.0, 1.0, 1.0))
        return ("mesh", _attr(path, el, "filename"), scale)
    if el.tag == "box":
        size = _numbers(path, el.get("size"), 3, f"{what} size")
        if np.any(size <= 0.0):
            raise InputError(path, f"{what} size must be positive")
        return ("box", size)
    if el.tag == "cylinder":
        radius = _number(path, el.get("radius"), f"{what} radius")
        length = _number(path, el.get("length"), f"{what} length")
        if radius <= 0.0 or length <= 0.0:
            raise InputError(path, f"{what} radius and length must be positive")
        return ("cylinder", radius, length)
    if el.tag == "sphere":
        radius = _number(path, el.get("radius"), f"{what} radius")
        if radius <= 0.0:
            raise InputError(path, f"{what} radius must be positive")
        return ("sphere", radius)
    raise InputError(path, f"{owner}: unknown collision geometry <{el.tag}>")


def _joint(path: str, el: ElementTree.Element) -> Joint:
    name = _attr(path, el, "name")
    kind = _attr(path, el, "type")
    what = f"joint {name!r}"
    if kind not in MOVABLE + HELD:
        raise InputError(
            path, f"{what} has unknown type {kind!r} (known: {', '.join(MOVABLE + HELD)})"
        )
    parent, child = el.find("parent"), el.find("child")
    if parent is None or child is None:
        raise InputError(path, f"{what} needs a <parent> and a <child>")
    axis = _numbers(path, _get(el, "axis", "xyz"), 3, f"{what} axis", (1.0, 0.0, 0.0))
    norm = float(np.linalg.norm(axis))
    if kind in MOVABLE and norm == 0.0:
        raise InputError(path, f"{what} has a zero axis")
    lower, upper = -math.inf, math.inf
    if kind in ("revolute", "prismatic"):
        limit = el.find("limit")
        if limit is None:
            raise InputError(path, f"{what} ({kind}) needs a <limit>")
        lower = _number(path, limit.get("lower"), f"{what} lower limit", 0.0)
        upper = _number(path, limit.get("upper"), f"{what} upper limit", 0.0)
        if lower > upper:
            raise InputError(path, f"{what} lower limit {lower:g} is above its upper {upper:g}")
    mimic = None
    el_mimic = el.find("mimic")
    if el_mimic is not None and kind in MOVABLE:
        leader = _attr(path, el_mimic, "joint")
        multiplier = _number(path, el_mimic.get("multiplier"), f"{what} mimic multiplier", 1.0)
        offset = _number(path, el_mimic.get("offset"), f"{what} mimic offset", 0.0)
        mimic = (leader, multiplier, offset)
    if kind in ("floating", "planar"):
        warn(path, f"{what} is {kind}: held at its origin (only revolute, continuous and "
             "prismatic joints move)")  # fmt: skip
    return Joint(
        name,
        kind,
        _attr(path, parent, "link"),
        _attr(path, child, "link"),
        _origin(path, el),
        axis / norm if norm > 0.0 else axis,
        lower,
        upper,
        mimic,
    )


def _get(el: ElementTree.Element, child: str, key: str) -> str | None:
    found = el.find(child)
    return None if found is None else found.get(key)


def _tree(path: str, links: list[str], joints: list[Joint]) -> tuple[str, list[Joint]]:
    """The root link and the joints ordered parents first; refuse what is not a tree."""
    known = set(links)
    by_child: dict[str, Joint] = {}
    names = set()
    for j in joints:
        if j.name in names:
            raise InputError(path, f"joint {j.name!r} is defined twice")
        names.add(j.name)
        for role, link in (("parent", j.parent), ("child", j.child)):
            if link not in known:
                raise InputError(path, f"joint {j.name!r}: {role} link {link!r} is not defined")
        if j.child in by_child:
            raise InputError(
                path,
                f"link {j.child!r} has two parent joints ({by_child[j.child].name!r}, {j.name!r})",
            )
        by_child[j.child] = j
    roots = [link for link in links if link not in by_child]
    if not roots:
        raise InputError(path, "the joints form a cycle: no link is the root")
    if len(roots) > 1:
        raise InputError(path, f"several root links ({', '.join(roots[:4])}): not one tree")
    children: dict[str, list[Joint]] = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j)
    ordered, stack = [], [roots[0]]
    while stack:
        for j in children.get(stack.pop(), []):
            ordered.append(j)
            stack.append(j.child)
    if len(ordered) != len(joints):
        cyclic = sorted({j.name for j in joints} - {j.name for j in ordered})
        raise InputError(path, f"the joints form a cycle (joint {cyclic[0]!r} is on it)")
    return roots[0], ordered


def _check_mimics(path: str, joints: list[Joint]) -> None:
    """Refuse a mimic of a joint that is missing, not movable, or leads back to itself."""
    by_name = {j.name: j for j in joints}
    for j in joints:
        seen = {j.name}
        at = j
        while at.mimic is not None:
            leader = by_name.get(at.mimic[0])
            if leader is None or leader.type not in MOVABLE:
                raise InputError(
                    path, f"joint {at.name!r} mimics {at.mimic[0]!r}, which is no movable joint"
                )
            if leader.name in seen:
                raise InputError(path, f"joint {j.name!r}: its mimic chain is a cycle")
            seen.add(leader.name)
            at = leader


# --------------------------------------------------------------------------------------------
# Geometry


def package_roots(urdf_path: str, package: str, package_paths=()) -> list[str]:
    """Folders that may be package ``package``'s root, in search order.

    Each of ``package_paths``, then the URDF's folder and each of its ancestors, offers: itself
    when it is named ``package`` or its ``package.xml`` names it; its child folder ``package``;
    a child folder whose ``package.xml`` names it.
    """
    start = os.path.dirname(os.path.abspath(urdf_path))
    ancestors = []
    at = start
    while True:
        ancestors.append(at)
        up = os.path.dirname(at)
        if up == at:
            break
        at = up
    out = []
    for base in [*package_paths, *ancestors]:
        if os.path.basename(os.path.normpath(base)) == package or _package_name(base) == package:
            out.append(base)
        if os.path.isdir(os.path.join(base, package)):
            out.append(os.path.join(base, package))
        if base in package_paths:
            out.extend(
                os.path.join(base, d)
                for d in sorted(_subdirs(base))
                if _package_name(os.path.join(base, d)) == package
            )
    return out


def _subdirs(base: str) -> list[str]:
    try:
        return [e.name for e in os.scandir(base) if e.is_dir() and not e.name.startswith(".")]
    except OSError:
        return []


_NAME = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")


def _package_name(folder: str) -> str | None:
    """The ``<name>`` a folder's ``package.xml`` declares, or None."""
    try:
        with open(os.path.join(folder, "package.xml"), "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return None
    found = _NAME.search(head)
    return None if found is None else found.group(1).decode("utf-8", "replace")


def resolve_mesh(urdf_path: str, filename: str, package_paths=()) -> str:
    """The file a URDF mesh ``filename`` names (``package://``, ``file://`` or relative)."""
    if filename.startswith("package://"):
        package, _, rel = filename[len("package://") :].partition("/")
        for root in package_roots(urdf_path, package, package_paths):
            candidate = os.path.join(root, rel)
            if os.path.isfile(candidate):
                return candidate
        raise InputError(
            urdf_path,
            f"mesh {filename}: not found in package {package!r} (looked in the URDF's folder, its "
            "ancestors and --package-path)",
        )
    if filename.startswith("file://"):
        filename = filename[len("file://") :]
    if not os.path.isabs(filename):
        filename = os.path.join(os.path.dirname(urdf_path), filename)
    if not os.path.isfile(filename):
        raise InputError(urdf_path, f"mesh {filename}: no such file")
    return filename


def _geometry(robot: Robot, c: Collision, package_paths, budget: Budget, meshes: dict):
    """(mesh, scale or None) of a collision element; each file or primitive built once."""
    kind = c.shape[0]
    if kind == "mesh":
        _, filename, scale = c.shape
        found = resolve_mesh(robot.path, filename, package_paths)
        key = ("mesh", os.path.realpath(found))
        if key not in meshes:
            meshes[key] = _read_mesh(robot.path, found, budget)
        return meshes[key], scale
    key = (kind, *np.ravel(c.shape[1:]).tolist())
    if key not in meshes:
        meshes[key] = _primitive(c.shape)
    return meshes[key], None


def _primitive(shape: tuple):
    import trimesh

    kind = shape[0]
    if kind == "box":
        mesh = trimesh.creation.box(extents=shape[1])
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(
            radius=shape[1], height=shape[2], sections=CYLINDER_SECTIONS
        )
    else:
        mesh = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=shape[1])
    return Soup(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64))


def _read_mesh(urdf_path: str, path: str, budget: Budget) -> Soup:
    """One mesh file's triangles, every node placed and merged (a link's element is one part)."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in MESH_EXTENSIONS:
        raise InputError(
            urdf_path,
            f"mesh {path}: unsupported type {ext or '(none)'} ({', '.join(MESH_EXTENSIONS)})",
        )
    data = read_file(path, budget.limits)
    if ext == ".dae":
        items = _read_dae(path, data)
    else:
        items = read_scene(path, data, ext, budget)
    vertices, faces, offset = [], [], 0
    for _, geom, placement in items:
        v = np.asarray(geom.vertices, dtype=np.float64)
        if not np.array_equal(placement, np.eye(4)):
            v = v @ placement[:3, :3].T + placement[:3, 3]
        vertices.append(v)
        faces.append(np.asarray(geom.faces, dtype=np.int64) + offset)
        offset += len(v)
    return Soup(np.vstack(vertices), np.vstack(faces))


def _read_dae(path: str, data: bytes) -> list[Item]:
    import io

    import trimesh

    try:
        import collada  # noqa: F401  (trimesh reads DAE through pycollada)
    except ImportError:
        raise InputError(
            path, "reading COLLADA (.dae) needs pycollada: pip install pycollada"
        ) from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = trimesh.load_scene(io.BytesIO(data), file_type="dae", process=False)
    except Exception as exc:
        raise InputError(path, f"cannot be read as a mesh: {one_line(exc)}") from None
    items = []
    for node in sorted(scene.graph.nodes_geometry):
        transform, name = scene.graph[node]
        geom = scene.geometry[name]
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            items.append((str(node), geom, np.asarray(transform, dtype=np.float64)))
    if not items:
        raise InputError(path, "holds no triangles")
    return items


__all__ = [
    "package_roots",
    "parse_robot",
    "parse_xml",
    "read_urdf",
    "resolve_mesh",
    "urdf_mechanism",
]
