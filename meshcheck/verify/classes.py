"""Pair classes: candidate pairs that are one situation, decided once.

An assembly repeats itself (the same bolt in forty holes, one module forty times along a line),
and every repetition is a part pair the verify stage would otherwise decide on its own. Each pair
is decided in its own frame instead, the frame of its first part, from what the pair is and not
where it is:

- the first part's geometry (``load.local_geometry``: the mesh up to translation) under the
  linear part of its placement that is not a rotation (a unit's scale, a mirror, a shear),
- the second part's geometry under its placement relative to that frame (rotation and shift),
- the pair's tolerance, the clearance, and whether the convex pieces proved the surfaces apart.

The placements in the pair's frame are rounded to a grid of ``SNAP_FRACTION`` of the pair's
tolerance (a power of two, so the rounding is exact arithmetic): two pairs whose placements round
alike are given to ``verify_pair`` as the very same arrays, so they get the very same verdict, bit
for bit, and it is computed once and moved into each pair's world frame (a rotation and a shift:
location, closest points, shared solid). Pairs whose placements round differently are different
classes and are decided apart, however close they are; no pair is ever given the verdict of
another placement. The rounding moves a part by at most ``2.4 * SNAP_FRACTION`` of the
tolerance, below the float32 rounding of the files' own coordinates, and every pair is rounded
so, whether or not another shares its class: a verdict depends on its pair alone, never on which
other pairs a run holds.

Classes are found with one hash of each pair's rounded placement, in time linear in the pairs;
which pairs share a class is a function of the inputs only. The pair cache keys on the class
(``cache.pair_key``), so a warm run, a moved assembly and a Dask run reuse the verdict too.

Another decision procedure (the B-rep stage, say) can use the same classes:

- ``pair_classes(bodies, pairs, tolerance, geometry=...)`` gives each pair's class
  (``PairClasses.label``), the pair each class is named by (``first``) and every class's
  members (``members()``);
- ``class_identity(classes, c)`` is what a class's verdict depends on (its two placed geometries,
  tolerance, surfaces flag): with the settings, the arguments of ``cache.pair_key``, to which a
  procedure adds what else its verdict depends on (a solid's identity, say);
- ``PairClasses.frame(k)`` is pair ``k``'s frame (rotation and origin); ``unplaced_verdict``
  takes a verdict decided on a pair at its world placement into its frame, and
  ``placed_verdict`` (``placed_verdicts``, many at once) moves a verdict in the frame to any
  member's place. A class decided on its first pair at that pair's world placement and moved
  so gives its members that pair's verdict, not their own to the bit (they differ by the
  rounding of their placements, at most 2.4 grid steps); one decided on the placed geometries
  (``PairClasses.arrays``) gives each member exactly its own.

Example: decide each class on its first pair's world meshes, moved to every member::

    classes = pair_classes(bodies, pairs, tolerance, geometry=local_geometries(bodies))
    for c, rows in enumerate(classes.members()):
        i, j = classes.pairs[classes.first[c]]
        here = decide(bodies[i], bodies[j])  # world coordinates
        in_frame = unplaced_verdict(here, *classes.frame(classes.first[c]))
        verdicts = placed_verdicts(in_frame, *classes.frames(rows))  # one per member
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..mesh import as_mesh, is_closed
from ..results import Location, PairVerdict, Solid

#: The grid a pair's placements are rounded to, as a fraction of its tolerance (the largest power
#: of two below it): a part moves by at most 2.4 grid steps (``_snap``), 2.4e-3 of the
#: tolerance, far below what the tolerance is there to absorb, while placements computed along
#: different paths (an instance's transform composed from its parents') agree to ~1e-16 of their
#: size and round alike.
SNAP_FRACTION = 2.0**-10


@dataclass(frozen=True)
class PlacedGeometry:
    """One geometry at one placement in a pair's frame: what ``verify_pair`` is given.

    Attributes
    ----------
    shape : int
        Index into ``PairClasses.shapes``.
    linear : (3, 3) float64
        Rounded linear map applied to the local vertices.
    shift : (3,) float64
        Rounded translation, model units.
    """

    shape: int
    linear: np.ndarray
    shift: np.ndarray

    @property
    def key(self) -> tuple:
        """Hashable identity: the shape and the placement's bits."""
        return (self.shape, self.linear.tobytes() + self.shift.tobytes())


