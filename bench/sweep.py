"""Time the proven sweep of a robot's link pairs against MoveIt-style sampling with python-fcl.

Both classify every link pair of the robot over the full joint ranges, in one run:

- meshcheck's sweep (``meshcheck.sweep``): never proven by conservative advancement, sometimes
  with a witness re-checked on the real meshes; the convex pieces come from a warm cache (a
  run's check has just made them), their time is printed apart;
- python-fcl at N random poses (MoveIt's Setup Assistant samples 10,000): each pose places
  every link (the same forward kinematics) and FCL collides every link pair's meshes; a pair
  is "never" when no sample collides, "always" when every sample does.

Prints both times, their ratio, and where the two disagree: a pair sampling calls never that
the sweep shows colliding (with the witness) is one MoveIt would wrongly disable; a pair the
sweep proves never that sampling sees colliding would be a bug.

    python bench/sweep.py                      # the panda, 10,000 samples
    python bench/sweep.py --robot pr2          # 54 links with geometry, 1,431 pairs
    python bench/sweep.py --robot fanuc --samples 2000
    python bench/sweep.py --robot pr2 --max-boxes 20000   # a smaller per-pair box budget

``--max-boxes`` sets ``meshcheck.sweep.search.MAX_BOXES`` (boxes one pair may evaluate before it is
left undecided) and ``--budget`` the run's sweep budget (``--sweep-budget``): smaller
budgets trade decided pairs for time. The sweep's time is also printed by class (the undecided
pairs' share is what a larger budget buys nothing with), with the work it did and the load
average at the end (the machine is shared; the ratio is measured in one run).

    python bench/sweep.py --robot pr2 --pair head_tilt_link:l_forearm_link --pair ...

sweeps only the named link pairs and prints each one's class, joints, boxes and time (no
sampling): where one pair's time goes. With ``--closest`` it sweeps nothing and looks for the
named pairs' nearest pose instead: 100,000 random poses (fixed seed), the 64 whose convex pieces
come nearest descended 60 steps by the pieces' distance, and python-fcl's distance between the
real meshes at the descended poses: the least is how near the pair is known to come (a pose,
printed; the true least may be smaller), what a proof of never must get within.

    python bench/sweep.py --robot pr2 --closest --pair l_forearm_link:l_gripper_palm_link
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROBOTS = {
    "panda": os.path.join(HERE, "..", "tests", "data", "robots", "panda_description", "urdf",
                          "panda.urdf"),
    "fanuc": os.path.join(HERE, "..", "tests", "data", "robots", "fanuc_description", "urdf",
                          "fanuc.urdf"),
    "pr2": os.path.join(HERE, "..", "tests", "data", "robots", "pr2_description", "urdf",
                        "pr2.urdf"),
}  # fmt: skip


def fcl_sampling(bodies, mech, samples: int, seed: int) -> tuple[dict, float]:
    """Classify every link pair from ``samples`` uniform random poses with python-fcl."""
    import fcl

    from meshcheck.load.robot import joint_values, link_transforms, with_mimics

    robot = mech.robot
    at_zero = link_transforms(robot, joint_values(robot))
    objects = {}
    for link, ks in mech.parts.items():
        inverse = np.linalg.inv(at_zero[link])
        vertices = np.vstack([bodies[k].world.vertices for k in ks])
        faces, offset = [], 0
        for k in ks:
            faces.append(np.asarray(bodies[k].mesh.faces) + offset)
            offset += len(bodies[k].mesh.vertices)
        model = fcl.BVHModel()
        local = vertices @ inverse[:3, :3].T + inverse[:3, 3]
        model.beginModel(len(local), offset)
        model.addSubModel(local, np.vstack(faces).astype(np.int32))
        model.endModel()
        objects[link] = fcl.CollisionObject(model, fcl.Transform())
    links = sorted(objects)
    pairs = [(a, b) for i, a in enumerate(links) for b in links[i + 1 :]]
    hits = dict.fromkeys(pairs, 0)
    movable = robot.movable
    lower = np.array([j.lower if np.isfinite(j.lower) else -np.pi for j in movable])
    upper = np.array([j.upper if np.isfinite(j.upper) else np.pi for j in movable])
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    for q in rng.uniform(lower, upper, size=(samples, len(movable))):
        values = with_mimics(robot, dict(zip([j.name for j in movable], q, strict=True)))
        placed = link_transforms(robot, values)
        for link in links:
            objects[link].setTransform(fcl.Transform(placed[link][:3, :3], placed[link][:3, 3]))
        for a, b in pairs:
            request, result = fcl.CollisionRequest(), fcl.CollisionResult()
            if fcl.collide(objects[a], objects[b], request, result):
                hits[a, b] += 1
    seconds = time.perf_counter() - start
    status = {
        p: "never" if n == 0 else "always" if n == samples else "sometimes" for p, n in hits.items()
    }
    return status, seconds


def oracle_confirms(bodies, mech, pair, tolerance: float = 1e-4) -> str | None:
    """How an independent check confirms that the two links collide at the sweep's witness:
    ``"contact"`` when python-fcl, on the real meshes posed there, sees them collide or come
    within ``tolerance`` (metres; the sweep's touching tolerance is 1e-5 of the smaller link),
    ``"buried"`` when the surfaces are apart but a vertex of one lies inside the other by the
    generalized winding number (tests/meshes.py; above one half, as meshcheck's verify stage
    decides it, for the PR2's open meshes too: a point such a mesh nearly encloses), else None.
    FCL tests surfaces only; meshcheck counts a part buried in another as interference (the
    PR2's 1 mm cube of base_footprint inside a finger, for one)."""
    import fcl
    import trimesh

    from meshcheck.load.robot import joint_values, link_transforms, with_mimics

    tests = os.path.join(HERE, "..", "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    from meshes import winding_inside

    robot = mech.robot
    at_zero = link_transforms(robot, joint_values(robot))
    base = joint_values(robot)
    leading = {j.name: base[j.name] for j in robot.movable}  # mimic joints follow the witness
    placed = link_transforms(robot, with_mimics(robot, {**leading, **pair.witness}))
    meshes = {}
    for link in (pair.a, pair.b):
        move = placed[link] @ np.linalg.inv(at_zero[link])
        meshes[link] = [
            trimesh.Trimesh(bodies[k].world.vertices @ move[:3, :3].T + move[:3, 3],
                            bodies[k].mesh.faces, process=False)
            for k in mech.parts[link]
        ]  # fmt: skip
    for a in meshes[pair.a]:
        for b in meshes[pair.b]:
            oa, ob = (fcl.CollisionObject(_bvh(m), fcl.Transform()) for m in (a, b))
            if fcl.collide(oa, ob, fcl.CollisionRequest(), fcl.CollisionResult()):
                return "contact"
            if fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult()) <= tolerance:
                return "contact"
            for inner, outer in ((a, b), (b, a)):
                if winding_inside(outer, inner.vertices[:1])[0]:
                    return "buried"
    return None


def _bvh(mesh):
    import fcl

    model = fcl.BVHModel()
    model.beginModel(len(mesh.vertices), len(mesh.faces))
    model.addSubModel(np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int32))
    model.endModel()
    return model


def _time_pairs() -> list:
    """Each swept pair's (a, b, class, joints, boxes, seconds), as ``sweep_pair`` returns."""
    import meshcheck.sweep.run as module

    sweep_pair, rows = module.sweep_pair, []

    def timed(pair, lower, *args, **kwargs):
        start = time.perf_counter()
        out = sweep_pair(pair, lower, *args, **kwargs)
        seconds = time.perf_counter() - start
        rows.append((out.a, out.b, str(out.status), len(lower), out.boxes, seconds))
        return out

    module.sweep_pair = timed
    return rows


def sweep_pairs(
    path: str, named: list[str], max_boxes: int | None, *, closest: bool = False
) -> int:
    """Sweep only the ``named`` link pairs (``A:B``) of the robot, printing each one's class,
    joints, boxes and seconds; with ``closest``, each one's nearest pose found instead
    (``nearest_pose``)."""
    import meshcheck.sweep.run as run
    import meshcheck.sweep.search as search
    from meshcheck.load import load_assembly
    from meshcheck.motion import Motion
    from meshcheck.results import PairSweep
    from meshcheck.settings import Settings
    from meshcheck.sweep import mechanism_pieces

    if max_boxes is not None:
        search.MAX_BOXES = max_boxes
    wanted = {tuple(sorted(p.split(":"))) for p in named}
    sweep_pair = run.sweep_pair

    def only_wanted(pair, lower, upper, resolution, **kwargs):
        if (pair.a, pair.b) not in wanted:
            return PairSweep(pair.a, pair.b, "skipped")
        if closest:
            distance, pieces, pose = nearest_pose(pair, lower, upper)
            print(
                f"{pair.a} / {pair.b}: {len(lower)} joints, python-fcl distance "
                f"{distance:.6f} (convex pieces {pieces:.6f}) at "
                + ", ".join(f"{k}={v:.4f}" for k, v in pose.items())
            )
            return PairSweep(pair.a, pair.b, "skipped")
        start = time.perf_counter()
        out = sweep_pair(pair, lower, upper, resolution, **kwargs)
        print(f"{pair.a} / {pair.b}: {out.status}, {len(lower)} joints, {out.boxes} boxes, "
              f"{time.perf_counter() - start:.2f} s")  # fmt: skip
        return out

    run.sweep_pair = only_wanted
    settings = Settings(motion=Motion(sweep=()), cache_dir=None, jobs=1)
    assembly = load_assembly([os.path.normpath(path)])
    bodies, (mech,) = assembly.bodies, assembly.mechanisms
    pieces = mechanism_pieces(bodies, [mech], settings)
    run.sweep_mechanism(mech, bodies, pieces, settings.motion)
    return 0


def nearest_pose(pair, lower, upper, *, samples: int = 100_000, starts: int = 64,
                 steps: int = 60, tries: int = 32) -> tuple[float, float, dict]:  # fmt: skip
    """The least python-fcl distance between the pair's real meshes found by descending the
    convex pieces' distance from the nearest of ``samples`` random poses, the pieces'
    distance bound there, and its pose."""
    import fcl
    import trimesh

    from meshcheck.sweep.search import descent_step

    rng = np.random.default_rng(1)

    def pieces(values):
        ta, tb, _ = pair.placements(values)
        return pair.piece_distances(ta, tb, np.inf)

    values = lower + (upper - lower) * rng.random((samples, len(lower)))
    order = np.argsort(pieces(values), kind="stable")[:starts]
    current = values[order]
    scores = pieces(current)
    step = np.broadcast_to(0.1 * (upper - lower), current.shape).copy()
    for _ in range(steps):
        better = descent_step(pieces, lower, upper, current, scores, step, rng, tries)
        step[~better] *= 0.7
    ta, tb, _ = pair.placements(current)
    models = [_bvh(trimesh.Trimesh(pair.links[n].vertices, pair.links[n].faces, process=False))
              for n in (pair.a, pair.b)]  # fmt: skip
    distances = []
    for e in range(len(current)):
        oa, ob = (fcl.CollisionObject(m, fcl.Transform(t[e][:3, :3], t[e][:3, 3]))
                  for m, t in zip(models, (ta, tb), strict=True))  # fmt: skip
        hit = fcl.collide(oa, ob, fcl.CollisionRequest(), fcl.CollisionResult())
        distances.append(
            0.0 if hit else fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult())
        )
    e = int(np.argmin(distances))
    return (
        float(distances[e]),
        float(scores[e]),
        dict(zip(pair.names, current[e].tolist(), strict=True)),
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=sorted(ROBOTS), default="panda")
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-boxes", type=int, default=None)
    parser.add_argument("--budget", type=int, default=None, help="the sweep's work budget")
    parser.add_argument("--pair", action="append", default=[], metavar="LINK:LINK")
    parser.add_argument(
        "--closest",
        action="store_true",
        help="with --pair: the pairs' nearest pose found, not their sweep",
    )
    parser.add_argument("--rows", metavar="FILE", help="write each pair's class, joints, boxes, "
                        "seconds and sampling's class to this JSON file")  # fmt: skip
    args = parser.parse_args()
    if args.pair:
        return sweep_pairs(ROBOTS[args.robot], args.pair, args.max_boxes, closest=args.closest)

    import meshcheck.sweep.search

    if args.max_boxes is not None:
        meshcheck.sweep.search.MAX_BOXES = args.max_boxes
    rows = _time_pairs()

    from meshcheck.load import load_assembly
    from meshcheck.motion import Motion
    from meshcheck.settings import Settings
    from meshcheck.sweep import mechanism_pieces, sweep_bodies

    path = os.path.normpath(ROBOTS[args.robot])
    budget = {} if args.budget is None else {"budget": args.budget}
    settings = Settings(motion=Motion(sweep=(), **budget), cache_dir=None, jobs=1)
    assembly = load_assembly([path])
    bodies, (mech,) = assembly.bodies, assembly.mechanisms
    start = time.perf_counter()
    pieces = mechanism_pieces(bodies, [mech], settings)
    pieces_s = time.perf_counter() - start
    start = time.perf_counter()
    (robot,) = sweep_bodies(bodies, [mech], settings, pieces=pieces)
    sweep_s = time.perf_counter() - start
    sampled, fcl_s = fcl_sampling(bodies, mech, args.samples, args.seed)

    print(f"robot: {path} ({len(mech.parts)} links with geometry, {len(robot.pairs)} pairs)")
    print(f"box budget per pair: {meshcheck.sweep.search.MAX_BOXES}; "
          f"sweep budget: {settings.motion.budget:,}")  # fmt: skip
    print(f"sweep: {robot.summary()}")
    counts = {s: sum(v == s for v in sampled.values()) for s in ("never", "sometimes", "always")}
    print(f"fcl sampling ({args.samples} poses): {counts}")
    print(f"convex pieces (CoACD, the sweep's, the check uses): {pieces_s:.1f} s")
    print(f"sweep (proof + witnesses):                       {sweep_s:.1f} s")
    by_class: dict = {}
    for row in rows:
        by_class[row[2]] = by_class.get(row[2], 0.0) + row[5]
    shares = ", ".join(f"{k} {v:.1f} s" for k, v in sorted(by_class.items()))
    print(f"  of which, by class: {shares}")
    print(f"python-fcl sampling at {args.samples} poses:          {fcl_s:.1f} s")
    print(f"ratio sweep / sampling: {sweep_s / fcl_s:.2f}")
    missed = bug = 0
    confirmed = {"contact": 0, "buried": 0, None: 0}
    for pair in robot.pairs:
        says = sampled[pair.a, pair.b]
        if pair.status == "sometimes" and says == "never":
            missed += 1
            confirmed[oracle_confirms(bodies, mech, pair)] += 1
            print(f"  sampling calls never, sweep found a witness: {pair.a} / {pair.b} at "
                  + ", ".join(f"{k}={v:.4f}" for k, v in pair.witness.items()))  # fmt: skip
        if pair.status == "never" and says != "never":
            bug += 1
            print(f"  BUG: sweep proved never, sampling collides: {pair.a} / {pair.b}")
    print(f"pairs sampling would wrongly disable: {missed}; at the witness pose python-fcl sees "
          f"{confirmed['contact']} in contact and the winding number {confirmed['buried']} "
          f"buried (unconfirmed: {confirmed[None]}); contradictions: {bug}")  # fmt: skip
    if args.rows:
        with open(args.rows, "w") as f:
            json.dump([[*r, sampled[r[0], r[1]]] for r in rows], f)
    print("load average at the end: " + " ".join(f"{x:.1f}" for x in os.getloadavg()))
    bug += confirmed[None]  # a witness no independent check confirms is a bug too
    return 1 if bug else 0


if __name__ == "__main__":
    sys.exit(main())
