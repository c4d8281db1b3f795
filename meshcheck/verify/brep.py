"""STEP part pairs -> verdicts decided on the exact solids (OpenCASCADE's B-rep), once each.

Why
---
A STEP part is tessellated, and its triangles lie up to the deflection from its curved faces: a
bolt coincident with its hole (line to line: the CAD common volume is 0) shows overlapping chords
a fraction of the tolerance thick, a 0.005 mm press fit hides inside a 0.01 mm tolerance, and a
clearance, a depth or a volume measured on the triangles is off by up to a deflection. The solids
the triangles came from answer all of these exactly, so a pair of STEP solids is decided on them,
and only on them:

- **The meshes filter.** A pair reaches this stage when its convex hulls come within reach (grown
  for STEP solids by ``reach_margin``). Its triangles are within the two deflections of the
  solids, so when the exact triangle distance exceeds the solids' reach (``tolerance +
  clearance``) plus both deflections, and neither mesh holds a shell of the other, the solids are
  farther apart than the reach: the pair is clear (``pair.surface_distance``; milliseconds).
  Every other pair goes to the B-rep, without being decided on the meshes first. Whether the
  meshes come within the two deflections is all the B-rep needs to know of a near pair, so the
  first triangle pair found within them answers (nearest boxes first): a bolt resting along its
  hole costs a few triangle pairs, not every pair of the contact.
- **The B-rep decides** (``solids.decide``), with the pair's own tolerance ``t``: the user's
  ``--tolerance``, or ``TOLERANCE_FRACTION`` of the smaller solid's own box diagonal (in its own
  frame, so every instance of a pair gets the same; the deflections do not enter, the solids are
  exact):

  * when the meshes come within the two deflections, one OpenCASCADE intersection gives the
    shared solid (``BRepAlgoAPI_Common``) and the section of the two boundaries; a section
    edge or vertex that lies on both within ``t`` proves the solids meet, and a shared solid
    with volume that they overlap. Otherwise (or when the meshes keep farther apart)
    ``BRepExtrema_DistShapeShape`` gives the distance ``d``;
  * ``d > t``: **clearance** (``d`` and the two closest points) up to the clearance, else clear;
  * a shared volume ``V`` at most ``pi/6 t**3`` (the volume of a ball of diameter ``t``) proves
    the overlap thinner than ``t``: **touching**, located at the section's box (or the closest
    points'). Otherwise a ball is exhibited inside the shared solid (a ray from a point of its
    surface into it, the midpoint classified inside, its radius the exact distance to the
    surface); a diameter above ``t`` is **interference** with that depth, volume ``V``, and
    the shared solid's centroid and box as its location. Otherwise, when every connected piece
    of the shared solid is provably thinner than ``t`` (its volume's ball, its box),
    **touching**; short of a proof, **interference** (the rule for meshes, kept).

Once each
---------
A pair is decided in its first solid's frame: the first product as written, the second moved by
their relative placement (``solids.decide_pair``). Its key (``pair_key``) is the two products'
content (the file's digest and the product), that relative placement bit for bit, the
tolerance, the clearance, whether the meshes come within the deflections, ``solids``,
``analytic`` and OpenCASCADE's version. Pairs of one run with one key are decided once (a bolt
in each of forty identical nuts), the verdict is kept in the run's pair cache (a warm run reads
no STEP document), and each pair gets it moved to its own placement (``to_world``).

The solids are decided in the run's worker processes when that pays (``_pays_in_workers``), one
pair per task. Where every core's process is started with OpenCASCADE loaded (``_streams``),
each pair goes to an idle worker as soon as the screen makes it: the pairs whose meshes meet
within the deflections first (milliseconds each), then those measured to the reach, so a worker
starts the costliest while this process still screens. A process that has not loaded
OpenCASCADE (a small file read ahead by a worker that has) leaves the pairs to the workers
started, and starts the pool's others only when the pairs' measured seconds repay it
(``_by_started_workers``). OpenCASCADE shapes are not pickled: each product travels once per
worker as BRep text (``StepSolids.product_text``, a few milliseconds to read, where reading the
STEP file again costs a fraction of a second), and the solids are never modified
(non-destructive booleans on copies), so a verdict does not depend on the pairs decided before
it in the same process.

A product whose faces are B-splines lying on planes, cylinders, cones, spheres or tori (as some
CAD systems export every face) is decided on the same solid rebuilt on those surfaces
(``analytic``), when OpenCASCADE's checker finds it valid and its volume is the original's:
OpenCASCADE intersects such faces tens of times faster, and the shared solid's volume is
integrated exactly where the B-spline's fixed quadrature can be far off.

A pair that cannot be decided on the B-rep (OpenCASCADE's boolean or distance fails, a part was
``--split`` into shells or rescaled by ``--units FILE=UNIT``) is verified on its meshes; when
that verdict is touching, a ``MeshcheckWarning`` names the finding and the tolerance that decided
it (``warn_unconfirmed``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import itertools
import json
import os
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence

import numpy as np

from ..cache import PairCache
from ..cache.store import checksum, package_version
from ..errors import InputError, MeshcheckWarning
from ..execute import Executor, Task
from ..load import Body
from ..load.formats import STEP_EXTENSIONS
from ..load.step.tessellate import PREPARE, PREPARE_BYTES
from ..progress import Progress
from ..results import Finding, Location, PairVerdict, Solid, Verdict
from ..settings import Settings
from ..tolerances import default_tolerance
from ..units import METRES
from .solids import NOT_ONE_SOLID, SHAPES

#: Bump when a cached B-rep verdict's meaning changes.
FORMAT_VERSION = 2
#: Seconds one pair on the B-rep (an intersection, or a distance) is expected to take before any
#: is measured (``_decide_all`` then goes by the pairs' mean): from milliseconds on analytic
#: cylinders and planes to seconds on a modelled thread in its hole (``python bench/step.py
#: FOLDERS --phases`` prints each file's mean).
PAIR_SECONDS = 0.15


def prepare_workers(executor: Executor, paths: Sequence[str]) -> None:
    """Start ``executor``'s workers loading OpenCASCADE while this process reads the STEP
    files among ``paths``, when they are large enough (``PREPARE_BYTES``) for their products'
    meshes and B-rep pairs to repay it."""
    size = 0
    for path in paths:
        if path.lower().endswith(STEP_EXTENSIONS):
            with contextlib.suppress(OSError):  # the loader says what is wrong with it
                size += os.path.getsize(path)
    if size >= PREPARE_BYTES:
        executor.prepare(PREPARE)


#: Seconds a worker spends before its first pair, loading OpenCASCADE and reading the products'
#: BRep text: 1.2 s of CPU on the shared 2-core machine (``-j 2`` against ``-j 1`` on
#: box_sides.STEP, the same run).
WORKER_SECONDS = 1.5


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
    own = _own_size_tolerances(bodies, on)
    deflection = np.array([b.deflection for b in bodies], dtype=np.float64)
    if not len(pairs):
        return np.zeros(0)
    i, j = pairs[:, 0], pairs[:, 1]
    both = on[i] & on[j]
    return np.where(both, deflection[i] + deflection[j] + np.maximum(own[i], own[j]), 0.0)


def largest_reach_margin(bodies: Sequence[Body]) -> float:
    """An upper bound of ``reach_margin`` over every pair of ``bodies``, model units."""
    on = np.array([is_on_brep(b) for b in bodies], dtype=bool)
    if on.sum() < 2:
        return 0.0
    deflection = max(b.deflection for b, is_on in zip(bodies, on, strict=True) if is_on)
    return 2.0 * deflection + float(_own_size_tolerances(bodies, on).max())


def decide_on_brep(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    near_surfaces: np.ndarray,
    settings: Settings,
    *,
    executor: Executor | None = None,
    cache: PairCache | None = None,
    meanwhile: Callable[[], None] | None = None,
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
    meanwhile : callable, optional
        Work of this process's own (a warning's check), called once the screen has made every
        job: while the workers decide the first ones when they are sent as made
        (``_streams``), before any is decided otherwise.

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
    jobs: list[_PairJob | None] = [None] * len(chosen)  # None: the meshes proved it clear
    verdicts: dict[str, PairVerdict | str] = {}
    todo: set[str] = set()

    def to_decide() -> Iterator[_PairJob]:
        """The screen's jobs (each put in ``jobs``) the B-rep has to decide: one per key, not
        in the cache."""
        for k, job in _screened(bodies, pairs[chosen], near_surfaces[chosen], settings):
            jobs[k] = job
            if job is None or job.key in verdicts or job.key in todo:
                continue
            hit = cache.get(job.key) if cache is not None else None
            if hit is not None:
                verdicts[job.key] = hit
            else:
                todo.add(job.key)
                yield job

    fresh = _decide_all(bodies, to_decide(), executor, meanwhile)
    for key, verdict in fresh.items():
        verdicts[key] = verdict
        if cache is not None and isinstance(verdict, PairVerdict):
            cache.put(key, verdict)
    findings, on_meshes = [], np.ones(len(pairs), dtype=bool)
    reasons = {}
    for i, j in pairs:  # two STEP parts, one of them split into shells
        if _is_step(bodies[i]) and _is_step(bodies[j]) and not (on[i] and on[j]):
            reasons[bodies[i].name, bodies[j].name] = NOT_ONE_SOLID
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
    """Digest of what computes a B-rep verdict: this file, ``solids``, ``analytic``,
    ``volumes`` and OpenCASCADE's version."""
    from . import analytic, solids, volumes

    sources = []
    for module in (__file__, solids.__file__, analytic.__file__, volumes.__file__):
        with open(module, "rb") as f:
            sources.append(f.read())
    version = package_version("cadquery-ocp-novtk", missing="?").encode()
    return checksum(*sources, version).hex()


