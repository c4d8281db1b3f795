"""Body -> convex pieces (CoACD); a convex body is its own single piece."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from .load import Body

DEFAULT_THRESHOLD = 0.1  # CoACD concavity threshold; the verify stage is exact, so coarse is fine


def is_convex(mesh: trimesh.Trimesh) -> bool:
    """True when a closed mesh fills its convex hull (volumes equal within 1e-6)."""
    if not mesh.is_watertight:
        return False
    hull = mesh.convex_hull
    return bool(abs(hull.volume - abs(mesh.volume)) <= 1e-6 * hull.volume)


def decompose_mesh(mesh: trimesh.Trimesh, *, threshold: float = DEFAULT_THRESHOLD) -> list[np.ndarray]:
    """Split a mesh into convex pieces, frame-local.

    Returns
    -------
    pieces : list of (n_i, 3) float64
        Vertices of each convex piece.
    """
    if is_convex(mesh):
        return [np.asarray(mesh.convex_hull.vertices, dtype=np.float64)]
    import coacd

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(mesh.vertices, mesh.faces), threshold=threshold)
    return [np.asarray(v, dtype=np.float64) for v, _ in parts]


def decompose_bodies(
    bodies: Sequence[Body],
    *,
    threshold: float = DEFAULT_THRESHOLD,
    cache_dir: str | None = None,
    jobs: int | None = None,
) -> list[list[np.ndarray]]:
    """Convex pieces of each body in world coordinates, one list per body."""
    out = []
    for body in bodies:
        pieces = decompose_mesh(body.mesh, threshold=threshold)
        out.append([trimesh.transform_points(p, body.transform) for p in pieces])
    return out
