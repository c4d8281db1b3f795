"""3MF files (a zip of XML), read with the standard library and streamed within the budget.

The model entry's declared size is checked before it is opened, and the stream is capped as it is
read (a zip can lie); the XML is parsed incrementally, keeping only numbers, so memory follows
the mesh, not the markup. Components are counted (instances and triangles, multiplied through
the component tree) before any is expanded.
"""

from __future__ import annotations

import io
import zipfile
from array import array
from xml.etree import ElementTree

import numpy as np
import trimesh

from ..errors import InputError
from ..units import unit_name
from .limits import Budget, num
from .scene import one_line

Item = tuple[str, trimesh.Trimesh, np.ndarray]
_SMALL_ENTRY = 16 << 20  # _rels/.rels: a few hundred bytes in practice
# 3MF XML deflates 5 to 20 times; a model entry above _SMALL_ENTRY deflated more than this is a
# zip bomb (it would cost time to parse even within the size limit), refused unread.
BOMB_RATIO = 200


class _Capped:
    """A read-only stream that refuses to yield more than ``cap`` bytes."""

    def __init__(self, raw, cap: int, path: str, what: str):
        self.raw, self.cap, self.path, self.what, self.total = raw, cap, path, what, 0

    def read(self, size: int = -1) -> bytes:
        chunk = self.raw.read(min(size, 1 << 20) if size and size > 0 else 1 << 20)
        self.total += len(chunk)
        if self.total > self.cap:
            raise InputError(
                self.path,
                f"3MF entry {self.what} holds more than the limit of {num(self.cap)} bytes",
            )
        return chunk


def read_3mf(path: str, data: bytes, budget: Budget) -> tuple[list[Item], str]:
    """(node name, local mesh, placement) of every mesh the build places, and the file's unit.

    A build item is named by its object's ``name`` attribute (else ``object<ID>``); an object
    made of components gives one body per mesh it reaches, named ``ITEM/COMPONENT`` with the
    component object's name (else ``component<k>``, k counting from 1); a name used twice gets
    ``_2``, ``_3``... in build order. The unit is the model's ``unit`` (default millimetre).
    """
    limits = budget.limits
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            model_name = _model_name(path, z, min(limits.max_file_bytes, _SMALL_ENTRY))
            info = z.getinfo(model_name)
            if info.file_size > limits.max_file_bytes:
                raise InputError(
                    path,
                    f"3MF entry {model_name} declares {num(info.file_size)} bytes uncompressed, "
                    f"over the limit of {num(limits.max_file_bytes)}",
                )
            ratio = info.file_size / max(info.compress_size, 1)
            if info.file_size > _SMALL_ENTRY and ratio > BOMB_RATIO:
                raise InputError(
                    path,
                    f"3MF entry {model_name} declares {num(info.file_size)} bytes compressed into "
                    f"{num(info.compress_size)} ({ratio:.0f}:1), the ratio of a zip bomb",
                )
            with z.open(info) as raw:
                stream = _Capped(raw, limits.max_file_bytes, path, model_name)
                model = _parse(path, stream, budget)
    except InputError:
        raise
    except (zipfile.BadZipFile, KeyError, ElementTree.ParseError, OSError, EOFError) as exc:
        raise InputError(path, f"cannot be read as 3MF: {one_line(exc)}") from None
    except (RuntimeError, NotImplementedError) as exc:  # encrypted or unsupported compression
        raise InputError(path, f"cannot be read as 3MF: {one_line(exc)}") from None
    objects, build, unit = model
    try:
        unit = unit_name(unit or "millimeter")
    except ValueError:
        raise InputError(path, f"3MF model declares an unknown unit {unit[:40]!r}") from None

    counts = _count_instances(path, objects, [oid for oid, _ in build])
    parts = sum(counts[oid][0] for oid, _ in build)
    triangles = sum(counts[oid][1] for oid, _ in build)
    budget.check_parts(path, parts, "placed meshes")
    budget.check_triangles(path, triangles, "placed triangles")

    meshes: dict[str, trimesh.Trimesh] = {}
    items = []
    for oid, transform_text in build:
        obj = objects[oid]
        label = obj["name"] or f"object{oid}"
        stack = [(oid, _transform(path, transform_text), label)]
        while stack:
            oid, transform, label = stack.pop()
            obj = objects[oid]
            if obj["verts"] is not None:
                if len(obj["tris"]):
                    if oid not in meshes:
                        verts = np.frombuffer(obj["verts"], dtype=np.float64).reshape(-1, 3)
                        tris = np.frombuffer(obj["tris"], dtype=np.int64).reshape(-1, 3)
                        meshes[oid] = trimesh.Trimesh(verts, tris, process=False)
                    items.append((label, meshes[oid], transform))
                continue
            comps = obj["components"]
            for k in range(len(comps) - 1, -1, -1):
                child, text = comps[k]
                sub = objects[child]["name"] or f"component{k + 1}"
                stack.append((child, transform @ _transform(path, text), f"{label}/{sub}"))
    used: dict[str, int] = {}
    named = []
    for node, mesh, transform in items:
        used[node] = used.get(node, 0) + 1
        named.append((node if used[node] == 1 else f"{node}_{used[node]}", mesh, transform))
    if not named:
        raise InputError(path, "holds no triangles")
    return named, unit