def _own_size_tolerances(bodies: Sequence[Body], on: np.ndarray) -> np.ndarray:
    """``_own_size_tolerance`` of each body on the B-rep (``on``), 0 for the others; ``(n,)``
    float64, computed once per product (its instances share its tessellation)."""
    memo: dict = {}
    out = np.zeros(len(bodies))
    for k, body in enumerate(bodies):
        if on[k]:
            key = _product_id(body)
            if key not in memo:
                memo[key] = _own_size_tolerance(body)
            out[k] = memo[key]
    return out


def _own_size_tolerance(body: Body) -> float:
    """The default tolerance of a solid alone, report units: ``TOLERANCE_FRACTION`` of its own
    box diagonal, in its own frame (every instance of it gets the same)."""
    bounds = np.asarray(body.mesh.bounds, dtype=np.float64)  # the file's unit
    diagonal = float(np.linalg.norm(bounds[1] - bounds[0])) * METRES[body.brep.unit]
    return float(default_tolerance(diagonal / METRES[body.units], 0.0))


def _node(body: Body) -> str | None:
    """The solid's node name in its STEP file (``PATH#NODE``), None for another part."""
    prefix = f"{body.path}#"
    return body.name[len(prefix) :] if body.name.startswith(prefix) else None


def _finding(bodies: Sequence[Body], job: _PairJob, verdict: PairVerdict) -> Finding:
    """The finding of a pair the B-rep found not clear, in the world and the report unit, its
    parts (and the verdict's) in name order."""
    from .batch import pair_finding

    a, b = bodies[job.first], bodies[job.second]
    return pair_finding(a, b, to_world(verdict, a), job.tolerance_report)


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