@dataclass(frozen=True)
class PairClasses:
    """The candidate pairs of a run, grouped into classes (see the module docstring).

    Attributes
    ----------
    pairs : (k, 2) int64
        The pairs in the order given, each ordered so its first part is the one whose frame the
        class is in (a function of the two parts' geometry and placement, never of argument
        order).
    label : (k,) int64
        The class of each pair.
    first : (c,) int64
        The first pair (row) of each class, in class order: the one progress names.
    shapes : list of load.LocalGeometry
        Each distinct geometry once, in digest order.
    placed : list of (PlacedGeometry, PlacedGeometry)
        Each class's two geometries in its frame, first part first.
    tolerance : (c,) float64
        Each class's touching tolerance, model units.
    surfaces_apart : (c,) bool
        Whether the convex pieces proved each class's surfaces beyond reach (all False until
        the pipeline's piece filter has looked, ``pipeline.surfaces_near``).
    body_shape : (n,) int64
        Index into ``shapes`` of each body's geometry.
    rotation : (n, 3, 3) float64
        Rotation of each body's frame (proper; identity for bodies in no pair).
    origin : (n, 3) float64
        Origin of each body's frame: where its local geometry's lowest corner is, world
        coordinates. A pair's frame is its first part's.
    closed : list of bool
        Whether each shape is closed (``mesh.is_closed``).
    """

    pairs: np.ndarray
    label: np.ndarray
    first: np.ndarray
    shapes: list
    placed: list
    tolerance: np.ndarray
    surfaces_apart: np.ndarray
    body_shape: np.ndarray
    rotation: np.ndarray
    origin: np.ndarray
    closed: list

    def __len__(self) -> int:
        return len(self.first)

    def frame(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Pair ``k``'s frame (its first part's): rotation ``(3, 3)`` and origin ``(3,)``."""
        i = self.pairs[k, 0]
        return self.rotation[i], self.origin[i]

    def frames(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The frames of pairs ``rows``: rotations ``(m, 3, 3)`` and origins ``(m, 3)``."""
        first = self.pairs[np.asarray(rows, dtype=np.int64), 0]
        return self.rotation[first], self.origin[first]

    def members(self) -> list[np.ndarray]:
        """The rows of each class's pairs, class by class."""
        order = np.argsort(self.label, kind="stable")
        bounds = np.searchsorted(self.label[order], np.arange(len(self) + 1))
        return [order[bounds[c] : bounds[c + 1]] for c in range(len(self))]

    def arrays(self, placed: PlacedGeometry) -> tuple[np.ndarray, np.ndarray, bool]:
        """Vertices ``(n, 3)`` float64 (the pair's frame), faces ``(m, 3)`` int64 and
        closedness of a placed geometry."""
        shape = self.shapes[placed.shape]
        vertices = shape.local
        if not _is_identity(placed.linear):
            vertices = vertices @ placed.linear.T
        if np.any(placed.shift):
            vertices = vertices + placed.shift
        return np.ascontiguousarray(vertices), shape.faces, self.closed[placed.shape]


