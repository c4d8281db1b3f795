"""URDF robots -> placed collision geometry: each link's collision elements at a pose.

A robot is a tree of links joined by joints (``load.robot``, which also poses it). Each link
with collision geometry becomes one part named ``ROBOT.urdf#LINK``, placed at the pose
(``Motion.pose``, zero by default), as ROS and MoveIt take a link: one body, its collision
elements together, never checked against each other. A link with several elements is their
union (manifold3d, the closed ones; open ones are kept beside it), and the part keeps each
element (``Body.elements``) so a finding can name the ones it involves (``verify.elements``).
URDF lengths are metres: the file declares ``m``. The parsed robot goes down with the parts
(``urdf_mechanism``): no later stage reads the URDF again.

Meshes (STL, OBJ, PLY, OFF; DAE when pycollada is installed) are read by the same readers as
mesh files, each once however many links use it, scaled by the element's ``scale``; boxes,
cylinders (``CYLINDER_SECTIONS``-gons) and spheres (icospheres, ``SPHERE_SUBDIVISIONS``) become
meshes. ``package://NAME/REL`` is looked up in the folders of ``Motion.package_paths``, then the
URDF's folder and its ancestors (see ``package_roots``). Every file a URDF names is read only
inside the package root ``package://`` found, the URDF's folder, the package the URDF lies in
and the package paths (``resolve_mesh``): ``..`` out of them, an absolute path or a ``file://``
elsewhere, or a symbolic link leading out is refused, unless ``Motion.allow_outside``.

The XML is read by expat with a document type declaration refused outright, so no entity is ever
declared or expanded (the "billion laughs" and external-entity attacks the standard library's
ElementTree parser lets through), and with bounded element count and depth.

Every problem is an ``InputError`` naming the URDF (exit 3): malformed XML, a DOCTYPE, a joint
whose parent or child link is missing, a link with two parents, a cycle, several root links, an
unknown joint type, a missing or unreadable mesh, a mesh outside the folders it may be read
from, non-finite numbers. A pose problem (a joint not in the robot, a value beyond the joint's
limits, degrees for a slide, a value for a mimic joint) is a ``ConfigError`` naming the joint
(exit 2).
"""

from __future__ import annotations

import math
import os
import re
import warnings
import xml.parsers.expat
from collections.abc import Sequence
from typing import NamedTuple
from xml.etree import ElementTree

import numpy as np

from ..errors import ConfigError, InputError
from ..geometry import topology
from ..mesh import check_boolean_room, clean_arrays, manifold_solid, outward_faces, warn
from ..motion import is_within
from ..results import CollisionElement
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
    """The robot a URDF describes, and (link, local mesh, placement) of every link with
    collision geometry, posed.

    Parameters
    ----------
    path : str
        The URDF, as given.
    data : bytes
        Its content.
    budget : Budget
        The run's; meshes are checked against it as mesh files are.
    motion : motion.Motion, optional
        The pose, package paths and whether files outside them may be read; default zero pose,
        no extra package paths, none outside.

    Returns
    -------
    robot : Robot
    items : list of (str, mesh, (4, 4) float64)
        Placements in metres. A link of one element: its mesh (shared with every link that uses
        the same file) placed at link placement @ collision origin @ scale. A link of several:
        their union in the link frame (``Joined``, with each element), placed at the link's
        placement.
    """
    robot = parse_robot(path, data)
    links = link_transforms(robot, urdf_pose(robot, motion))
    package_paths = tuple(motion.package_paths) if motion is not None else ()
    allow_outside = bool(motion is not None and motion.allow_outside)
    meshes: dict = {}

    def geometry(c: Collision):
        return _geometry(robot, c, package_paths, budget, meshes, allow_outside=allow_outside)

    by_link: dict[str, list[Collision]] = {}
    for c in robot.collisions:
        by_link.setdefault(c.link, []).append(c)
    items = []
    for link, elements in by_link.items():
        if len(elements) == 1:
            (c,) = elements
            mesh, scale = geometry(c)
            placement = links[link] @ c.origin
            if scale is not None:
                placement = placement @ np.diag([*scale, 1.0])
            items.append((link, mesh, placement))
        else:
            items.append((link, join_elements(path, link, elements, geometry), links[link]))
    if not items:
        raise InputError(path, "no link has collision geometry")
    return robot, items