def _screened(bodies, pairs, near_surfaces, settings) -> Iterator[tuple[int, _PairJob | None]]:
    """Each pair's index and job, or None when its meshes stay farther apart than the solids'
    reach plus the two deflections (``pair.surface_distance``): then the solids are clear. A
    job's ``may_overlap`` says whether the meshes come within the two deflections (or one holds
    the other); otherwise the solids are apart, and no boolean is needed.

    A job made is sent to a worker at once (``_decide_all``), so the jobs come as early as the
    screen can tell them, costliest first (``_costliest_first``): first the pairs whose meshes
    meet within the deflections at first sight (``pair.first_within``, milliseconds), then the
    others, each measured to the reach (tens of milliseconds on a large mesh)."""
    from .pair import first_within, surface_distance

    memo: dict = {}
    jobs, rest = {}, []
    for k in _costliest_first(bodies, pairs):
        job = jobs[k] = _pair_job(bodies, pairs[k], settings)
        a, b = bodies[job.first], bodies[job.second]
        deflections = a.deflection + b.deflection
        if near_surfaces[k] and first_within(a.world, b.world, deflections, memo=memo) is not None:
            yield k, _keyed(job, may_overlap=True)
        else:
            rest.append(k)
    for k in rest:
        job = jobs[k]
        a, b = bodies[job.first], bodies[job.second]
        deflections = a.deflection + b.deflection
        reach = job.tolerance_report + deflections
        reach += float(job.clearance or 0.0) * 1e-3 / METRES[a.units]
        distance = surface_distance(
            a.world, b.world, reach=reach, surfaces_apart=not bool(near_surfaces[k]), memo=memo
        )
        yield k, (None if distance > reach else _keyed(job, may_overlap=distance <= deflections))


