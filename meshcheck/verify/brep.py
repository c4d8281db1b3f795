"""STEP part pairs -> verdicts decided on the exact solids (OpenCASCADE's B-rep), once each.

Why
---
A STEP part is tessellated, and its triangles lie up to the deflection from its curved faces: a
bolt coincident with its hole (line to line: the CAD common volume is 0) shows overlapping chords
a fraction of the tolerance thick, a 0.005 mm press fit hides inside a 0.01 mm tolerance, and a
clearance, a depth or a volume measured on the triangles is off by up to a deflection. The solids
the triangles came from answer all of these exactly, so a pair of STEP solids is decided on them,
and only on them:

- **The meshes filter.** A pair reaches this stage when its convex hulls come within reach. Its
  triangles are then within the two deflections of the solids, so when the exact triangle
  distance exceeds the solids' reach (``tolerance + clearance``) plus both deflections, and
  neither mesh holds a shell of the other, the solids are farther apart than the reach: the
  pair is clear (``pair.may_come_within``; milliseconds). Every other pair goes to the B-rep,
  without being decided on the meshes first.
- **The B-rep decides** (``decide``), with the pair's own tolerance ``t``: the user's
  ``--tolerance``, or ``TOLERANCE_FRACTION`` of the smaller solid's own box diagonal (in its own
  frame, so every instance of a pair gets the same; the deflections do not enter, the solids are
  exact). ``BRepExtrema_DistShapeShape`` gives the distance ``d`` (0 when the solids overlap or
  one holds the other):

  * ``d > t``: **clearance** (``d``, the two closest points) up to the clearance, else clear;
  * otherwise ``BRepAlgoAPI_Common`` gives the shared solid and ``GProp`` its volume ``V``. A ball
    of diameter above ``t`` has volume above ``pi/6 t**3``: ``V`` at most that proves the shared
    volume thinner than ``t``, **touching** (located at the closest points' box). Otherwise a
    ball is exhibited inside the shared solid (``_largest_ball``: a ray from a point of its
    surface into it, the midpoint classified inside, its radius the exact distance to the
    surface); a diameter above ``t`` is **interference** with that depth, volume ``V``, and the
    shared solid's centroid and box as its location. Otherwise, when every connected piece of
    the shared solid is provably thinner than ``t`` (its volume's ball, its box), **touching**;
    short of a proof, **interference** (the rule for meshes, kept).

Once each
---------
A pair is decided in its first solid's frame: the first product as written, the second moved by
their relative placement. Its key (``pair_key``) is the two products' content (the file's digest
and the product), that relative placement bit for bit, the tolerance, the clearance, this file
and OpenCASCADE's version; pairs of one run with one key are decided once (a bolt in each of
forty identical nuts), and the verdict is kept in the run's pair cache, so a warm run reads no
STEP document. Each verdict is moved to its pair's placement (``to_world``). ``decide_pair`` is
the whole decision for one key: a caller grouping pairs by class decides a representative with
it.

The solids are decided in the run's worker processes when that pays (``batch.pays_in_workers``),
one pair per task. OpenCASCADE shapes are not pickled: each product travels once per worker as
BRep text (``StepSolids.product_text``, a few milliseconds to read, where reading the STEP file
again costs a fraction of a second), and the solids are never modified (non-destructive
booleans), so a verdict does not depend on the pairs decided before it in the same process.

A pair that cannot be decided on the B-rep (OpenCASCADE's boolean or distance fails, a part was
``--split`` into shells or rescaled by ``--units FILE=UNIT``) is verified on its meshes; when
that verdict is touching, a ``MeshcheckWarning`` names the finding and the tolerance that decided
it (``warn_unconfirmed``).
"""

from __future__ import annotations

import dataclasses
import functools
import io
import json
import math
import os
import warnings
from collections.abc import Sequence

import numpy as np

from ..cache import PairCache
from ..cache.store import checksum, package_version
from ..errors import InputError, MeshcheckWarning
from ..execute import Executor, Task
from ..load import Body
from ..load.files import STEP_EXTENSIONS
from ..progress import Progress
from ..results import Finding, Location, PairVerdict, Solid, Verdict, finding_id
from ..settings import Settings
from ..tolerances import default_tolerance
from ..units import METRES

#: Points of the shared solid's surface a ball is grown from, the largest facets first.
BALL_SEEDS = 24
#: Bump when a cached B-rep verdict's meaning changes.
FORMAT_VERSION = 2
#: Expected seconds of one pair on the B-rep (a distance and, for pairs that meet, a boolean):
#: ``python bench/step.py`` (the scripted OpenCASCADE peer's seconds per pair, same run).
PAIR_SECONDS = 0.15
#: The shared solid of an interference is drawn (reports, export) from a tessellation this
#: fraction of its box diagonal from its faces.
SOLID_DEFLECTION = 2e-3


