"""A STEP file's bytes -> its tessellated solids (from the cache, or OpenCASCADE) and its exact
ones, as read (kept, or read when the verify stage first asks for them)."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import trimesh

from ...cache import Tessellation, TessellationCache, tessellation_key
from ...errors import InputError
from ...units import METRES
from . import ahead
from .assembly import Instance, named_instances, placed_solids
from .document import read_document
from .tessellate import (
    DEFAULT_ANGULAR_DEFLECTION,
    MAX_STEP_TRIANGLES,
    PREPARE_BYTES,
    Products,
    brep_text,
    placed_meshes,
    products,
    tessellate,
)
from .units import mesh_settings, warn_no_unit

if TYPE_CHECKING:
    from ...execute import Executor


class StepSolids:
    """The exact solids of one STEP file, by part node name: what its parts' triangles
    approximate, for the verify stage to decide their pairs on (``meshcheck.verify.brep``).

    Made by ``read_step`` from the bytes the load stage read and checked, and kept by the
    file's bodies (``Body.brep``), so no later stage opens the file. When the file was read to be
    tessellated, its solids are the instances read then (the mesher worked on a copy of their
    topology: they hold no triangulation); when a worker read it ahead (``ahead``), their BRep
    texts are the ones it wrote from them; when the tessellation came from the cache, the bytes
    are kept and read into a document when a solid is first asked for, and only then. Either
    way the solids are the file as a fresh read gives them, whatever the cache held.

    What fixes a solid in the world is known without reading the document: its product (one per
    distinct tessellated product, numbered in node order) and its placement, both from the
    tessellation (``product``, ``placement_mm``); a pair of solids is decided in the first one's
    frame, so instances of one product share their verdicts (``meshcheck.verify.brep``).

    The solids are OpenCASCADE shapes and stay in this process: a pickled copy (a body sent to
    a worker) keeps the path, digest and placements, not the shapes nor the bytes, and
    ``by_node`` and ``product_text`` refuse there. Workers get a product as OpenCASCADE's BRep
    text (``product_text``), a few milliseconds to read, instead of the document.

    Attributes
    ----------
    path : str
        The file, as given.
    digest : str
        Hex SHA-256 of its content.
    unit : str
        The length unit the file declares (its tessellation's).
    """

    def __init__(
        self,
        path: str,
        data: bytes,
        instances: list[Instance] | None = None,
        *,
        items: list[tuple[str, trimesh.Trimesh, np.ndarray]] = (),
        unit: str = "mm",
        texts: dict[str, bytes] | None = None,
    ):
        self.path = path
        self.digest = hashlib.sha256(data).hexdigest()
        self.unit = unit
        self._data = data if instances is None else None
        self._instances = instances
        self._solids: dict[str, object] | None = None
        self._texts: dict[int, bytes] = {}
        self._named: dict[str, Instance] | None = None
        to_mm = METRES[unit] / 1e-3
        products: dict[int, int] = {}  # id(mesh) -> product number
        self._nodes: dict[str, tuple[int, np.ndarray]] = {}
        for name, mesh, transform in items:
            matrix = np.array(transform, dtype=np.float64)
            matrix[:3, 3] *= to_mm
            self._nodes[name] = (products.setdefault(id(mesh), len(products)), matrix)
        for node, text in (texts or {}).items():  # by node, from the worker that read the file
            if node in self._nodes:
                self._texts.setdefault(self.product(node), text)

    def has_node(self, node: str) -> bool:
        """Whether ``node`` names one of the file's tessellated solids."""
        return node in self._nodes

    def product(self, node: str) -> int:
        """The product number of ``node``'s solid: instances of one product share it."""
        return self._nodes[node][0]

    def placement_mm(self, node: str) -> np.ndarray:
        """(4, 4) float64: ``node``'s solid's placement, product frame to the file's assembly
        frame, millimetres (OpenCASCADE's unit)."""
        return self._nodes[node][1]

    def by_node(self) -> dict[str, object]:
        """The placed solids (``TopoDS_Shape``, the assembly's frame, millimetres whatever the
        file declares), by node name: ``read_step``'s names, from the same walk of the same
        bytes.

        Raises
        ------
        InputError
            As ``read_step`` for the same bytes; or the solids are asked for in another process.
        """
        if self._solids is None:
            self._solids = dict(placed_solids(self._document()))
        return self._solids

    def product_text(self, node: str) -> bytes:
        """``node``'s product as OpenCASCADE's BRep text, in the product's own frame,
        millimetres, without triangulation: what a worker reads the solid from.

        Raises
        ------
        InputError
            As ``by_node``.
        """
        product = self.product(node)
        if product not in self._texts:
            if self._named is None:
                self._named = dict(named_instances(self._document()))
            self._texts[product] = brep_text(self._named[node].product)
        return self._texts[product]

    def text_length(self, node: str) -> int | None:
        """The length of ``node``'s product text (``product_text``) when it is in hand (read
        with the file), None when it is not: nothing is read for it."""
        text = self._texts.get(self.product(node))
        return None if text is None else len(text)

    def _document(self) -> list[Instance]:
        """The file's instances: kept from the tessellation, or read from the bytes once."""
        if self._instances is None:
            if self._data is None:
                raise InputError(self.path, "its exact solids stay in the process that read it")
            self._instances = read_document(self._data, self.path)
            self._data = None
        return self._instances

    def __getstate__(self) -> dict:
        return {"path": self.path, "digest": self.digest, "unit": self.unit, "nodes": self._nodes}

    def __setstate__(self, state: dict) -> None:
        self.path, self.digest, self.unit = state["path"], state["digest"], state["unit"]
        self._nodes = state["nodes"]
        self._data, self._instances, self._solids, self._texts = None, None, None, {}
        self._named = None


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
        The length unit the file declares, a key of ``meshcheck.units.METRES`` (``"mm"`` when it
        declares none that is recognised, with a warning).
    deflection : float
        Linear deflection of the tessellation, ``unit``: the triangles lie within this of the
        CAD faces, so a gap or depth is uncertain by up to twice this.
    angular_deflection : float
        Angular deflection of the tessellation, radians.
    solids : StepSolids
        The exact solids the items were tessellated from, by name.
    """

    items: list[tuple[str, trimesh.Trimesh, np.ndarray]]
    unit: str
    deflection: float
    angular_deflection: float
    solids: StepSolids


def read_step(
    path: str,
    *,
    data: bytes | None = None,
    deflection: float | None = None,
    deflection_unit: str | None = None,
    unit: str | None = None,
    angular_deflection: float | None = None,
    cache: TessellationCache | None = None,
    max_triangles: int | None = None,
    executor: Executor | None = None,
) -> StepAssembly:
    """Tessellate the solids of a STEP file, in the unit the file declares.

    Parameters
    ----------
    path : str
        A STEP (ISO 10303-21) file.
    data : bytes, optional
        Its content, when the caller has read it already (the load stage, within its limits);
        default: read from ``path``.
    deflection : float, optional
        Largest distance between a curved face and its triangles, in ``deflection_unit``.
        Default ``DEFAULT_DEFLECTION_MM`` millimetres, or ``DEFAULT_RELATIVE_DEFLECTION`` of
        the largest solid's diagonal when that is more.
    deflection_unit : str, optional
        Unit of ``deflection``, a key of ``meshcheck.units.METRES``; default the file's own unit.
    unit : str, optional
        The unit the file's lengths really are in (``--units FILE=UNIT``): deflections are
        meant in it; the assembly keeps the file's numbers and declared unit.
    angular_deflection : float, optional
        Largest angle between neighbouring facets, radians; default
        ``DEFAULT_ANGULAR_DEFLECTION``.
    cache : TessellationCache, optional
        Where tessellations are kept, by file content and settings.
    max_triangles : int, optional
        Triangles the file may be tessellated into (distinct products once); default and upper
        bound ``MAX_STEP_TRIANGLES``.
    executor : execute.Executor, optional
        The run's executor: its workers mesh the products when they loaded OpenCASCADE while
        the file was read (``tessellate``); the same triangles as here.

    Returns
    -------
    StepAssembly

    Raises
    ------
    InputError
        The file cannot be read, is not STEP, holds no solid, has an assembly cycle, a dangling
        or an external reference, a solid outside every placed product, or the deflection cannot
        be honoured (see the module docstring).
    ValueError
        ``deflection`` or ``angular_deflection`` is not a positive finite number, or
        ``deflection_unit`` is unknown (options are the caller's to validate).

    Examples
    --------
    >>> asm = read_step("sample_meshes/assembly.step")
    >>> asm.unit, [name for name, _, _ in asm.items][:3]
    ('mm', ['bolt_m6', 'bolt_m6_1', 'bolt_m6_2'])
    """
    _check_deflections(deflection, deflection_unit, angular_deflection)
    angular = (
        DEFAULT_ANGULAR_DEFLECTION if angular_deflection is None else float(angular_deflection)
    )
    data = _read_bytes(path) if data is None else data
    real_unit = unit
    declared, unit, wanted_mm, ratio = mesh_settings(data, deflection, deflection_unit, real_unit)
    budget = MAX_STEP_TRIANGLES if max_triangles is None else min(max_triangles, MAX_STEP_TRIANGLES)

    key = tessellation_key(data, wanted_mm, angular, default_scale=ratio) if cache else ""
    found = cache.get(key) if cache is not None else None
    instances, texts = None, None
    if found is None or found.unit != unit:
        read = ahead.take(path, data, (unit, wanted_mm, angular, ratio), executor)
        if read is None:
            instances = read_document(data, path)
            read = products(instances, path, wanted_mm, angular, unit, ratio)
        else:
            texts = {n: read.solid_texts[i.product_key] for n, i in named_instances(read.instances)}
        # A small file's products are meshed here (or welded here, from the triangles of the
        # worker that read it ahead): a worker would import trimesh to weld them.
        meshers = executor if len(data) >= PREPARE_BYTES else None
        found = _tessellation(read, path, angular, budget, unit, meshers)
        if cache is not None:
            cache.put(key, found)
    else:
        ahead.drop(path)  # nothing to read: the worker reading it ahead, if any, stops
    if declared is None and real_unit is None:
        warn_no_unit(path)
    solids = StepSolids(path, data, instances, items=found.items, unit=found.unit, texts=texts)
    return StepAssembly(*found, solids=solids)


def _tessellation(
    read: Products,
    path: str,
    angular: float,
    budget: int,
    unit: str,
    executor: Executor | None = None,
) -> Tessellation:
    """The products meshed (``tessellate``), closed and named, in the file's ``unit``."""
    to_unit = 1e-3 / METRES[unit]  # file units per mm
    meshes = tessellate(read, path, angular, budget, unit, executor=executor)
    held = read.deflection_mm * to_unit
    items, deflection = placed_meshes(read.instances, meshes, path, to_unit, held)
    return Tessellation(items, unit, deflection, angular)


def _check_deflections(deflection, deflection_unit, angular_deflection) -> None:
    """Refuse (ValueError) an unknown unit or a deflection that is not a positive number."""
    if deflection_unit is not None and deflection_unit not in METRES:
        raise ValueError(f"unknown length unit {deflection_unit!r}")
    for value in (deflection, angular_deflection):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"deflection must be a positive number, not {value!r}")


def _read_bytes(path: str) -> bytes:
    """The content of ``path`` (for callers that have not read it)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if not data:
        raise InputError(path, "empty file")
    return data