def _keyed(job: _PairJob, *, may_overlap: bool) -> _PairJob:
    """``job`` with its key (``pair_key``) and ``may_overlap``."""
    key = pair_key(
        job.products,
        job.relative,
        tolerance=job.tolerance,
        clearance=job.clearance,
        may_overlap=may_overlap,
    )
    return dataclasses.replace(job, key=key, may_overlap=may_overlap)


def _costliest_first(bodies: Sequence[Body], pairs: np.ndarray) -> np.ndarray:
    """The order of ``pairs`` by their solids' BRep texts, longest first (``_task``'s size),
    when every text is in hand (read with the file); as given otherwise, reading none for it."""
    sizes = []
    for i, j in pairs:
        lengths = [bodies[k].brep.text_length(_node(bodies[k])) for k in (i, j)]
        if None in lengths:
            return np.arange(len(pairs))
        sizes.append(sum(lengths))
    return np.argsort(-np.asarray(sizes, dtype=np.int64), kind="stable")


def _pays_in_workers(executor: Executor | None, pairs: int, seconds: float | None = None) -> bool:
    """Whether deciding ``pairs`` pairs (``seconds`` each, default ``PAIR_SECONDS``) in
    ``executor``'s workers saves more than their start and their loading OpenCASCADE
    (``WORKER_SECONDS``, unless they loaded it while the file was read: ``PREPARE``) cost."""
    from .batch import POOL_SECONDS

    if executor is None or not pairs:
        return False
    if executor.is_distributed:
        return True
    if not _may_pay(executor):
        return False
    start = 0.0 if executor.is_started else POOL_SECONDS
    if PREPARE not in executor.prepared:
        start += WORKER_SECONDS
    each = PAIR_SECONDS if seconds is None else seconds
    return pairs * each * (1.0 - 1.0 / executor.jobs) > start


def _may_pay(executor: Executor) -> bool:
    """Whether ``executor`` has processes besides this one (a Dask cluster, or local workers)."""
    return executor.is_distributed or executor.jobs > 1


def _left_to_workers(executor: Executor) -> bool:
    """Whether this process leaves the solids to ``executor``'s workers: it has not loaded
    OpenCASCADE (a small file read ahead, ``load.step.ahead.take``), they have (``PREPARE``).
    Loading it here (0.6-0.8 s of CPU) would cost more than such a file's pairs, and while it
    loads, no worker is sent a task."""
    return (
        not executor.is_distributed
        and PREPARE in executor.prepared
        and executor.is_started
        and "OCP.OCP" not in sys.modules
    )


def _by_started_workers(run, executor: Executor, tasks: list[Task]) -> list:
    """Results of ``tasks`` decided by the workers already started (the pool's reserve too: the
    early worker's twin), in batches of 1, 2, 4... tasks, until the batches' mean seconds say
    the rest repay starting the pool's others (``WORKER_SECONDS`` each, OpenCASCADE loaded):
    these then take the rest with them. One map when the started ones fill every core.
    ``run(executor, tasks, done, here=..., grow=...)`` is ``_decide_all``'s map."""
    results: list = []
    started = time.monotonic()
    while len(results) < len(tasks):
        done = len(results)
        mean = (time.monotonic() - started) / max(done, 1)  # seconds per task, these workers
        spare = 1.0 - executor.started / executor.jobs  # of the rest, what others would take
        if spare <= 0:  # every core has its worker: no batches to measure
            return results + run(executor, tasks[done:], done, here=False, grow=False)
        if done and (len(tasks) - done) * mean * spare > WORKER_SECONDS:
            return results + run(executor, tasks[done:], done, here=False)
        results += run(executor, tasks[done : 2 * done + 1], done, here=False, grow=False)
    return results


