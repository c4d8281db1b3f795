"""Pairs -> verdicts, many at a time: pair classes, the pair cache, and dispatch to the run's
workers.

``verify_classes`` takes the pairs' classes (``classes.pair_classes``), looks each class up in
the signed pair cache (``cache.PairCache``), verifies the misses with ``pair.verify_pair`` (here,
or in tasks on the run's executor when there are enough of them), stores the new verdicts and
turns every verdict that is not clear into a ``Finding`` for each pair of its class.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cache import PairCache, pair_key
from ..execute import Executor, Task
from ..load import Body
from ..mesh import as_mesh
from ..progress import Progress
from ..results import Finding, PairVerdict, Verdict, finding_id
from ..settings import Settings
from .classes import (
    PairClasses,
    class_identity,
    class_meshes,
    placed_verdicts,
    shared_key,
)
from .pair import verify_pair

# Where verifying in workers pays is decided from the expected serial seconds of the pairs, a
# function of the inputs only (the verdicts are the same either way, in the same order).
#
#: Expected seconds of a pair whose surfaces may come near: the triangle search and exact
#: distances. ``python bench/verify_parallel.py --size 800``: 720 such pairs in 5.2 s on a
#: quiet 2-core machine.
PAIR_SECONDS = 0.007
#: Expected extra seconds of a pair that may interfere (both meshes closed, hulls penetrating):
#: the shared solid (manifold3d) and its certified depth (``verify.depth``).
#: ``python bench/verify_costs.py`` (CPU seconds per pair of such pairs, ``PAIR_SECONDS``'s part
#: included, cold, loaded machine): 0.028 on the cycloidal gearbox (189 pairs), 0.016 on the PR2
#: (26 pairs).
SOLID_SECONDS = 0.02
#: Serial seconds a fresh pool must save to repay its start (imports, compiled kernels, shipping
#: the meshes): ``bench/verify_parallel.py`` put the 2-process crossover at about 300 plain
#: pairs (1.63x the serial time at 100 pairs, 1.12x at 200, 0.87x at 400, 0.74x at 720).
POOL_SECONDS = 300 * PAIR_SECONDS / 2
#: ... and workers already started (by loading or decomposition): a few messages.
STARTED_POOL_SECONDS = 32 * PAIR_SECONDS / 2
#: This process verifies too while it waits on a local pool, which then starts one worker fewer
#: (``Executor.map(here=True)``): on two cores, two workers importing trimesh and scipy while
#: this process waited cost more than they saved (``python bench/real_assemblies.py``).
VERIFY_HERE_TOO = True
#: Pairs per task sent to a worker at most: enough to amortise a message, few enough to balance.
PAIRS_PER_TASK = 16
#: Expected seconds per task at most: expensive pairs travel alone, so two workers stay busy.
TASK_SECONDS = 0.1


def verify_classes(
    bodies: Sequence[Body],
    classes: PairClasses,
    settings: Settings,
    *,
    executor: Executor | None = None,
    cache: PairCache | None = None,
    hulls_penetrate: np.ndarray | None = None,
) -> list[Finding]:
    """Decide each pair class once, in its frame; a finding for each of its pairs when the
    verdict is not clear, the verdict moved to the pair (``classes.placed_verdicts``), sorted.

    With ``cache`` (the run's pair verdicts, ``cache.PairCache``), verdicts cached by an
    earlier run for the same class are reused; the rest are verified, on ``executor``'s
    processes when their expected serial time (``expected_seconds``; ``hulls_penetrate``,
    ``(k,)`` bool per pair, marks pairs whose hulls overlap) repays the workers, and then
    cached. The findings do not depend on where a verdict came from.
    """
    pairs = classes.pairs
    if hulls_penetrate is None:
        hulls_penetrate = np.zeros(len(pairs), dtype=bool)
    first = classes.first
    cost = expected_seconds(
        bodies, pairs[first], ~classes.surfaces_apart, np.asarray(hulls_penetrate)[first]
    )
    keys, verdicts = _cached(classes, settings.clearance, cache)
    todo = np.array([c for c, v in enumerate(verdicts) if v is None], dtype=np.int64)
    hits = len(classes) - len(todo)
    with Progress("checking", len(classes)) as bar:
        bar.update(hits)
        computed = _verify(
            bodies,
            classes,
            todo,
            settings.clearance,
            executor,
            lambda done: bar.update(hits + done),
            cost=cost[todo],
            bar=bar,
        )
    for c, verdict in zip(todo, computed, strict=True):
        verdicts[c] = verdict
        if cache is not None:
            cache.put(keys[c], verdict)
    if cache is not None and len(todo):
        cache.remove_stale_temporaries()
    return _findings(bodies, classes, verdicts)


def _cached(classes: PairClasses, clearance, cache) -> tuple[list, list]:
    """Each class's cache key (none without a cache), and its cached verdict or None."""
    verdicts: list[PairVerdict | None] = [None] * len(classes)
    keys: list[str] = []
    if cache is None:
        return keys, verdicts
    for c in range(len(classes)):
        a, b, tol, apart = class_identity(classes, c)
        keys.append(pair_key(a, b, tolerance=tol, clearance=clearance, surfaces_apart=apart))
        verdicts[c] = cache.get(keys[c])
    return keys, verdicts


def _findings(bodies, classes: PairClasses, verdicts) -> list[Finding]:
    """A finding for each pair whose class's verdict is not clear, the verdict moved to the
    pair's frame; sorted by part names."""
    findings = []
    for c, (rows, verdict) in enumerate(zip(classes.members(), verdicts, strict=True)):
        if verdict.status == Verdict.CLEAR:
            continue
        moved = placed_verdicts(verdict, *classes.frames(rows))
        for k, v in zip(rows, moved, strict=True):
            i, j = classes.pairs[k]
            findings.append(pair_finding(bodies[i], bodies[j], v, float(classes.tolerance[c])))
    findings.sort(key=lambda f: (f.a, f.b))
    return findings


def verify_task(store: dict, items: list, clearance: float | None) -> list[PairVerdict]:
    """Verify a chunk of classes in a worker: ``items`` are ``(key_a, key_b, tolerance,
    surfaces_apart)``, the keys naming ``(vertices, faces, closed)`` of the placed geometries
    in ``store`` (``classes.shared_key``).

    The meshes are built once per process (kept in ``store``), bit for bit the arrays the main
    process holds, so each verdict is the one ``verify_pair`` gives there.
    """
    memo = store.setdefault(("verify", "memo"), {})
    out = []
    for key_a, key_b, tol, apart in items:
        meshes = []
        for key in (key_a, key_b):
            mesh = store.get(("verify", "mesh", key))
            if mesh is None:
                vertices, faces, closed = store[key]
                mesh = as_mesh(vertices, faces, closed=closed)
                store[("verify", "mesh", key)] = mesh
            meshes.append(mesh)
        out.append(
            verify_pair(
                *meshes, tolerance=tol, clearance=clearance, surfaces_apart=apart, memo=memo
            )
        )
    return out


def expected_seconds(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    near_surfaces: np.ndarray,
    hulls_penetrate: np.ndarray,
) -> np.ndarray:
    """Expected serial seconds of verifying each pair, ``(k,)`` float64 (a function of the inputs
    only): ``PAIR_SECONDS`` where the surfaces may come near, plus ``SOLID_SECONDS`` where
    the pair may interfere (both meshes closed, hulls penetrating); a pair whose surfaces are
    proven apart only has its shells tested, a fraction of that."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    closed = np.zeros(len(bodies), dtype=bool)
    by_mesh: dict[int, bool] = {}  # closedness is the mesh's: decided once per mesh
    for i in np.unique(pairs):
        mesh = bodies[i].mesh
        if id(mesh) not in by_mesh:
            by_mesh[id(mesh)] = bodies[i].is_closed
        closed[i] = by_mesh[id(mesh)]
    near = np.asarray(near_surfaces, dtype=bool)
    solid = (
        near & np.asarray(hulls_penetrate, dtype=bool) & closed[pairs[:, 0]] & closed[pairs[:, 1]]
    )
    return np.where(near, PAIR_SECONDS, 0.1 * PAIR_SECONDS) + np.where(solid, SOLID_SECONDS, 0.0)


def pays_in_workers(executor: Executor | None, cost: np.ndarray) -> bool:
    """True when verifying pairs of expected serial seconds ``cost`` on ``executor``'s workers
    saves more than starting them (or messaging started ones) costs."""
    if executor is None or not len(cost):
        return False
    if executor.is_distributed:
        return True
    if executor.jobs <= 1:
        return False
    start = STARTED_POOL_SECONDS if executor.is_started else POOL_SECONDS
    total = float(np.sum(cost))
    return total - total / executor.jobs > start


def _verify(
    bodies, classes: PairClasses, todo, clearance, executor, progress, *, cost=None, bar=None
) -> list:
    """Verdicts of the classes ``todo`` in order: here, or as tasks on ``executor`` when that
    pays."""
    if cost is None:
        cost = np.full(len(todo), PAIR_SECONDS)
    if not pays_in_workers(executor, cost):
        return _verify_here(bodies, classes, todo, clearance, progress, bar)
    return _verify_in_workers(bodies, classes, todo, clearance, executor, progress, cost, bar)


def _names(bodies, classes: PairClasses, c: int) -> str:
    i, j = classes.pairs[classes.first[c]]
    return f"{bodies[i].name} x {bodies[j].name}"


def _verify_here(bodies, classes: PairClasses, todo, clearance, progress, bar) -> list:
    """Verdicts of the classes ``todo`` in this process, one after another."""
    memo: dict = {}  # per-mesh data verify reuses across pairs; the meshes outlive the loop
    meshes: dict = {}
    out = []
    current = [""]
    if bar is not None:
        bar.detail = lambda: current[0]
    for count, c in enumerate(todo, start=1):
        current[0] = _names(bodies, classes, c)
        out.append(
            verify_pair(
                *class_meshes(classes, c, meshes),
                tolerance=float(classes.tolerance[c]),
                clearance=clearance,
                surfaces_apart=bool(classes.surfaces_apart[c]),
                memo=memo,
            )
        )
        progress(count)
    if bar is not None:
        bar.detail = None
    return out


def _chunks(cost: np.ndarray) -> list[slice]:
    """Consecutive runs of pairs, each at most ``PAIRS_PER_TASK`` pairs and, past its first
    pair, at most ``TASK_SECONDS`` of expected work."""
    out, start, total = [], 0, 0.0
    for k, seconds in enumerate(cost):
        if k > start and (k - start >= PAIRS_PER_TASK or total + seconds > TASK_SECONDS):
            out.append(slice(start, k))
            start, total = k, 0.0
        total += float(seconds)
    if start < len(cost):
        out.append(slice(start, len(cost)))
    return out


def _verify_in_workers(
    bodies, classes: PairClasses, todo, clearance, executor, progress, cost, bar
) -> list:
    """Verdicts of the classes ``todo`` as tasks on ``executor``, in order; each placed
    geometry is shared once, under its content key (``classes.shared_key``)."""
    shared: dict = {}
    items = []
    for c in todo:
        keys = []
        for placed in classes.placed[c]:
            key = shared_key(classes, placed)
            if key not in shared:
                shared[key] = classes.arrays(placed)
            keys.append(key)
        items.append((*keys, float(classes.tolerance[c]), bool(classes.surfaces_apart[c])))
    chunks = _chunks(cost)
    tasks = [
        Task(
            (items[c], clearance),
            needs=tuple(sorted({k for it in items[c] for k in it[:2]})),
            size=int(1e6 * float(np.sum(cost[c]))),
        )
        for c in chunks
    ]
    ends = np.cumsum([c.stop - c.start for c in chunks])
    if bar is not None:
        bar.detail = lambda: ", ".join(
            _names(bodies, classes, todo[chunks[t].start]) for t in executor.running
        )
    try:
        results = executor.map(
            "meshcheck.verify.batch:verify_task",
            tasks,
            shared=shared,
            progress=lambda done: progress(int(ends[done - 1]) if done else 0),
            here=VERIFY_HERE_TOO,
        )
    finally:
        if bar is not None:
            bar.detail = None
    out = []
    for task, result in zip(tasks, results, strict=True):
        if result is None:  # its worker died: verify here (a bug then shows its traceback)
            result = Executor().map("meshcheck.verify.batch:verify_task", [task], shared=shared)[0]
        out.extend(result)
    progress(len(items))
    return out


def pair_finding(a: Body, b: Body, verdict: PairVerdict, tolerance: float) -> Finding:
    """The finding of a pair that is not clear, its parts (and the verdict's) in name order."""
    if (a.name, a.id_digest) > (b.name, b.id_digest):
        a, b, verdict = b, a, verdict.swapped()
    pair_id = finding_id(
        a.name, a.id_digest, b.name, b.id_digest, placement_a=a.transform, placement_b=b.transform
    )
    return Finding(a.name, b.name, verdict, id=pair_id, tolerance=tolerance)