def urdf_pose(robot: Robot, motion=None) -> dict[str, float]:
    """Every movable joint's value at ``motion``'s pose (``joint_values``), the values of the
    configuration's ``[[joint]]`` tables left to ``load.joints``.

    Raises
    ------
    ConfigError
        A joint of the robot is also a ``[[joint]]`` of the configuration; see ``joint_values``.
    """
    pose = ()
    if motion is not None:  # the values of [[joint]] tables are load.joints' to place
        ours = {spec.name for spec in motion.joints}
        pose = tuple(v for v in motion.pose if v.joint not in ours)
        clash = sorted(ours & {j.name for j in robot.joints})
        if clash:
            raise ConfigError(
                robot.path,
                f"joint {clash[0]!r} is also a [[joint]] of the configuration: rename one",
            )
    return joint_values(robot, pose)


def urdf_mechanism(robot: Robot, bodies: Sequence, motion=None) -> Mechanism:
    """The ``Mechanism`` of a URDF robot: each link's parts among ``bodies``, posed as
    ``motion`` says.

    The robot's parts are the bodies of its file (``Body.path`` is ``robot.path``), named
    ``PATH#LINK``, or ``PATH#LINK#k`` for the shells of a split part (``load.split_body``).
    """
    known = {c.link for c in robot.collisions}
    prefix = f"{robot.path}#"
    parts: dict[str, list[int]] = {}
    for k, body in enumerate(bodies):
        if body.path != robot.path:
            continue
        link = body.name.removeprefix(prefix)
        if link not in known:  # a shell of a split part
            link = link.rpartition("#")[0]
        parts.setdefault(link, []).append(k)
    return Mechanism(robot, parts, adjacent=adjacent_links(robot), pose=urdf_pose(robot, motion))


class Joined(NamedTuple):
    """A link's collision elements as one mesh in the link frame, and each element.

    Attributes
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
        The union of the closed elements (manifold3d), then the open ones.
    elements : tuple of load.body.PartElement
        Each element, cleaned, in the link frame, in file order.
    """

    vertices: np.ndarray
    faces: np.ndarray
    elements: tuple


def join_elements(path: str, link: str, elements: Sequence[Collision], geometry) -> Joined:
    """One mesh of a link's several collision elements (``Joined``).

    Each element is placed in the link frame (its origin and scale; a mirroring scale
    flips its triangles) and cleaned; the closed ones are joined by manifold3d's union, so
    elements that overlap by design (a post sunk into its plate) make one solid whose volume
    counts once. When manifold3d refuses them (or an element is open), the elements are kept
    side by side: a finding's volume may then count their overlap twice.
    """
    from .body import PartElement

    name = f"{path}#{link}"
    parts = []
    for c in elements:
        mesh, scale = geometry(c)
        local = c.origin if scale is None else c.origin @ np.diag([*scale, 1.0])
        v = np.asarray(mesh.vertices, dtype=np.float64) @ local[:3, :3].T + local[:3, 3]
        f = np.asarray(mesh.faces, dtype=np.int64)
        if np.linalg.det(local[:3, :3]) < 0.0:
            f = f[:, ::-1]
        v, f = clean_arrays(v, f, name)
        element = CollisionElement(link, c.index, c.name)
        parts.append(PartElement(element, v, f, bool(topology.is_closed(f))))
    closed = [p for p in parts if p.is_closed]
    pieces = [(p.vertices, p.faces) for p in parts if not p.is_closed]
    union = _union([(p.vertices, outward_faces(p.vertices, p.faces)) for p in closed])
    if union is None:
        pieces = [(p.vertices, p.faces) for p in closed] + pieces
        if len(closed) > 1:
            warn(name, "manifold3d could not join its collision elements into one solid; they "
                 "are checked side by side (a volume may count their overlap twice)")  # fmt: skip
    else:
        pieces.insert(0, union)
    vertices, faces, offset = [], [], 0
    for v, f in pieces:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return Joined(np.vstack(vertices), np.vstack(faces), tuple(parts))