def is_on_brep(body: Body) -> bool:
    """Whether ``body`` is one solid of a STEP file, as the file has it (not rescaled by
    ``--units FILE=UNIT``, not split into shells): its pairs are decided on the B-rep."""
    if not _is_step(body) or body.brep is None:
        return False
    node = _node(body)
    return node is not None and body.brep.has_node(node)


def _is_step(body: Body) -> bool:
    """A part of a STEP file in the file's own unit (not rescaled by ``--units FILE=UNIT``)."""
    is_step = os.path.splitext(body.path)[1].lower() in STEP_EXTENSIONS
    return is_step and body.deflection > 0 and not body.is_rescaled


def reach_margin(bodies: Sequence[Body], pairs: np.ndarray) -> np.ndarray:
    """What the broad phase and the convex filters must add to a pair's reach (``(k,)`` float64,
    model units) so that no pair the B-rep would find within its own reach is pruned: the two
    deflections (the triangles' distance from the solids) and the solids' own tolerance; 0 for
    pairs not decided on the B-rep."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    on = np.array([is_on_brep(b) for b in bodies], dtype=bool)
    own = np.array([_own_size_tolerance(b) if on[k] else 0.0 for k, b in enumerate(bodies)])
    deflection = np.array([b.deflection for b in bodies], dtype=np.float64)
    if not len(pairs):
        return np.zeros(0)
    i, j = pairs[:, 0], pairs[:, 1]
    both = on[i] & on[j]
    return np.where(both, deflection[i] + deflection[j] + np.maximum(own[i], own[j]), 0.0)


def largest_reach_margin(bodies: Sequence[Body]) -> float:
    """An upper bound of ``reach_margin`` over every pair of ``bodies``, model units."""
    on = [b for b in bodies if is_on_brep(b)]
    if len(on) < 2:
        return 0.0
    return 2.0 * max(b.deflection for b in on) + max(_own_size_tolerance(b) for b in on)


def decide_on_brep(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    near_surfaces: np.ndarray,
    settings: Settings,
    *,
    executor: Executor | None = None,
    cache: PairCache | None = None,
) -> tuple[list[Finding], np.ndarray, dict[tuple[str, str], str]]:
    """Decide the pairs of STEP solids among ``pairs`` on their B-rep (see the module docstring).

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts.
    pairs : (k, 2) int64
        The pairs whose convex hulls come within reach.
    near_surfaces : (k,) bool
        Whether each pair's convex pieces come within reach (``pipeline.surfaces_near``).
    settings : Settings
        The run's settings (``tolerance``, ``clearance``).
    executor : execute.Executor, optional
        The run's executor; pairs are decided in its workers when that pays.
    cache : cache.PairCache, optional
        The run's pair verdicts, where B-rep verdicts are kept too.

    Returns
    -------
    findings : list of Finding
        One per pair decided on the B-rep that is not clear, sorted by part names.
    on_meshes : (k,) bool
        The pairs left to the meshes: not two STEP solids, or not decided on their B-rep.
    reasons : dict
        Why a pair of two STEP parts left to the meshes was not decided on the B-rep, by the
        pair's part names (``warn_unconfirmed``).
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    on = np.array([is_on_brep(b) for b in bodies], dtype=bool)
    chosen = np.flatnonzero(on[pairs[:, 0]] & on[pairs[:, 1]]) if len(pairs) else np.zeros(0, int)
    jobs = _screened(bodies, pairs[chosen], near_surfaces[chosen], settings)
    verdicts: dict[str, PairVerdict | str] = {}
    todo: dict[str, _PairJob] = {}
    for job in jobs:
        if job is None or job.key in verdicts or job.key in todo:
            continue
        hit = cache.get(job.key) if cache is not None else None
        if hit is not None:
            verdicts[job.key] = hit
        else:
            todo[job.key] = job
    fresh = _decide_all(bodies, list(todo.values()), executor)
    for key, verdict in fresh.items():
        verdicts[key] = verdict
        if cache is not None and isinstance(verdict, PairVerdict):
            cache.put(key, verdict)
    findings, on_meshes = [], np.ones(len(pairs), dtype=bool)
    reasons = {}
    for i, j in pairs:  # two STEP parts, one of them split into shells
        if _is_step(bodies[i]) and _is_step(bodies[j]) and not (on[i] and on[j]):
            reasons[bodies[i].name, bodies[j].name] = _NOT_ONE_SOLID
    for k, job in zip(chosen, jobs, strict=True):
        verdict = None if job is None else verdicts[job.key]  # None: the meshes proved it clear
        if isinstance(verdict, str):
            reasons[bodies[job.first].name, bodies[job.second].name] = verdict
            continue
        on_meshes[k] = False
        if verdict is not None and verdict.status != Verdict.CLEAR:
            findings.append(_finding(bodies, job, verdict))
    findings.sort(key=lambda f: (f.a, f.b))
    return findings, on_meshes, reasons