def pair_classes(
    bodies: Sequence,
    pairs: np.ndarray,
    tolerance: np.ndarray,
    surfaces_apart: np.ndarray | None = None,
    *,
    geometry: dict,
) -> PairClasses:
    """Group part ``pairs`` into classes that get one verdict (see the module docstring).

    Parameters
    ----------
    bodies : sequence of load.Body
    pairs : (k, 2) int64
        Indices into ``bodies``.
    tolerance : (k,) float64
        Each pair's touching tolerance, model units.
    surfaces_apart : (k,) bool, optional
        Pairs whose surfaces the convex pieces proved beyond reach (``verify_pair``'s argument),
        when known: pairs that differ in it are different classes. None: not known yet (the
        pipeline proves it per class, in the class's frame, ``pipeline.surfaces_near``).
    geometry : dict
        ``load.local_geometries`` of (at least) the bodies of ``pairs``.

    Returns
    -------
    PairClasses

    Examples
    --------
    >>> import trimesh
    >>> from meshcheck.load import Body, local_geometries
    >>> box = trimesh.creation.box()
    >>> moved = [np.eye(4) for _ in range(4)]
    >>> for k, x in enumerate([0.0, 0.5, 10.0, 10.5]):
    ...     moved[k][0, 3] = x
    >>> bodies = [Body(f"b{k}", "", box, moved[k]) for k in range(4)]
    >>> classes = pair_classes(bodies, np.array([[0, 1], [2, 3]]), np.full(2, 1e-5),
    ...                        np.zeros(2, bool), geometry=local_geometries(bodies))
    >>> len(classes), classes.label.tolist()
    (1, [0, 0])
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    tolerance = np.asarray(tolerance, dtype=np.float64).reshape(-1)
    if surfaces_apart is None:
        surfaces_apart = np.zeros(len(pairs), dtype=bool)
    surfaces_apart = np.asarray(surfaces_apart, dtype=bool).reshape(-1)
    frames = _Frames(bodies, geometry)
    grid = _grid(tolerance)
    forward = _placements(frames, pairs[:, 0], pairs[:, 1], grid)
    backward = _placements(frames, pairs[:, 1], pairs[:, 0], grid)
    shape = frames.shape
    same = shape[pairs[:, 0]] == shape[pairs[:, 1]]
    flip = shape[pairs[:, 0]] > shape[pairs[:, 1]]
    if same.any():  # one geometry twice: the placement whose bits come first
        flip[same] = _is_after(forward[same], backward[same])
    oriented = np.where(flip[:, None], pairs[:, ::-1], pairs)
    placement = np.where(flip[:, None], backward, forward)

    rows = np.empty((len(pairs), 2 + placement.shape[1] + 2), dtype=np.float64)
    rows[:, 0:2] = shape[oriented]
    rows[:, 2 : 2 + placement.shape[1]] = placement
    rows[:, -2] = tolerance
    rows[:, -1] = surfaces_apart
    label = np.empty(len(pairs), dtype=np.int64)
    seen: dict[bytes, int] = {}
    first: list[int] = []
    for k, row in enumerate(rows):
        key = row.tobytes()
        c = seen.get(key)
        if c is None:
            c = seen[key] = len(first)
            first.append(k)
        label[k] = c
    first_rows = np.array(first, dtype=np.int64)
    placed = [_placed_geometries(rows[k]) for k in first_rows]
    return PairClasses(
        pairs=oriented,
        label=label,
        first=first_rows,
        shapes=frames.shapes,
        placed=placed,
        tolerance=tolerance[first_rows],
        surfaces_apart=surfaces_apart[first_rows],
        body_shape=frames.shape,
        rotation=frames.rotation,
        origin=frames.origin,
        closed=frames.closed,
    )


def class_identity(classes: PairClasses, c: int) -> tuple:
    """What class ``c``'s verdict depends on besides the settings: its two placed geometries
    as ``(digest, (4, 4) placement)`` each, and its tolerance and surfaces-apart flag (the
    arguments of ``cache.pair_key``)."""
    a, b = classes.placed[c]

    def placed(p: PlacedGeometry):
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = p.linear, p.shift
        return classes.shapes[p.shape].digest, matrix

    return placed(a), placed(b), float(classes.tolerance[c]), bool(classes.surfaces_apart[c])


def placed_verdict(verdict: PairVerdict, rotation: np.ndarray, origin: np.ndarray) -> PairVerdict:
    """A verdict computed in a pair's frame, moved to world coordinates.

    Parameters
    ----------
    verdict : PairVerdict
        In the frame (``PairClasses``: its first part's rotation and origin).
    rotation : (3, 3) float64
        The frame's rotation (proper, orthonormal).
    origin : (3,) float64
        The frame's origin, world coordinates.

    Returns
    -------
    PairVerdict
        The same status, distance, depth and volume; the shared solid, the closest points and
        the location moved. The location's box is the box of the moved solid or closest points
        when the verdict has them, else the box around the moved corners of its box.
    """
    (out,) = placed_verdicts(verdict, rotation[None], origin[None])
    return out


def placed_verdicts(
    verdict: PairVerdict, rotation: np.ndarray, origin: np.ndarray
) -> list[PairVerdict]:
    """``placed_verdict`` for many frames at once: ``rotation`` ``(m, 3, 3)``, ``origin``
    ``(m, 3)``; one verdict per frame."""
    m = len(rotation)
    if verdict.location is None and verdict.solid is None and verdict.closest is None:
        return [verdict] * m
    rotation = np.asarray(rotation, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)

    def move(points: np.ndarray) -> np.ndarray:  # (p, 3) -> (m, p, 3)
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return points @ np.transpose(rotation, (0, 2, 1)) + origin[:, None, :]

    solids: list = [None] * m
    if verdict.solid is not None:
        moved = move(verdict.solid.vertices)
        solids = [Solid(v, verdict.solid.faces) for v in moved]
    closest = None
    if verdict.closest is not None:
        closest = move(np.stack(verdict.closest))  # (m, 2, 3)
    locations: list = [None] * m
    where = verdict.location
    if where is not None:
        centroid = move(where.centroid)[:, 0]
        if verdict.solid is not None and len(verdict.solid.vertices):
            lower = np.stack([s.vertices.min(axis=0) for s in solids])
            upper = np.stack([s.vertices.max(axis=0) for s in solids])
        elif closest is not None:
            p, q = closest[:, 0], closest[:, 1]
            centroid, lower, upper = 0.5 * (p + q), np.minimum(p, q), np.maximum(p, q)
        else:
            corners = move(_box_corners(where.lower, where.upper))
            lower, upper = corners.min(axis=1), corners.max(axis=1)
        locations = [Location(*xs) for xs in zip(centroid, lower, upper, strict=True)]
    return [
        PairVerdict(
            verdict.status,
            verdict.distance,
            depth=verdict.depth,
            volume=verdict.volume,
            location=locations[k],
            is_surface_only=verdict.is_surface_only,
            solid=solids[k],
            closest=None if closest is None else (closest[k, 0], closest[k, 1]),
        )
        for k in range(m)
    ]


def unplaced_verdict(verdict: PairVerdict, rotation: np.ndarray, origin: np.ndarray) -> PairVerdict:
    """A verdict in world coordinates taken into a pair's frame: ``placed_verdict``'s inverse
    (rotation transposed, origin first), for a verdict decided at a pair's world placement."""
    rotation = np.asarray(rotation, dtype=np.float64)
    inverse = rotation.T
    return placed_verdict(verdict, inverse, -(inverse @ np.asarray(origin, dtype=np.float64)))


def class_meshes(classes: PairClasses, c: int, meshes: dict) -> tuple:
    """Class ``c``'s two placed geometries as ``trimesh.Trimesh``, kept in ``meshes`` (by
    ``PlacedGeometry.key``) so classes that share one share the mesh and ``verify_pair``'s memo."""
    out = []
    for placed in classes.placed[c]:
        mesh = meshes.get(placed.key)
        if mesh is None:
            vertices, faces, closed = classes.arrays(placed)
            mesh = meshes[placed.key] = as_mesh(vertices, faces, closed=closed)
        out.append(mesh)
    return tuple(out)


def shared_key(classes: PairClasses, placed: PlacedGeometry) -> tuple:
    """Key of a placed geometry among a run's shared values: its content, so it means the same
    in every worker whichever run stage sent it."""
    digest = classes.shapes[placed.shape].digest
    tail = hashlib.sha256(placed.key[1]).hexdigest()[:32]
    return ("placed", digest, tail)


# ---------------------------------------------------------------------------------------------
# Frames and placements


class _Frames:
    """Each body's frame: the rotation and origin of its local geometry in world coordinates,
    what is left of its placement's linear map (``residual``), and its geometry's index."""

    def __init__(self, bodies: Sequence, geometry: dict):
        n = len(bodies)
        of_mesh: dict[int, int] = {}  # id(mesh) -> row of ``meshes``
        meshes = []
        mesh_row = np.empty(n, dtype=np.int64)
        for k, body in enumerate(bodies):
            row = of_mesh.get(id(body.mesh))
            if row is None:
                row = of_mesh[id(body.mesh)] = len(meshes)
                meshes.append(body.mesh)
            mesh_row[k] = row
        local = [geometry[id(m)] for m in meshes]
        digests = sorted({g.digest for g in local})
        index = {d: k for k, d in enumerate(digests)}
        self.shapes: list = [None] * len(digests)
        self.closed: list = [False] * len(digests)
        for mesh, g in zip(meshes, local, strict=True):
            s = index[g.digest]
            if self.shapes[s] is None:
                self.shapes[s] = g
                self.closed[s] = is_closed(mesh)
        self.shape = np.array([index[g.digest] for g in local], dtype=np.int64)[mesh_row]
        corner = np.array([g.corner for g in local], dtype=np.float64).reshape(-1, 3)[mesh_row]
        transform = np.array([b.transform for b in bodies], dtype=np.float64).reshape(-1, 4, 4)
        self.linear = np.ascontiguousarray(transform[:, :3, :3])
        self.origin = (self.linear @ corner[:, :, None])[:, :, 0] + transform[:, :3, 3]
        self.rotation, self.residual = _rotations(self.linear)
        # Vertices of a shape lie within ``size`` of its frame's origin: the grid of a linear
        # map's entries is the placement grid over it, so an entry's rounding moves no vertex by
        # more than the grid.
        self.size = np.array(
            [_power_of_two_above(float(np.linalg.norm(s.local.max(axis=0, initial=0.0))))
             for s in self.shapes]
        )  # fmt: skip


def _rotations(linear: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The proper rotation nearest each linear map (polar decomposition) and what is left of the
    map after it, two ``(n, 3, 3)`` arrays; a positive multiple of the identity (no placement,
    a unit's scale) gives the identity exactly."""
    n = len(linear)
    rotation = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    residual = linear.copy()
    diagonal = np.einsum("nii->ni", linear)
    is_scaled = np.all(linear == diagonal[:, :, None] * np.eye(3), axis=(1, 2)) & np.all(
        (diagonal == diagonal[:, :1]) & (diagonal > 0), axis=1
    )
    turned = np.flatnonzero(~is_scaled)
    if len(turned):
        u, _, vt = np.linalg.svd(linear[turned])
        flip = np.linalg.det(u @ vt) < 0  # a mirror stays in the residual
        u[flip, :, 2] *= -1.0
        rotation[turned] = u @ vt
        residual[turned] = np.transpose(rotation[turned], (0, 2, 1)) @ linear[turned]
    return rotation, residual


def _grid(tolerance: np.ndarray) -> np.ndarray:
    """The placement grid of each pair: the largest power of two at most ``SNAP_FRACTION`` of
    its tolerance; 0 (no rounding) for a tolerance of 0."""
    step = SNAP_FRACTION * np.asarray(tolerance, dtype=np.float64)
    _, exponent = np.frexp(step)
    return np.where(step > 0.0, np.ldexp(1.0, exponent - 1), 0.0)


def _snap(values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``values`` rounded to multiples of ``grid`` (broadcast; exact: powers of two), -0.0 as 0.0.

    Rounding the 9 entries of a linear map by at most half a step of ``grid / size`` moves a
    vertex within ``size`` of the origin by at most ``1.5 grid`` (Frobenius norm), and the shift
    by at most ``0.87 grid``: 2.4 grid steps in all.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        snapped = np.where(grid > 0.0, np.rint(values / grid) * grid, values)
    return snapped + 0.0


def _placements(frames: _Frames, a: np.ndarray, b: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Rounded placements of the pairs ``(a, b)`` in ``a``'s frame, ``(k, 21)``: ``a``'s
    residual linear map (9), ``b``'s linear map (9) and shift (3)."""
    rotation_t = np.transpose(frames.rotation[a], (0, 2, 1))
    linear_b = rotation_t @ frames.linear[b]
    shift_b = np.einsum("kij,kj->ki", rotation_t, frames.origin[b] - frames.origin[a])
    size_a = frames.size[frames.shape[a]]
    size_b = frames.size[frames.shape[b]]
    out = np.empty((len(a), 21))
    out[:, 0:9] = _snap(frames.residual[a].reshape(-1, 9), (grid / size_a)[:, None])
    out[:, 9:18] = _snap(linear_b.reshape(-1, 9), (grid / size_b)[:, None])
    out[:, 18:21] = _snap(shift_b, grid[:, None])
    return out


def _is_after(forward: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """Rows where ``backward``'s bits sort before ``forward``'s (so a pair of one geometry is
    oriented the same way whichever part comes first)."""
    out = np.zeros(len(forward), dtype=bool)
    for k, (f, b) in enumerate(zip(forward, backward, strict=True)):
        out[k] = b.tobytes() < f.tobytes()
    return out


def _placed_geometries(row: np.ndarray) -> tuple[PlacedGeometry, PlacedGeometry]:
    a = PlacedGeometry(int(row[0]), row[2:11].reshape(3, 3).copy(), np.zeros(3))
    b = PlacedGeometry(int(row[1]), row[11:20].reshape(3, 3).copy(), row[20:23].copy())
    return a, b


def _power_of_two_above(x: float) -> float:
    """The smallest power of two at least ``x`` (1 for 0)."""
    if x <= 0.0 or not np.isfinite(x):
        return 1.0
    mantissa, exponent = np.frexp(x)
    return float(np.ldexp(1.0, int(exponent) - (1 if mantissa == 0.5 else 0)))


def _is_identity(matrix: np.ndarray) -> bool:
    return bool(np.array_equal(matrix, np.eye(3)))


def _box_corners(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The 8 corners of a box, ``(8, 3)``."""
    pick = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=bool)
    return np.where(pick, np.asarray(upper, dtype=np.float64), np.asarray(lower, dtype=np.float64))


__all__ = [
    "SNAP_FRACTION",
    "PairClasses",
    "PlacedGeometry",
    "class_identity",
    "class_meshes",
    "pair_classes",
    "placed_verdict",
    "placed_verdicts",
    "shared_key",
    "unplaced_verdict",
]