def _union(solids: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray] | None:
    """The union of closed, outward meshes (manifold3d); None when there are none or it refuses
    one."""
    if not solids:
        return None
    import manifold3d

    check_boolean_room(sum(len(f) for _, f in solids), "union", inputs=2)
    made = [manifold_solid(v, f) for v, f in solids]
    if any(solid is None for solid in made):
        return None
    out = manifold3d.Manifold.batch_boolean(made, manifold3d.OpType.Add).to_mesh64()
    v = np.asarray(out.vert_properties, dtype=np.float64)[:, :3].reshape(-1, 3)
    f = np.asarray(out.tri_verts, dtype=np.int64).reshape(-1, 3)
    return (v, f) if len(f) else None


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
            label = col.get("name")
            collisions.append(
                Collision(
                    name,
                    k,
                    _origin(path, col),
                    _shape(path, col, f"link {name!r}"),
                    label.strip() if label and label.strip() else None,
                )
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


def parse_xml(
    path: str,
    data: bytes,
    *,
    max_elements: int = MAX_ELEMENTS,
    positions: dict | None = None,
) -> ElementTree.Element:
    """An XML document's element tree, read by expat with no DOCTYPE and no entities.

    Parameters
    ----------
    path : str
        The file, for messages.
    data : bytes
        Its content.
    max_elements : int
        Elements the document may hold (its depth is bounded by ``MAX_DEPTH``).
    positions : dict, optional
        Filled with ``id(element) -> (line, start, end)`` for every element: its first line
        (from 1) and its bytes ``data[start:end]``, start tag to end tag (or the empty tag).

    Raises
    ------
    InputError
        Not well-formed, declares a document type or entity, or exceeds ``max_elements`` or
        ``MAX_DEPTH``.
    """
    parser = xml.parsers.expat.ParserCreate()
    builder = ElementTree.TreeBuilder()
    depth = [0, 0]  # current depth, elements seen
    open_: list[tuple] = []  # (element, line, start) of the elements not yet closed

    def refuse(*_):
        raise _Refused("declares a document type or entities (refused: entity expansion)")

    def start(tag, attrs):
        depth[0] += 1
        depth[1] += 1
        if depth[0] > MAX_DEPTH or depth[1] > max_elements:
            raise _Refused(f"more than {max_elements} elements or {MAX_DEPTH} levels deep")
        element = builder.start(tag, attrs)
        if positions is not None:
            open_.append((element, parser.CurrentLineNumber, parser.CurrentByteIndex))

    def end(tag):
        depth[0] -= 1
        builder.end(tag)
        if positions is not None:
            element, line, begin = open_.pop()
            finish = _tag_end(data, begin)
            if data[finish - 2 : finish] != b"/>":  # not an empty tag: to its end tag's ">"
                finish = data.index(b">", parser.CurrentByteIndex) + 1
            positions[id(element)] = (line, begin, finish)

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


#: A start tag from its ``<`` to its ``>``, quoted attribute values skipped (possessive: linear).
_TAG = re.compile(rb"""(?:[^>"']++|"[^"]*+"|'[^']*+')*+>""")


def _tag_end(data: bytes, start: int) -> int:
    """The byte after the ``>`` closing the tag that starts at ``start`` (quotes skipped)."""
    found = _TAG.match(data, start)
    return found.end() if found else len(data)


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

    Each of ``package_paths`` offers: itself when it is named ``package`` or its
    ``package.xml`` names it; its child folder ``package``; a child folder whose
    ``package.xml`` names it. The URDF's folder and each of its ancestors offer: itself, and
    its child folder ``package``, when their ``package.xml`` names ``package`` (a package is a
    folder that says so: a folder merely named like it above the URDF, ``/home`` for
    ``package://home/...``, is none).
    """
    start = os.path.dirname(os.path.abspath(urdf_path))
    out = []
    for base in package_paths:
        if os.path.basename(os.path.normpath(base)) == package or _package_name(base) == package:
            out.append(base)
        if os.path.isdir(os.path.join(base, package)):
            out.append(os.path.join(base, package))
        out.extend(
            os.path.join(base, d)
            for d in sorted(_subdirs(base))
            if _package_name(os.path.join(base, d)) == package
        )
    for base in _ancestors(start):
        for candidate in (base, os.path.join(base, package)):
            if _package_name(candidate) == package:
                out.append(candidate)
    return out


def _ancestors(folder: str) -> list[str]:
    """``folder`` and each folder above it, up to the root."""
    out = []
    while True:
        out.append(folder)
        up = os.path.dirname(folder)
        if up == folder:
            return out
        folder = up


def own_roots(urdf_path: str, package_paths=()) -> list[str]:
    """The folders any file a URDF names may lie in: its folder, the package it lies in (the
    nearest folder above it holding a ``package.xml``), and ``package_paths``."""
    folder = os.path.dirname(os.path.abspath(urdf_path))
    out = [folder]
    package = next((a for a in _ancestors(folder) if _package_name(a) is not None), None)
    if package is not None:
        out.append(package)
    return out + [os.path.abspath(p) for p in package_paths]


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


def is_inside(path: str, roots: Sequence[str]) -> bool:
    """Whether ``path`` lies inside ``roots``, by the letter of the path (``..`` resolved)
    and after its symbolic links are followed."""
    lexical, real = os.path.abspath(path), os.path.realpath(path)

    def within(p: str, folders) -> bool:
        return any(is_within(r, p) for r in folders)

    return within(lexical, [os.path.abspath(r) for r in roots]) and within(
        real, [os.path.realpath(r) for r in roots]
    )


def resolve_mesh(
    urdf_path: str, filename: str, package_paths=(), *, allow_outside: bool = False
) -> str:
    """The file a URDF mesh ``filename`` names (``package://``, ``file://`` or a path).

    ``package://NAME/REL`` is ``REL`` below the first root of package NAME
    (``package_roots``) that holds it; anything else is a path, relative to the URDF's folder.

    Raises
    ------
    InputError
        The file is missing; or it lies outside the package root it was found in and the
        URDF's own folders (``own_roots``), by ``..``, an absolute path or a symbolic link,
        and ``allow_outside`` is off (the check does not read what is not the robot's).
    """
    roots = own_roots(urdf_path, package_paths)
    hint = "refused (--allow-outside-paths reads it)"
    if filename.startswith("package://"):
        package, _, rel = filename[len("package://") :].partition("/")
        for root in package_roots(urdf_path, package, package_paths) if package else ():
            candidate = os.path.join(root, rel)
            if not allow_outside and not is_inside(candidate, [root, *roots]):
                raise InputError(
                    urdf_path, f"mesh {filename}: leads outside package {package!r}: {hint}"
                )
            if os.path.isfile(candidate):
                return candidate
        raise InputError(
            urdf_path,
            f"mesh {filename}: not found in package {package!r} (looked in the URDF's folder, its "
            "ancestors and --package-path, for a package.xml naming it)",
        )
    if filename.startswith("file://"):
        filename = filename[len("file://") :]
    if not os.path.isabs(filename):
        filename = os.path.join(os.path.dirname(urdf_path), filename)
    if not allow_outside and not is_inside(filename, roots):
        raise InputError(
            urdf_path,
            f"mesh {filename}: outside the URDF's folder, its package and --package-path: {hint}",
        )
    if not os.path.isfile(filename):
        raise InputError(urdf_path, f"mesh {filename}: no such file")
    return filename


def _geometry(
    robot: Robot, c: Collision, package_paths, budget: Budget, meshes: dict, *, allow_outside
):
    """(mesh, scale or None) of a collision element; each file or primitive built once."""
    kind = c.shape[0]
    if kind == "mesh":
        _, filename, scale = c.shape
        found = resolve_mesh(robot.path, filename, package_paths, allow_outside=allow_outside)
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
    "Joined",
    "is_inside",
    "join_elements",
    "own_roots",
    "package_roots",
    "parse_robot",
    "parse_xml",
    "read_urdf",
    "resolve_mesh",
    "urdf_mechanism",
    "urdf_pose",
]