_NOT_ONE_SOLID = "the part is not one closed solid of its file"


def warn_unconfirmed(findings: Sequence[Finding], reasons: dict[tuple[str, str], str]) -> None:
    """Warn about each touching finding of two STEP solids the meshes decided (``reasons``:
    why the B-rep did not, by part names): an interference thinner than the tessellation's
    tolerance would not be reported."""
    for finding in findings:
        reason = reasons.get((finding.a, finding.b)) or reasons.get((finding.b, finding.a))
        if reason and finding.status == Verdict.TOUCHING:
            warnings.warn(
                MeshcheckWarning(
                    f"{finding.a} and {finding.b}: touching on the tessellation (tolerance "
                    f"{finding.tolerance:.3g}, the deflections' sum) but not confirmed on the "
                    f"B-rep: {reason}; an interference thinner than that tolerance would not be "
                    "reported"
                ),
                stacklevel=2,
            )


class _Unconfirmed(Exception):
    """The pair cannot be decided on the B-rep; the message says why."""


# ---------------------------------------------------------------------------------------------
# One pair: what decides it, its key, its verdict in the world


@dataclasses.dataclass(frozen=True)
class _PairJob:
    """One pair of STEP solids, oriented by content (``first`` is the solid it is decided in).

    ``products`` name each solid's product text in a task's store; ``relative`` is the second
    solid's placement in the first one's frame (mm); ``tolerance`` and ``clearance`` are in mm,
    ``tolerance_report`` in the report unit; ``may_overlap`` is False when the meshes prove the
    solids apart (``decide_pair``).
    """

    first: int
    second: int
    key: str
    products: tuple[tuple[str, str, int], tuple[str, str, int]]
    relative: np.ndarray
    tolerance: float
    clearance: float | None
    tolerance_report: float
    may_overlap: bool = True


def _pair_job(bodies: Sequence[Body], pair: np.ndarray, settings: Settings) -> _PairJob:
    i, j = (int(k) for k in pair)
    if _content(bodies[j]) < _content(bodies[i]):
        i, j = j, i
    a, b = bodies[i], bodies[j]
    report_to_mm = METRES[a.units] / 1e-3
    if settings.tolerance is not None:
        tolerance_report = float(settings.tolerance)
    else:
        tolerance_report = min(_own_size_tolerance(a), _own_size_tolerance(b))
    tolerance = tolerance_report * report_to_mm
    clearance = None if settings.clearance is None else float(settings.clearance) * report_to_mm
    relative = relative_placement(a.brep.placement_mm(_node(a)), b.brep.placement_mm(_node(b)))
    products = (_product_id(a), _product_id(b))
    return _PairJob(i, j, "", products, relative, tolerance, clearance, tolerance_report)


def _content(body: Body) -> tuple:
    """What orders a pair's two solids: their products' content, then their placements."""
    node = _node(body)
    matrix = np.ascontiguousarray(body.brep.placement_mm(node), dtype=np.float64).tobytes()
    return body.brep.digest, body.brep.product(node), matrix, body.name


def _product_id(body: Body) -> tuple[str, str, int]:
    """The key of a solid's product text in a task's store: its file's digest and product."""
    return ("brep", body.brep.digest, body.brep.product(_node(body)))


