"""The check, stage by stage: load -> hulls -> pieces -> GJK filter -> exact verdicts -> findings.

Each stage narrows the part pairs the next one looks at:

1. broad phase on the parts' boxes, grown by the reach (clearance + tolerance);
2. GJK on whole-part convex hulls: a part's mesh lies inside its hull, so pairs whose hulls stay
   beyond the reach are clear, and parts that meet nobody are never decomposed;
3. GJK on the convex pieces of the remaining parts; the pieces cover every triangle of their part,
   so pairs whose pieces stay beyond the reach have surfaces beyond the reach: they are clear
   unless one part is buried inside the other, which the verify stage decides with one point;
4. the verify stage decides the rest on the real meshes.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from . import verify
from .broadphase import candidate_pairs
from .config import Approval, Config, Groups, approval_reason, default_tolerance, load_config
from .decompose import DEFAULT_THRESHOLD, decompose_bodies, local_geometry
from .errors import MeshcheckWarning
from .geometry import Status, pack_convex, query_pairs
from .load import Body, load_bodies
from .progress import Progress
from .results import CheckResult, Finding, Part, finding_id


def check(
    paths: Sequence[str],
    *,
    clearance: float | None = None,
    tolerance: float | None = None,
    threshold: float | None = None,
    cache_dir: str | None = None,
    jobs: int | None = None,
    approvals: Sequence[Approval] = (),
    groups: Groups | None = None,
    export: str | None = None,
    split: bool = False,
    config: Config | str | os.PathLike | None = None,
) -> CheckResult:
    """Check the parts in ``paths`` for interference, contact and (optionally) clearance.

    Parameters
    ----------
    paths : sequence of str or path-like (or a single one)
        Mesh files and directories (every supported mesh file below them). Each body becomes a
        part named by its path, ``PATH#NODE`` inside multi-body files.
    clearance : float, optional
        Also report part pairs whose true distance is below this, model units.
    tolerance : float, optional
        Overlaps and gaps below this count as touching, model units. Default: 1e-5 of the
        assembly's bounding-box diagonal.
    threshold : float, optional
        CoACD concavity threshold; default ``decompose.DEFAULT_THRESHOLD``.
    cache_dir : str, optional
        Directory for cached decompositions; None disables the cache.
    jobs : int, optional
        Worker processes for decomposition; default all cores.
    approvals : sequence of Approval
        Findings on matching pairs are reported as approved and do not fail the run; added to
        the configuration's ``ignore`` rules.
    groups : Groups, optional
        Check only pairs across the two groups; replaces the configuration's ``groups``.
    export : str, optional
        Write the assembly with the clashes marked to this glTF binary (.glb) file.
    split : bool
        Make each disconnected shell of a body its own part (``NAME#1``, ``NAME#2``...).
    config : Config or path, optional
        Settings from a configuration file (``config.load_config``); an option passed here
        wins over the file. Not searched for: the command line does that (``find_config``).
        Its ``ignore`` rules by ``id`` approve the finding with that stable ID.

    Returns
    -------
    CheckResult
        Its ``warnings`` list the MeshcheckWarnings raised on the way, which are also re-issued.

    Raises
    ------
    InputError
        An input cannot be checked.
    ConfigError
        The configuration file is invalid.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    paths = [os.fspath(p) for p in paths]
    if config is not None and not isinstance(config, Config):
        config = load_config(config)
    if config is not None:
        clearance = config.clearance if clearance is None else clearance
        tolerance = config.tolerance if tolerance is None else tolerance
        threshold = config.threshold if threshold is None else threshold
        approvals = (*approvals, *config.ignore)
        approved_ids = dict(reversed(config.ignore_ids))  # the first rule for an ID wins
        groups = config.groups if groups is None else groups
    else:
        approved_ids = {}
    if threshold is None:
        threshold = DEFAULT_THRESHOLD

    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", MeshcheckWarning)
            with Progress("loading", 0) as bar:
                bodies = load_bodies(paths, split=split, progress=bar.update_total)
            result = check_bodies(
                bodies,
                clearance=clearance,
                tolerance=tolerance,
                threshold=threshold,
                cache_dir=cache_dir,
                jobs=jobs,
                approvals=approvals,
                approved_ids=approved_ids,
                groups=groups,
                export=export,
            )
    finally:
        # re-issue outside the recorder, so callers' filters (and the CLI) see them as usual
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    messages = [str(w.message) for w in caught if issubclass(w.category, MeshcheckWarning)]
    return dataclasses.replace(result, warnings=[*result.warnings, *messages])


def check_bodies(
    bodies: Sequence[Body],
    *,
    clearance: float | None = None,
    tolerance: float | None = None,
    threshold: float = DEFAULT_THRESHOLD,
    cache_dir: str | None = None,
    jobs: int | None = None,
    approvals: Sequence[Approval] = (),
    approved_ids: Mapping[str, str] | None = None,
    groups: Groups | None = None,
    export: str | None = None,
) -> CheckResult:
    """Run the check on bodies already loaded; see ``check``.

    ``approved_ids`` maps stable finding IDs to the reason they are approved; a pattern in
    ``approvals`` that matches the pair takes precedence.
    """
    n = len(bodies)
    hulls = pack_convex(_world_hulls(bodies), is_hull=True)
    if tolerance is None:
        tolerance = default_tolerance(hulls.lower.min(axis=0), hulls.upper.max(axis=0))
    reach = tolerance + (clearance or 0.0)

    # Whole-part hulls: a mesh lies inside its hull, so a pair of hulls beyond reach is clear.
    pairs = candidate_pairs(hulls.lower, hulls.upper, margin=reach)
    if groups is not None:
        pairs = pairs[groups.pair_mask([b.name for b in bodies], pairs)]
    hull_query = query_pairs(hulls, pairs, tolerance=tolerance, depth=False, max_distance=reach)
    near = pairs[_within(hull_query, reach)]

    # Convex pieces, only for parts whose hull comes within reach of another part.
    needed = np.unique(near)
    with Progress("decomposing", len({id(bodies[i].mesh) for i in needed})) as bar:
        piece_lists = decompose_bodies(
            [bodies[i] for i in needed],
            threshold=threshold,
            cache_dir=cache_dir,
            jobs=jobs,
            progress=bar.update,
        )
    piece_count = np.zeros(n, dtype=np.int64)
    piece_count[needed] = [len(p) for p in piece_lists]
    owner = np.repeat(needed, piece_count[needed]).astype(np.int64)
    # Pieces may carry extra interior points (triangle cover); a support scan over a superset of
    # the hull's vertices is still exact, so Qhull need not run again.
    pieces = pack_convex([p for plist in piece_lists for p in plist], is_hull=True)

    # Piece pairs of two different parts whose hulls are near; a part pair with a piece pair within
    # reach (or undecided) may have surfaces within reach.
    piece_pairs = candidate_pairs(pieces.lower, pieces.upper, margin=reach, owner=owner)
    owners = np.sort(owner[piece_pairs], axis=1)
    keys = owners[:, 0] * n + owners[:, 1]
    near_keys = near[:, 0] * n + near[:, 1]
    piece_pairs, keys = piece_pairs[np.isin(keys, near_keys)], keys[np.isin(keys, near_keys)]
    piece_query = query_pairs(
        pieces, piece_pairs, tolerance=tolerance, depth=False, max_distance=reach
    )
    hit = _within(piece_query, reach)
    surfaces_near = set(np.unique(keys[hit]).tolist())

    findings = []
    memo: dict = {}  # per-mesh data verify reuses across pairs; the bodies outlive the loop
    bar = Progress("checking", len(near))
    for count, (i, j) in enumerate(near, start=1):
        bar.update(count)
        a, b = bodies[i], bodies[j]
        verdict = verify.verify_pair(
            a.world,
            b.world,
            tolerance=tolerance,
            clearance=clearance,
            surfaces_apart=int(i * n + j) not in surfaces_near,
            memo=memo,
        )
        if verdict.status == verify.CLEAR:
            continue
        (name_a, digest_a), (name_b, digest_b) = sorted([(a.name, a.digest), (b.name, b.digest)])
        fid = finding_id(name_a, digest_a, name_b, digest_b)
        findings.append(
            Finding(
                a=name_a,
                b=name_b,
                status=verdict.status,
                distance=verdict.distance,
                depth=verdict.depth,
                volume=verdict.volume,
                location=verdict.location,
                id=fid,
                is_surface_only=verdict.is_surface_only,
                approved=approval_reason(approvals, name_a, name_b)
                or (approved_ids or {}).get(fid),
            )
        )
    bar.close()
    findings.sort(key=lambda f: (f.a, f.b))
    parts = [
        Part(b.name, b.path, len(b.mesh.faces), b.is_closed, int(piece_count[k]))
        for k, b in enumerate(bodies)
    ]
    if export is not None:
        from .export import export_clashes

        export_clashes(export, bodies, findings)
    return CheckResult(
        findings=findings,
        parts=parts,
        tolerance=tolerance,
        clearance=clearance,
        pairs_checked=len(pairs),
        checked_pairs=[(bodies[i].name, bodies[j].name) for i, j in pairs],
    )


def _world_hulls(bodies: Sequence[Body]) -> list[np.ndarray]:
    """Hull vertices of each body, world coordinates; qhull runs once per distinct geometry.

    Geometry is compared up to translation (``decompose.local_geometry``), so instances of one
    mesh and copies of one part at other places share a hull.
    """
    from scipy.spatial import ConvexHull, QhullError

    by_mesh: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # id(mesh) -> (local hull, corner)
    by_digest: dict[str, np.ndarray] = {}
    out = []
    for body in bodies:
        if id(body.mesh) not in by_mesh:
            local, _, corner, digest = local_geometry(body.mesh)
            if digest not in by_digest:
                try:
                    by_digest[digest] = local[np.sort(ConvexHull(local).vertices)]
                except (QhullError, ValueError):  # flat or degenerate: every vertex
                    by_digest[digest] = local
            by_mesh[id(body.mesh)] = (by_digest[digest], corner)
        hull, corner = by_mesh[id(body.mesh)]
        hull = hull + corner
        transform = np.asarray(body.transform, dtype=np.float64)
        if not np.array_equal(transform, np.eye(4)):
            hull = hull @ transform[:3, :3].T + transform[:3, 3]
        out.append(hull)
    return out


def _within(result, reach: float) -> np.ndarray:
    """Mask of pairs that may come within ``reach``: not proven separated beyond it."""
    return (result.status != Status.SEPARATED) | (result.distance <= reach)