def _parse(path: str, stream, budget: Budget):
    """Objects, build items and unit of a 3MF model, parsed incrementally.

    Returns
    -------
    objects : dict
        id -> {"name", "verts" (array of float64 or None), "tris" (array of int64),
        "components" [(objectid, transform text)]}
    build : list of (objectid, transform text)
    unit : str or None
    """
    objects: dict[str, dict] = {}
    build: list[tuple[str, str | None]] = []
    unit = None
    ns = None
    stack: list[ElementTree.Element] = []
    obj = None
    in_build = False
    room = budget.limits.max_triangles - budget.triangles
    triangles = 0
    try:
        for event, elem in ElementTree.iterparse(stream, events=("start", "end")):
            tag = elem.tag
            if ns is None:
                ns = tag[: tag.index("}") + 1] if tag.startswith("{") else ""
                unit = elem.get("unit")
            local = tag[len(ns) :] if tag.startswith(ns) else None
            if event == "start":
                stack.append(elem)
                if local == "object":
                    obj = {"name": elem.get("name"), "verts": None, "tris": None, "components": []}
                    objects[elem.get("id")] = obj
                elif local == "mesh" and obj is not None:
                    obj["verts"], obj["tris"] = array("d"), array("q")
                elif local == "build":
                    in_build = True
                continue
            stack.pop()
            if local == "vertex" and obj is not None and obj["verts"] is not None:
                obj["verts"].extend(
                    (float(elem.get("x")), float(elem.get("y")), float(elem.get("z")))
                )
            elif local == "triangle" and obj is not None and obj["tris"] is not None:
                obj["tris"].extend((int(elem.get("v1")), int(elem.get("v2")), int(elem.get("v3"))))
                triangles += 1
                if triangles > room:
                    budget.check_triangles(path, triangles, "triangles in its meshes (at least)")
            elif local == "component" and obj is not None:
                obj["components"].append((elem.get("objectid"), elem.get("transform")))
            elif local == "object":
                obj = None
            elif local == "build":
                in_build = False
            elif local == "item" and in_build:
                build.append((elem.get("objectid"), elem.get("transform")))
            if stack:
                stack[-1].remove(elem)  # keep memory flat: the numbers are stored already
    except (TypeError, ValueError) as exc:
        raise InputError(path, f"malformed 3MF mesh: {one_line(exc)}") from None
    return objects, build, unit


def _count_instances(path: str, objects: dict, roots: list) -> dict[str, tuple[int, int]]:
    """(meshes reached, triangles placed) per object, through its components; refuses cycles."""
    done: dict[str, tuple[int, int]] = {}
    visiting: set[str] = set()
    for root in roots:
        if root not in objects:
            raise InputError(path, f"3MF build item refers to missing object {root}")
        stack = [(root, False)]
        while stack:
            oid, expanded = stack.pop()
            if oid in done:
                continue
            obj = objects[oid]
            if obj["verts"] is not None:
                done[oid] = (1, len(obj["tris"]) // 3) if len(obj["tris"]) else (0, 0)
                continue
            children = [child for child, _ in obj["components"]]
            if expanded:
                visiting.discard(oid)
                done[oid] = (sum(done[c][0] for c in children), sum(done[c][1] for c in children))
                continue
            visiting.add(oid)
            stack.append((oid, True))
            for child in children:
                if child not in objects:
                    raise InputError(path, f"3MF component refers to missing object {child}")
                if child in visiting:
                    raise InputError(path, f"3MF components form a cycle through object {child}")
                if child not in done:
                    stack.append((child, False))
    return done


def _model_name(path: str, z: zipfile.ZipFile, cap: int) -> str:
    """The archive member holding the 3D model (from _rels/.rels, else 3D/3dmodel.model)."""
    try:
        info = z.getinfo("_rels/.rels")
    except KeyError:
        return "3D/3dmodel.model"
    if info.file_size > cap:
        raise InputError(path, f"3MF entry _rels/.rels declares {num(info.file_size)} bytes")
    with z.open(info) as raw:
        text = _Capped(raw, cap, path, "_rels/.rels").read(cap + 1)
    try:
        rels = ElementTree.fromstring(text)
    except ElementTree.ParseError:
        return "3D/3dmodel.model"
    for rel in rels.iter():
        target = rel.get("Target")
        if target and target.lower().endswith(".model"):
            return target.lstrip("/")
    return "3D/3dmodel.model"


def _transform(path: str, text: str | None) -> np.ndarray:
    """3MF ``transform`` attribute (12 numbers, row-vector convention) -> (4, 4) float64."""
    out = np.eye(4)
    if not text:
        return out
    try:
        m = np.array([float(x) for x in text.split()], dtype=np.float64)
    except ValueError:
        m = np.empty(0)
    if m.shape != (12,):
        raise InputError(path, f"malformed 3MF transform {text[:80]!r}")
    if not np.all(np.isfinite(m)):
        raise InputError(path, "3MF transform holds NaN or infinite values")
    m = m.reshape(4, 3)
    out[:3, :3] = m[:3].T
    out[:3, 3] = m[3]
    return out