def relative_placement(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(4, 4) float64: ``second``'s placement in ``first``'s frame (both rigid, (4, 4))."""
    rotation, shift = first[:3, :3], first[:3, 3]
    out = np.eye(4)
    out[:3, :3] = rotation.T @ second[:3, :3]
    out[:3, 3] = rotation.T @ (second[:3, 3] - shift)
    return out


def pair_key(
    products: tuple[tuple, tuple],
    relative: np.ndarray,
    *,
    tolerance: float,
    clearance: float | None,
    may_overlap: bool = True,
) -> str:
    """Key of a B-rep verdict: hex SHA-256 of everything it depends on.

    Parameters
    ----------
    products : ((str, str, int), (str, str, int))
        Each solid's product: ``("brep", file digest, product number)``.
    relative : (4, 4) float64
        The second solid's placement in the first one's frame, mm (bit for bit).
    tolerance, clearance : float
        mm (bit for bit); clearance may be None.
    may_overlap : bool
        False when the solids are known apart (``decide_pair``).
    """
    payload = {
        "brep": FORMAT_VERSION,
        "code": _code_version(),
        "products": [list(p) for p in products],
        "relative": np.ascontiguousarray(relative, dtype=np.float64).tobytes().hex(),
        "tolerance": float(tolerance).hex(),
        "clearance": None if clearance is None else float(clearance).hex(),
        "may_overlap": bool(may_overlap),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return checksum(text.encode()).hex()


@functools.cache
def _code_version() -> str:
    """Digest of what computes a B-rep verdict: this file and OpenCASCADE's version."""
    with open(__file__, "rb") as f:
        source = f.read()
    return checksum(source, package_version("cadquery-ocp-novtk", missing="?").encode()).hex()


def _own_size_tolerance(body: Body) -> float:
    """The default tolerance of a solid alone, report units: ``TOLERANCE_FRACTION`` of its own
    box diagonal, in its own frame (every instance of it gets the same)."""
    bounds = np.asarray(body.mesh.bounds, dtype=np.float64)
    scale = float(np.abs(np.linalg.det(np.asarray(body.transform)[:3, :3]))) ** (1.0 / 3.0)
    return float(default_tolerance(np.linalg.norm(bounds[1] - bounds[0]) * scale, 0.0))


def _node(body: Body) -> str | None:
    """The solid's node name in its STEP file (``PATH#NODE``), None for another part."""
    prefix = f"{body.path}#"
    return body.name[len(prefix) :] if body.name.startswith(prefix) else None


def _finding(bodies: Sequence[Body], job: _PairJob, verdict: PairVerdict) -> Finding:
    """The finding of a pair the B-rep found not clear, in the world and the report unit, its
    parts (and the verdict's) in name order."""
    a, b = bodies[job.first], bodies[job.second]
    verdict = to_world(verdict, a)
    if (a.name, a.digest) > (b.name, b.digest):
        a, b, verdict = b, a, verdict.swapped()
    pair_id = finding_id(
        a.name, a.digest, b.name, b.digest, placement_a=a.transform, placement_b=b.transform
    )
    return Finding(a.name, b.name, verdict, id=pair_id, tolerance=job.tolerance_report)


def to_world(verdict: PairVerdict, first: Body) -> PairVerdict:
    """A verdict decided in ``first``'s product frame (mm) placed where ``first`` is, in the
    report unit: lengths scaled, points and the shared solid moved by its transform."""
    mm_to_file = 1e-3 / METRES[first.brep.unit]
    mm_to_report = 1e-3 / METRES[first.units]
    transform = np.asarray(first.transform, dtype=np.float64)

    def moved(points: np.ndarray) -> np.ndarray:
        local = np.asarray(points, dtype=np.float64) * mm_to_file
        return local @ transform[:3, :3].T + transform[:3, 3]

    location = verdict.location
    if location is not None:
        lower, upper = np.asarray(location.lower), np.asarray(location.upper)
        corners = np.array([[(lower, upper)[(k >> d) & 1][d] for d in range(3)] for k in range(8)])
        world = moved(corners)
        location = Location(moved(location.centroid[None])[0], world.min(axis=0), world.max(axis=0))
    solid = verdict.solid
    if solid is not None:
        solid = Solid(moved(solid.vertices), solid.faces)
    closest = verdict.closest
    if closest is not None:
        closest = (moved(closest[0][None])[0], moved(closest[1][None])[0])
    return dataclasses.replace(
        verdict,
        distance=verdict.distance * mm_to_report,
        depth=None if verdict.depth is None else verdict.depth * mm_to_report,
        volume=None if verdict.volume is None else verdict.volume * mm_to_report**3,
        location=location,
        solid=solid,
        closest=closest,
    )


# ---------------------------------------------------------------------------------------------
# Many pairs: the meshes' filter, then the B-rep here or in workers


def _screened(bodies, pairs, near_surfaces, settings) -> list[_PairJob | None]:
    """Each pair's job, or None when its meshes stay farther apart than the solids' reach plus
    the two deflections (``pair.surface_distance``): then the solids are clear. A job's
    ``may_overlap`` says whether the meshes come within the two deflections (or one holds the
    other); otherwise the solids are apart, and no boolean is needed."""
    from .pair import surface_distance

    memo: dict = {}
    out: list[_PairJob | None] = []
    for pair, is_near in zip(pairs, near_surfaces, strict=True):
        job = _pair_job(bodies, pair, settings)
        a, b = bodies[job.first], bodies[job.second]
        deflections = a.deflection + b.deflection
        reach = job.tolerance_report + deflections
        reach += float(job.clearance or 0.0) * 1e-3 / METRES[a.units]
        distance = surface_distance(
            a.world, b.world, reach=reach, surfaces_apart=not bool(is_near), memo=memo
        )
        if distance > reach:
            out.append(None)
            continue
        may_overlap = distance <= deflections
        key = pair_key(
            job.products,
            job.relative,
            tolerance=job.tolerance,
            clearance=job.clearance,
            may_overlap=may_overlap,
        )
        out.append(dataclasses.replace(job, key=key, may_overlap=may_overlap))
    return out


def _decide_all(bodies, jobs: list[_PairJob], executor) -> dict[str, PairVerdict | str]:
    """Verdicts (or why not) of ``jobs`` by key: here, or in ``executor``'s workers when their
    expected seconds repay them."""
    from .batch import pays_in_workers

    if not jobs:
        return {}
    shared: dict = {}
    try:
        for job in jobs:
            for body, product in zip(
                (bodies[job.first], bodies[job.second]), job.products, strict=True
            ):
                if product not in shared:
                    shared[product] = body.brep.product_text(_node(body))
    except InputError as exc:  # the file is gone or changed since load (a cache miss)
        return dict.fromkeys((j.key for j in jobs), f"its file cannot be read again ({exc.reason})")
    tasks = [
        Task(
            (
                (
                    job.products[0],
                    job.products[1],
                    job.relative,
                    job.tolerance,
                    job.clearance,
                    job.may_overlap,
                ),
            ),
            needs=job.products,
            size=len(jobs) - n,
        )
        for n, job in enumerate(jobs)
    ]
    cost = np.full(len(jobs), PAIR_SECONDS)
    runner = executor if pays_in_workers(executor, cost) else Executor()
    with Progress("checking on the B-rep", len(tasks)) as bar:
        results = runner.map(
            "meshcheck.verify.brep:brep_task",
            tasks,
            shared=shared,
            progress=bar.update,
            here=True,
        )
    out = {}
    for job, task, result in zip(jobs, tasks, results, strict=True):
        if result is None:  # its worker died: decide here (a bug then shows its traceback)
            result = Executor().map("meshcheck.verify.brep:brep_task", [task], shared=shared)[0]
        out[job.key] = result
    return out


def brep_task(store: dict, item: tuple) -> PairVerdict | str:
    """Decide one pair in a worker: ``item`` is ``(product_a, product_b, relative, tolerance,
    clearance, may_overlap)``, the products naming BRep texts in ``store`` (read once per
    process); the verdict is in the first product's frame, mm, or a string saying why there is
    none."""
    product_a, product_b, relative, tolerance, clearance, may_overlap = item
    try:
        return decide_pair(
            _shape(store, product_a),
            _shape(store, product_b),
            relative,
            tolerance=tolerance,
            clearance=clearance,
            may_overlap=may_overlap,
        )
    except _Unconfirmed as exc:
        return str(exc)


def _shape(store: dict, product) -> object:
    """The product's solid from its BRep text in ``store``, read once per process."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    memo = store.setdefault(("brep", "shapes"), {})
    if product not in memo:
        shape = TopoDS_Shape()
        BRepTools.Read_s(shape, io.BytesIO(store[product]), BRep_Builder())
        memo[product] = shape
    return memo[product]


def decide_pair(
    product_a,
    product_b,
    relative: np.ndarray,
    *,
    tolerance: float,
    clearance: float | None,
    may_overlap: bool = True,
) -> PairVerdict:
    """The verdict of one pair of solids, decided in the first one's frame.

    Parameters
    ----------
    product_a, product_b : OCP.TopoDS.TopoDS_Shape
        The two products, each in its own frame, mm.
    relative : (4, 4) float64
        ``product_b``'s placement in ``product_a``'s frame (``relative_placement``), mm.
    tolerance : float
        mm.
    clearance : float, optional
        mm.
    may_overlap : bool
        False when the solids are known to be apart (the meshes stay farther apart than their
        deflections): the distance alone decides, no boolean is made.

    Returns
    -------
    PairVerdict
        In ``product_a``'s frame, mm (``to_world`` places it).

    Raises
    ------
    _Unconfirmed
        The solids are not closed, the placement is not rigid, or OpenCASCADE failed.
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.Standard import Standard_Failure

    for product in (product_a, product_b):
        if not is_closed_solid(product):
            raise _Unconfirmed(_NOT_ONE_SOLID)
    try:
        moved = BRepBuilderAPI_Copy(product_b, True, False).Shape().Moved(_location(relative))
        verdict = decide(
            product_a, moved, tolerance=tolerance, clearance=clearance, may_overlap=may_overlap
        )
    except Standard_Failure as exc:
        raise _Unconfirmed(f"OpenCASCADE failed ({type(exc).__name__})") from None
    return _to_fields(verdict)


def _location(matrix: np.ndarray):
    """A TopLoc_Location of a rigid (4, 4) transform."""
    from OCP.gp import gp_Trsf
    from OCP.TopLoc import TopLoc_Location

    m = np.asarray(matrix, dtype=np.float64)
    if not np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9):
        raise _Unconfirmed("its placement is not a rigid motion")
    trsf = gp_Trsf()
    trsf.SetValues(*(float(x) for x in m[:3].ravel()))
    return TopLoc_Location(trsf)


