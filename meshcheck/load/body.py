"""The part type every reader produces, and what the load stage hands down."""

from __future__ import annotations

import functools
import hashlib
from dataclasses import InitVar, dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import trimesh

from ..mesh import is_closed
from ..results import CollisionElement
from .robot import Mechanism

if TYPE_CHECKING:
    from .step import StepSolids


class PartElement(NamedTuple):
    """One collision element of a part made of several (a URDF link's), in the part's frame.

    Attributes
    ----------
    element : results.CollisionElement
        Which element it is (link, index, name).
    vertices : (n, 3) float64
        Cleaned, in the part's own frame and the file's unit (as ``Body.mesh``).
    faces : (m, 3) int64
    is_closed : bool
    """

    element: CollisionElement
    vertices: np.ndarray
    faces: np.ndarray
    is_closed: bool


@dataclass(frozen=True, eq=False)
class Body:
    """One part of the assembly.

    Attributes
    ----------
    name : str
        ``PATH`` or ``PATH#NODE`` (see the ``meshcheck.load`` docstring).
    path : str
        The file the body came from, as given.
    mesh : trimesh.Trimesh
        Geometry in its own frame and the file's unit, as stored in the file (shared between
        instances).
    transform : (4, 4) float64
        Homogeneous transform from the mesh's frame to world coordinates in the report unit: the
        placement in the file, then the conversion from the file's unit.
    relative_name : str
        The name relative to the argument the body came from: ``RELPATH[#NODE]`` below a
        directory argument, ``basename(PATH)[#NODE]`` for a file argument. Defaults to ``name``.
    units : str
        The report unit (``meshcheck.units``) of the world coordinates.
    deflection : float
        How far the triangles may lie from the true surface, report units: the tessellation
        tolerance of a part read from CAD (STEP), 0 for a mesh file (the mesh is the part).
    is_float32 : bool
        Whether its coordinates went through float32 on the way here (binary STL, float PLY, glTF,
        STEP through its GLB), so coincident faces far from the origin can be float32 rounding
        apart (``settings.pair_tolerances``). False for coordinates read in double (ASCII STL,
        OBJ, OFF, double PLY, 3MF). Default True: a body built in Python claims nothing.
    is_rescaled : bool
        Whether the user gave its file a unit other than the one it was read in (``--units
        FILE=UNIT``): its lengths are not what the file says, so the file's own B-rep (a STEP
        solid, in the declared unit) is not this part (``verify.brep`` leaves it alone).
    brep : load.step.StepSolids or None
        The exact solids of its STEP file, kept in the process that loaded it (the verify stage
        confirms findings on them, ``verify.brep``); None for a mesh file or a part built in
        Python.
    elements : tuple of PartElement
        The collision elements a URDF link of several is made of (its mesh is their union):
        a finding names the ones it involves (``verify.elements``). Empty otherwise.
    source_digest : str
        What the part's finding IDs hash as its geometry when its triangles are only one
        rendering of it: a STEP solid's product B-rep (hex SHA-256 of its BRep text), which
        another deflection or mesher does not change. Empty: its mesh's ``digest``
        (``id_digest``).
    known_digest : str, optional
        ``mesh_digest(mesh)`` when the caller has it (a reader hashes a mesh once, however many
        instances place it); not kept as a field, so ``dataclasses.replace`` never carries it
        to another mesh. Default: computed on first use of ``digest``.
    """

    name: str
    path: str
    mesh: trimesh.Trimesh
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    relative_name: str = ""
    units: str = "mm"
    deflection: float = 0.0
    is_float32: bool = True
    is_rescaled: bool = False
    brep: StepSolids | None = field(default=None, repr=False)
    elements: tuple[PartElement, ...] = field(default=(), repr=False)
    source_digest: str = field(default="", repr=False)
    known_digest: InitVar[str | None] = None

    def __post_init__(self, known_digest: str | None):
        if not self.relative_name:
            object.__setattr__(self, "relative_name", self.name)
        if known_digest is not None:
            self.__dict__["digest"] = known_digest  # the cached value of ``digest``

    @functools.cached_property
    def world(self) -> trimesh.Trimesh:
        """The mesh in world coordinates, report units."""
        if np.array_equal(self.transform, np.eye(4)):
            return self.mesh
        return self.mesh.copy().apply_transform(self.transform)

    @functools.cached_property
    def digest(self) -> str:
        """Hex SHA-256 of the body's own geometry (vertices and faces, frame-local)."""
        return mesh_digest(self.mesh)

    @property
    def id_digest(self) -> str:
        """The geometry digest its finding IDs hash: ``source_digest``, else ``digest``."""
        return self.source_digest or self.digest

    @property
    def is_closed(self) -> bool:
        """True when the mesh bounds a volume (see ``meshcheck.mesh.is_closed``)."""
        return is_closed(self.mesh)


@dataclass(frozen=True)
class Assembly:
    """What the load stage hands down: the parts, and the robots among them.

    Attributes
    ----------
    bodies : list of Body
    mechanisms : tuple of Mechanism
        Every URDF robot, in the order their parts come, then the mechanism the configuration's
        ``[[joint]]`` tables make of mesh parts; each link's parts are indices into ``bodies``.
    """

    bodies: list[Body]
    mechanisms: tuple[Mechanism, ...] = ()


def mesh_digest(mesh: trimesh.Trimesh) -> str:
    """Hash a mesh's vertices and faces (float64 / int64 bytes) into a hex SHA-256."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    return h.hexdigest()


class LocalGeometry(NamedTuple):
    """A mesh's geometry up to translation, and its digest (``local_geometry``).

    Attributes
    ----------
    local : (n, 3) float64
        Vertices moved so their lowest corner (per-axis minimum) is the origin.
    faces : (m, 3) int64
        Triangles.
    corner : (3,) float64
        The lowest corner; ``local + corner`` is the mesh, up to rounding.
    digest : str
        Hex SHA-256 of ``local`` and ``faces``: equal for copies of a mesh moved by a translation
        that leaves their coordinates' bits alone (instances, exact offsets).
    """

    local: np.ndarray
    faces: np.ndarray
    corner: np.ndarray
    digest: str


def local_geometry(mesh) -> LocalGeometry:
    """A mesh's geometry up to translation, and its digest (see ``LocalGeometry``)."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    corner = vertices.min(axis=0) if len(vertices) else np.zeros(3)
    local = np.ascontiguousarray(vertices - corner)
    h = hashlib.sha256(local.tobytes())
    h.update(faces.tobytes())
    return LocalGeometry(local, faces, corner, h.hexdigest())


def local_geometries(bodies) -> dict[int, LocalGeometry]:
    """``local_geometry`` of each distinct mesh of ``bodies``, by ``id(mesh)`` (the bodies keep
    the meshes alive while the dict is used)."""
    out: dict[int, LocalGeometry] = {}
    for body in bodies:
        if id(body.mesh) not in out:
            out[id(body.mesh)] = local_geometry(body.mesh)
    return out