def _decide_all(
    bodies, jobs: Iterable[_PairJob], executor, meanwhile: Callable[[], None] | None = None
) -> dict[str, PairVerdict | str]:
    """Verdicts (or why not) of ``jobs`` by key: here, or in ``executor``'s workers when their
    expected seconds repay them. Where every core has its process with OpenCASCADE loaded
    (``_streams``), each job goes to an idle worker as soon as the screen makes it.
    ``meanwhile`` is called once the last job is made (``decide_on_brep``)."""
    shared: dict = {SHAPES: {}}  # SHAPES: this process's solids, read once, kept between maps
    made: list[_PairJob] = []
    unreadable: list[str] = []  # why the solids cannot be had: then no job is decided
    counters: list[Progress] = []  # the stage's, once open: it counts the tasks as made

    def tasks() -> Iterator[Task]:
        for job in jobs:
            made.append(job)
            if unreadable:
                continue  # the screen goes on: its jobs say which pairs it proved clear
            try:
                for body, product in zip(
                    (bodies[job.first], bodies[job.second]), job.products, strict=True
                ):
                    if product not in shared:
                        shared[product] = body.brep.product_text(_node(body))
            except InputError as exc:  # the file is gone or changed since load (a cache miss)
                unreadable.append(f"its file cannot be read again ({exc.reason})")
                continue
            for bar in counters:
                bar.update_total(bar.done, len(made))
            yield _task(job, shared)
        if meanwhile is not None:
            meanwhile()

    streams = _streams(executor)
    made_tasks = tasks()
    first = next(made_tasks, None)  # the screen up to its first pair for the B-rep
    if first is None:
        return dict.fromkeys((job.key for job in made), unreadable[0]) if unreadable else {}
    made_tasks = itertools.chain([first], made_tasks)
    if not streams:
        made_tasks = list(made_tasks)
    with Progress("checking on the B-rep", len(made)) as bar:
        counters.append(bar)

        def run(runner: Executor, chosen: Iterable[Task], done: int = 0, **where) -> list:
            return runner.map(
                "meshcheck.verify.solids:brep_task",
                chosen,
                shared=shared,
                progress=lambda n: bar.update(done + n),
                **({"here": True} | where),
            )

        if streams:
            results = run(executor, made_tasks, grow=False)
        else:
            results = _decided(run, executor, made_tasks)
    if unreadable:
        return dict.fromkeys((job.key for job in made), unreadable[0])
    out = {}
    for job, result in zip(made, results, strict=True):
        if result is None:  # its worker died: decide here (a bug then shows its traceback)
            task = _task(job, shared)
            result = Executor().map("meshcheck.verify.solids:brep_task", [task], shared=shared)[0]
        out[job.key] = result
    return out


def _decided(run, executor: Executor | None, tasks: list[Task]) -> list:
    """The results of ``tasks`` (``run(executor, tasks, done, **where)``, ``_decide_all``'s
    map): in ``executor``'s workers when their expected seconds repay them, here otherwise."""
    pays = _pays_in_workers(executor, len(tasks))
    if pays and _left_to_workers(executor):
        return _by_started_workers(run, executor, tasks)
    if pays:
        return run(executor, tasks)
    if executor is None or not _may_pay(executor):
        return run(Executor(), tasks)
    # Pairs here, one at a time, until their mean seconds say the rest repay workers.
    results, started = [], time.process_time()
    while len(results) < len(tasks):
        done = len(results)
        mean = (time.process_time() - started) / max(done, 1)
        if done and _pays_in_workers(executor, len(tasks) - done, mean):
            results += run(executor, tasks[done:], done)
        else:
            results += run(Executor(), tasks[done : done + 1], done)
    return results


def _streams(executor: Executor | None) -> bool:
    """Whether the screen's jobs go to ``executor``'s workers as it makes them: every core but
    this process's has its worker (the pool grows no further), the workers and this process
    have OpenCASCADE loaded (``PREPARE``), so this process screens beside the workers, then
    takes pairs with them. A process without it (``_left_to_workers``) leaves every core to
    the workers: screening beside them would only take a core from one."""
    return (
        executor is not None
        and not executor.is_distributed
        and executor.jobs > 1
        and executor.is_started
        and executor.started >= executor.jobs - 1
        and PREPARE in executor.prepared
        and "OCP.OCP" in sys.modules
    )


def _task(job: _PairJob, shared: dict) -> Task:
    """A job's task; ``shared`` holds its products' texts."""
    return Task(
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
        # The solids' BRep texts, roughly what intersecting them costs: the workers start on
        # the costliest pairs, this process on the costliest they left, then the cheapest
        # (``LocalPool.map``).
        size=len(shared[job.products[0]]) + len(shared[job.products[1]]),
    )