# ---------------------------------------------------------------------------------------------
# The solids (millimetres): OpenCASCADE only, no I/O


@dataclasses.dataclass(frozen=True)
class BrepVerdict:
    """What the exact solids say about a pair; lengths in their unit.

    Attributes
    ----------
    status : Verdict
    distance : float
        Distance between the solids (0 when they share volume).
    depth : float or None
        Diameter of a ball exhibited inside the shared solid (interference only).
    volume : float
        Volume of the shared solid.
    centroid, lower, upper : (3,) float64 or None
        Interference: the shared solid's centre of mass and box. Touching and clearance: the box
        of the closest points and its centre.
    closest : ((3,) float64, (3,) float64) or None
        Clearance: the two closest points, on the first solid and on the second.
    solid : (vertices (n, 3) float64, faces (m, 3) int64) or None
        Interference: a tessellation of the shared solid (``SOLID_DEFLECTION``), to draw.
    """

    status: Verdict
    distance: float
    depth: float | None
    volume: float
    centroid: np.ndarray | None = None
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    closest: tuple[np.ndarray, np.ndarray] | None = None
    solid: tuple[np.ndarray, np.ndarray] | None = None


def decide(
    shape_a,
    shape_b,
    *,
    tolerance: float,
    clearance: float | None = None,
    may_overlap: bool = True,
) -> BrepVerdict:
    """The verdict of two exact solids (see the module docstring), lengths in their unit.

    Parameters
    ----------
    shape_a, shape_b : OCP.TopoDS.TopoDS_Shape
        Closed solids, placed, in one frame; neither is modified.
    tolerance : float
        Overlaps thinner and gaps narrower than this are touching.
    clearance : float, optional
        Gaps up to this are ``clearance``; farther is ``clear``.
    may_overlap : bool
        True: the boolean comes first, and when the shared solid has volume the distance is 0
        without ``BRepExtrema``. False (the caller knows the solids apart): the distance comes
        first, and the boolean only when it is within ``tolerance``. The verdict is the same
        either way; a touching pair is located at the shared sliver's box in the first case.

    Returns
    -------
    BrepVerdict

    Raises
    ------
    _Unconfirmed
        OpenCASCADE's boolean or distance failed.

    Examples
    --------
    >>> from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    >>> from OCP.gp import gp_Pnt
    >>> a = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(1, 1, 1)).Shape()
    >>> b = BRepPrimAPI_MakeBox(gp_Pnt(0.7, 0, 0), gp_Pnt(2, 1, 1)).Shape()
    >>> v = decide(a, b, tolerance=1e-3)
    >>> str(v.status), round(v.volume, 9), round(v.depth, 6)
    ('interference', 0.3, 0.3)
    >>> str(decide(a, b.Moved(_shift(0.3)), tolerance=1e-3).status)
    'touching'
    >>> v = decide(a, b.Moved(_shift(0.5)), tolerance=1e-3, clearance=0.5, may_overlap=False)
    >>> str(v.status), round(v.distance, 9)
    ('clearance', 0.2)
    """
    shared, section, volume, points = None, None, 0.0, None
    if may_overlap:
        shared, section = _intersection(shape_a, shape_b)
        volume = max(_volume(shared), 0.0)
    if section is not None and _meets_within(section, tolerance):
        distance = 0.0  # the boundaries meet (within their own tolerances, at most ``tolerance``)
    else:
        distance, points = _distance(shape_a, shape_b)
    if distance > tolerance:
        if clearance is not None and distance <= clearance:
            centre, lower, upper = _box_of(points)
            return BrepVerdict(
                Verdict.CLEARANCE, distance, None, 0.0, centre, lower, upper, closest=points[0]
            )
        return BrepVerdict(Verdict.CLEAR, distance, None, 0.0)
    if shared is None:
        shared, section = _intersection(shape_a, shape_b)
        volume = max(_volume(shared), 0.0)
    if volume > math.pi / 6.0 * tolerance**3:
        depth, ball_bound = _largest_ball(shared), _thickness_bound(shared)
        if depth > tolerance or ball_bound > tolerance:
            centroid, lower, upper = _placement_of(shared)
            return BrepVerdict(
                Verdict.INTERFERENCE,
                0.0,
                depth,
                volume,
                centroid,
                lower,
                upper,
                solid=_tessellation(shared),
            )
    if points is None:
        _, lower, upper = _placement_of(section)
        centre = 0.5 * (lower + upper)
    else:
        centre, lower, upper = _box_of(points)
    return BrepVerdict(Verdict.TOUCHING, distance, None, volume, centre, lower, upper)


