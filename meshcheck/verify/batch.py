"""Pairs -> verdicts, many at a time: the pair cache, and dispatch to the run's workers.

``verify_pairs`` looks each pair up in the signed pair cache (``cache.PairCache``), verifies the
misses with ``pair.verify_pair`` (here, or in tasks on the run's executor when there are enough of
them), stores the new verdicts and turns every verdict that is not clear into a ``Finding``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cache import PairCache, pair_key
from ..execute import Executor, Task
from ..load import Body
from ..progress import Progress
from ..results import Finding, PairVerdict, Verdict, finding_id
from ..settings import Settings
from .pair import verify_pair

#: Fewer pairs than this to verify are verified in this process: starting worker processes
#: (imports, loading the compiled kernels) costs more than the pairs take.
#: ``python bench/verify_parallel.py --size 800`` on a quiet 2-core machine: a fresh 2-process
#: pool took 1.63x the serial time at 100 pairs, 1.12x at 200, 0.87x at 400, 0.74x at 720 (on
#: the same machine shared with other jobs the crossover moved to ~1,000 pairs).
PARALLEL_MIN_PAIRS = 300
#: Pairs per task sent to a worker: enough to amortise a message, few enough to balance.
PAIRS_PER_TASK = 16


def verify_pairs(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    tolerance: np.ndarray,
    near_surfaces: np.ndarray,
    settings: Settings,
    *,
    executor: Executor | None = None,
    secret: bytes | None = None,
) -> list[Finding]:
    """Decide each pair on the real meshes; a finding for each pair that is not clear, sorted.

    With ``secret`` (the run's cache key) and a cache directory, verdicts cached from an earlier
    run (``cache.PairCache``: same meshes, placement, tolerance and clearance) are reused; the
    rest are verified, on ``executor``'s processes when there are at least
    ``PARALLEL_MIN_PAIRS`` of them, and then cached. The findings do not depend on where a
    verdict came from.
    """
    pairs = _oriented(bodies, np.asarray(pairs, dtype=np.int64).reshape(-1, 2))
    verdicts: list[PairVerdict | None] = [None] * len(pairs)
    cache = None
    if settings.cache_dir is not None and secret is not None:
        cache = PairCache(settings.cache_dir, secret=secret)
    keys: list[str] = []
    if cache is not None:
        for k, ((i, j), tol, is_near) in enumerate(
            zip(pairs, tolerance, near_surfaces, strict=True)
        ):
            keys.append(
                pair_key(
                    (bodies[i].digest, bodies[i].transform),
                    (bodies[j].digest, bodies[j].transform),
                    tolerance=float(tol),
                    clearance=settings.clearance,
                    surfaces_apart=not is_near,
                )
            )
            hit = cache.get(keys[k])
            if hit is not None:
                verdicts[k] = hit
    todo = np.array([k for k, v in enumerate(verdicts) if v is None], dtype=np.int64)
    hits = len(pairs) - len(todo)
    with Progress("checking", len(pairs)) as bar:
        bar.update(hits)
        computed = _verify(
            bodies,
            pairs[todo],
            np.asarray(tolerance)[todo],
            np.asarray(near_surfaces)[todo],
            settings.clearance,
            executor,
            lambda done: bar.update(hits + done),
        )
    for k, verdict in zip(todo, computed, strict=True):
        verdicts[k] = verdict
        if cache is not None:
            cache.put(keys[k], verdict)
    if cache is not None and len(todo):
        cache.remove_stale_temporaries()

    findings = [
        _finding(bodies[i], bodies[j], verdict, float(tol))
        for (i, j), tol, verdict in zip(pairs, tolerance, verdicts, strict=True)
        if verdict.status != Verdict.CLEAR
    ]
    findings.sort(key=lambda f: (f.a, f.b))
    return findings


def _oriented(bodies: Sequence[Body], pairs: np.ndarray) -> np.ndarray:
    """``pairs`` with each pair's parts ordered by geometry and placement, not by where their
    files came in the arguments: a verdict, bit for bit, and its cache key do not depend on the
    order the files were given in."""
    if not len(pairs):
        return pairs
    used = np.unique(pairs)
    placed = sorted(used, key=lambda i: (bodies[i].digest, _placement_bytes(bodies[i])))
    rank = np.empty(int(used.max()) + 1, dtype=np.int64)
    rank[placed] = np.arange(len(placed))
    swap = rank[pairs[:, 0]] > rank[pairs[:, 1]]
    return np.where(swap[:, None], pairs[:, ::-1], pairs)


def _placement_bytes(body: Body) -> bytes:
    return np.ascontiguousarray(body.transform, dtype=np.float64).tobytes()


def verify_task(store: dict, items: list, clearance: float | None) -> list[PairVerdict]:
    """Verify a chunk of pairs in a worker: ``items`` are ``(key_a, key_b, tolerance,
    surfaces_apart)``, the keys naming ``(vertices, faces)`` of world meshes in ``store``.

    The meshes are rebuilt once per process (kept in ``store``), bit for bit the arrays the main
    process holds, so each verdict is the one ``verify_pair`` gives there.
    """
    import trimesh

    memo = store.setdefault(("verify", "memo"), {})
    out = []
    for key_a, key_b, tol, apart in items:
        meshes = []
        for key in (key_a, key_b):
            mesh = store.get(("verify", "mesh", key))
            if mesh is None:
                vertices, faces = store[key]
                mesh = trimesh.Trimesh(vertices, faces, process=False, validate=False)
                store[("verify", "mesh", key)] = mesh
            meshes.append(mesh)
        out.append(
            verify_pair(
                *meshes, tolerance=tol, clearance=clearance, surfaces_apart=apart, memo=memo
            )
        )
    return out


def _verify(bodies, pairs, tolerance, near_surfaces, clearance, executor, progress) -> list:
    """Verdicts of ``pairs`` in order: here, or as tasks of ``PAIRS_PER_TASK`` pairs."""
    # Workers already started (by loading or decomposition) cost nothing more to use.
    started = executor is not None and executor.is_started
    least = 2 * PAIRS_PER_TASK if started else PARALLEL_MIN_PAIRS
    parallel = executor is not None and (
        executor.is_distributed or (executor.jobs > 1 and len(pairs) >= least)
    )
    if not parallel:
        memo: dict = {}  # per-mesh data verify reuses across pairs; the bodies outlive the loop
        out = []
        for count, ((i, j), tol, is_near) in enumerate(
            zip(pairs, tolerance, near_surfaces, strict=True), start=1
        ):
            out.append(
                verify_pair(
                    bodies[i].world,
                    bodies[j].world,
                    tolerance=float(tol),
                    clearance=clearance,
                    surfaces_apart=not is_near,
                    memo=memo,
                )
            )
            progress(count)
        return out

    # One shared value per distinct world mesh, named by the first body that has it.
    key_of: dict[int, int] = {}
    shared: dict = {}
    for i in np.unique(pairs):
        world = bodies[i].world
        if id(world) not in key_of:
            key_of[id(world)] = int(i)
            shared[int(i)] = (
                np.asarray(world.vertices, dtype=np.float64),
                np.asarray(world.faces, dtype=np.int64),
            )
    items = [
        (key_of[id(bodies[i].world)], key_of[id(bodies[j].world)], float(tol), not bool(near))
        for (i, j), tol, near in zip(pairs, tolerance, near_surfaces, strict=True)
    ]
    tasks = [
        Task(
            (items[a : a + PAIRS_PER_TASK], clearance),
            needs=tuple(sorted({k for it in items[a : a + PAIRS_PER_TASK] for k in it[:2]})),
        )
        for a in range(0, len(items), PAIRS_PER_TASK)
    ]
    results = executor.map(
        "meshcheck.verify.batch:verify_task",
        tasks,
        shared=shared,
        progress=lambda done: progress(min(len(items), done * PAIRS_PER_TASK)),
    )
    out = []
    for task, result in zip(tasks, results, strict=True):
        if result is None:  # its worker died: verify here (a bug then shows its traceback)
            result = Executor().map("meshcheck.verify.batch:verify_task", [task], shared=shared)[0]
        out.extend(result)
    progress(len(items))
    return out


def _finding(a: Body, b: Body, verdict: PairVerdict, tolerance: float) -> Finding:
    """The finding of a pair that is not clear, its parts (and the verdict's) in name order."""
    if (a.name, a.digest) > (b.name, b.digest):
        a, b, verdict = b, a, verdict.swapped()
    pair_id = finding_id(
        a.name, a.digest, b.name, b.digest, placement_a=a.transform, placement_b=b.transform
    )
    return Finding(a.name, b.name, verdict, id=pair_id, tolerance=tolerance)