def _shift(dx: float):
    """A TopLoc_Location moving by ``dx`` along x (for the examples)."""
    return _location(np.array([[1, 0, 0, dx], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))


def _to_fields(v: BrepVerdict) -> PairVerdict:
    """A verdict as every stage after verify reads one (``results.PairVerdict``)."""
    interferes = v.status == Verdict.INTERFERENCE
    location = None if v.centroid is None else Location(v.centroid, v.lower, v.upper)
    solid = None if v.solid is None or not len(v.solid[1]) else Solid(*v.solid)
    return PairVerdict(
        v.status,
        0.0 if interferes else v.distance,
        depth=v.depth if interferes else None,
        volume=v.volume if interferes else None,
        location=location,
        solid=solid,
        closest=v.closest if v.status == Verdict.CLEARANCE else None,
    )


def is_closed_solid(shape) -> bool:
    """Whether ``shape`` holds solids, each bounded by closed shells (OpenCASCADE's check of
    the topology: every edge of a shell shared by two of its faces)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer

    solids = _solids(shape)
    for solid in solids:
        explorer, shells = TopExp_Explorer(solid, TopAbs_SHELL), 0
        while explorer.More():
            if not BRep_Tool.IsClosed_s(explorer.Current()):
                return False
            shells += 1
            explorer.Next()
        if not shells:
            return False
    return bool(solids)


def _intersection(shape_a, shape_b):
    """The shared solid of two solids and the section of their boundaries (OpenCASCADE's boolean
    common and section from one intersection, one thread, the arguments left untouched)."""
    from OCP.BOPAlgo import BOPAlgo_PaveFiller
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Section
    from OCP.OCP.collections import List_TopoDS_Shape

    arguments = List_TopoDS_Shape()
    arguments.Append(shape_a)
    arguments.Append(shape_b)
    filler = BOPAlgo_PaveFiller()
    filler.SetArguments(arguments)
    filler.SetRunParallel(False)
    filler.SetNonDestructive(True)
    filler.Perform()
    if filler.HasErrors():
        raise _Unconfirmed("OpenCASCADE's boolean intersection failed")
    common = BRepAlgoAPI_Common(shape_a, shape_b, filler)
    section = BRepAlgoAPI_Section(shape_a, shape_b, filler)
    if not (common.IsDone() and section.IsDone()):
        raise _Unconfirmed("OpenCASCADE's boolean common failed")
    return common.Shape(), section.Shape()


def _meets_within(section, tolerance: float) -> bool:
    """Whether a section of two boundaries is not empty and each of its vertices and edges lies
    on both within ``tolerance`` (OpenCASCADE's tolerance of each): then the solids are at most
    ``tolerance`` apart."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    found = False
    for kind, cast in ((TopAbs_VERTEX, TopoDS.Vertex), (TopAbs_EDGE, TopoDS.Edge)):
        explorer = TopExp_Explorer(section, kind)
        while explorer.More():
            if BRep_Tool.Tolerance_s(cast(explorer.Current())) > tolerance:
                return False
            found = True
            explorer.Next()
    return found


def _volume(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return float(props.Mass())


def _placement_of(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre of mass and bounding box of a solid."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)  # exact, not enlarged by the tessellation
    return (
        np.array(props.CentreOfMass().Coord()),
        np.array(box.CornerMin().Coord()),
        np.array(box.CornerMax().Coord()),
    )


def _box_of(points: list[tuple[np.ndarray, np.ndarray]]):
    """Centre and box of the closest points."""
    every = np.array([p for pair in points for p in pair], dtype=np.float64)
    lower, upper = every.min(axis=0), every.max(axis=0)
    return 0.5 * (lower + upper), lower, upper


def _distance(shape_a, shape_b) -> tuple[float, list[tuple[np.ndarray, np.ndarray]]]:
    """Distance between two solids (0 when one holds the other) and its solutions' points."""
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    extrema = BRepExtrema_DistShapeShape(shape_a, shape_b)
    if not extrema.IsDone() or extrema.NbSolution() == 0:
        raise _Unconfirmed("OpenCASCADE's distance failed")
    points = [
        (np.array(extrema.PointOnShape1(k).Coord()), np.array(extrema.PointOnShape2(k).Coord()))
        for k in range(1, extrema.NbSolution() + 1)
    ]
    return float(extrema.Value()), points


def _tessellation(shape) -> tuple[np.ndarray, np.ndarray]:
    """A tessellation of a solid, ``SOLID_DEFLECTION`` of its size from its faces, to draw."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    from ..load.step.tessellate import face_arrays, shape_diagonal

    BRepMesh_IncrementalMesh(
        shape, max(SOLID_DEFLECTION * shape_diagonal(shape), 1e-9), False, 0.5, False
    )
    vertices, faces, _ = face_arrays(shape)
    return vertices, faces


def _solids(shape) -> list:
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out, explorer = [], TopExp_Explorer(shape, TopAbs_SOLID)
    while explorer.More():
        out.append(TopoDS.Solid(explorer.Current()))
        explorer.Next()
    return out


def _thickness_bound(shape) -> float:
    """An upper bound on the diameter of any ball inside ``shape``: per connected solid, the
    ball of its volume and its box's smallest side; the largest of them."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    bound = 0.0
    for solid in _solids(shape):
        box = Bnd_Box()
        BRepBndLib.Add_s(solid, box, False)
        side = min(np.array(box.CornerMax().Coord()) - np.array(box.CornerMin().Coord()))
        ball = 2.0 * (3.0 * max(_volume(solid), 0.0) / (4.0 * math.pi)) ** (1.0 / 3.0)
        bound = max(bound, min(side, ball))
    return bound


def _largest_ball(shape) -> float:
    """Diameter of the largest of a few balls exhibited inside ``shape`` (0 when none).

    For each seed (the centroids of a coarse tessellation's largest facets), a ray goes from the
    seed into the solid along the facet's inward normal; the midpoint between the seed and where
    the ray leaves is kept when OpenCASCADE classifies it inside, with the exact distance from it
    to the solid's surface as the radius. Each ball is inside the solid, so the largest is a
    lower bound on its depth.
    """
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.TopAbs import TopAbs_IN

    best = 0.0
    for solid in _solids(shape):
        classifier = BRepClass3d_SolidClassifier(solid)
        for point, inward in _seeds(solid):
            exit_at = _ray_exit(solid, point, inward)
            if exit_at is None:
                continue
            centre = point + 0.5 * exit_at * inward
            classifier.Perform(_pnt(centre), 1e-12)
            if classifier.State() != TopAbs_IN:
                continue
            best = max(best, 2.0 * _distance_to_surface(solid, centre))
    return best


def _seeds(solid) -> list[tuple[np.ndarray, np.ndarray]]:
    """(point, inward unit normal) on the solid's faces, at the parameters of the centroids of a
    coarse mesh's largest facets: points of the exact surface, normals of the exact surface."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.gp import gp_Pnt, gp_Vec
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    from ..load.step import shape_diagonal

    BRepMesh_IncrementalMesh(solid, max(shape_diagonal(solid) * 1e-2, 1e-9), False, 0.5, False)
    facets = []
    explorer = TopExp_Explorer(solid, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
        if tri is None or not tri.HasUVNodes():
            continue
        surface = BRepAdaptor_Surface(face)
        sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
        for i in range(1, tri.NbTriangles() + 1):
            idx = tri.Triangle(i).Get()
            uv = np.mean([tri.UVNode(k).Coord() for k in idx], axis=0)
            xyz = np.array([tri.Node(k).Coord() for k in idx])
            area = float(np.linalg.norm(np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])))
            point, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            surface.D1(float(uv[0]), float(uv[1]), point, du, dv)
            normal = np.cross(du.Coord(), dv.Coord())
            length = float(np.linalg.norm(normal))
            if area > 0 and length > 0:
                facets.append((area, np.array(point.Coord()), -sign * normal / length))
    facets.sort(key=lambda f: (-f[0], tuple(f[1])))
    return [(p, n) for _, p, n in facets[:BALL_SEEDS]]


def _ray_exit(solid, point: np.ndarray, direction: np.ndarray) -> float | None:
    """Distance along ``direction`` from ``point`` (on the surface) to where the ray meets the
    surface again, or None."""
    from OCP.gp import gp_Dir, gp_Lin
    from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector

    intersector = IntCurvesFace_ShapeIntersector()
    intersector.Load(solid, 1e-9)
    intersector.Perform(gp_Lin(_pnt(point), gp_Dir(*direction)), 0.0, math.inf)
    if not intersector.IsDone():
        return None
    hits = [intersector.WParameter(i) for i in range(1, intersector.NbPnt() + 1)]
    scale = max(1.0, float(np.abs(point).max()))
    hits = [w for w in hits if w > 1e-9 * scale]
    return min(hits) if hits else None


def _distance_to_surface(solid, centre: np.ndarray) -> float:
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer

    vertex = BRepBuilderAPI_MakeVertex(_pnt(centre)).Vertex()
    nearest = math.inf
    explorer = TopExp_Explorer(solid, TopAbs_SHELL)  # the surface, not the solid's inside
    while explorer.More():
        extrema = BRepExtrema_DistShapeShape(vertex, explorer.Current())
        if extrema.IsDone():
            nearest = min(nearest, float(extrema.Value()))
        explorer.Next()
    return 0.0 if not math.isfinite(nearest) else nearest


def _pnt(xyz):
    from OCP.gp import gp_Pnt

    return gp_Pnt(*(float(c) for c in xyz))
