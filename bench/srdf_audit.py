"""Audit moveit_resources' SRDFs: meshcheck's ``--audit-srdf`` against python-fcl sampling.

For the panda and the fanuc, each ``disable_collisions`` entry the SRDF gives as ``Never`` (what
MoveIt's Setup Assistant decided from random samples) is, in one run:

- audited by meshcheck (``sweep.audit``: only the pairs the SRDF names are swept; never is
  proven, a wrongly disabled pair comes with a witness pose re-checked on the real meshes); the
  convex pieces of the audited links (CoACD) are timed apart;
- sampled with python-fcl at N uniform random poses (the Setup Assistant's method, 10,000 by
  default), the same pairs only: the peer the audit's time is compared with.

Every answer is checked independently (``tests/robot_oracle.py``: its own forward kinematics
from the URDF, trimesh reading the collision meshes, python-fcl, the winding number): each
witness must collide there (python-fcl contact, or one link buried in the other), and no pair
the audit proves never may collide at any sample. Exit status 1 on a contradiction.

    python bench/srdf_audit.py                       # both robots, tests/data/robots
    python bench/srdf_audit.py --robot panda --samples 2000
    python bench/srdf_audit.py --data DIR            # DIR: a moveit_resources checkout

The robots and SRDFs are moveit_resources' (commit ef5836d, vendored in tests/data/robots with
their licences; ``--data`` reads the same layout from a clone).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tests"))

#: robot -> (description package, URDF below it, package name, config package, SRDF below it)
ROBOTS = {
    "panda": ("panda_description", "urdf/panda.urdf", "moveit_resources_panda_description",
              "panda_moveit_config", "config/panda.srdf"),
    "fanuc": ("fanuc_description", "urdf/fanuc.urdf", "moveit_resources_fanuc_description",
              "fanuc_moveit_config", "config/fanuc.srdf"),
}  # fmt: skip


def audit(urdf: str, srdf: str, cache: str):
    """meshcheck's audit of the SRDF's Never entries: (SrdfAudit, pieces seconds, audit
    seconds). The pieces are made first (cold cache), then the audit is timed on its own."""
    from meshcheck.cache import open_caches
    from meshcheck.load import load_assembly
    from meshcheck.motion import Motion
    from meshcheck.settings import Settings
    from meshcheck.sweep import audit_srdf, mechanism_pieces

    settings = Settings(motion=Motion(audit=srdf), cache_dir=cache, jobs=1)
    assembly = load_assembly([urdf], motion=settings.motion)
    bodies, mechanisms = assembly.bodies, assembly.mechanisms
    caches = open_caches(cache)
    start = time.perf_counter()
    pieces = mechanism_pieces(bodies, mechanisms, settings, cache=caches.decompositions)
    pieces_s = time.perf_counter() - start
    start = time.perf_counter()
    result = audit_srdf(bodies, mechanisms, settings, pieces=pieces)
    return result, pieces_s, time.perf_counter() - start


def sampled(robot, pairs, samples: int, seed: int) -> tuple[dict, float]:
    """How many of ``samples`` uniform random poses each link pair collides at (python-fcl on
    the oracle's meshes and kinematics), and the seconds it took."""
    import fcl
    import trimesh
    from meshes import fcl_object
    from robot_oracle import link_poses

    links = sorted({link for pair in pairs for link in pair})
    objects = {}
    for link in links:
        merged = trimesh.util.concatenate(robot.meshes[link])
        objects[link] = fcl_object(merged)
    movable = robot.movable
    lower = np.array([j.lower for j in movable])
    upper = np.array([j.upper for j in movable])
    hits = dict.fromkeys(pairs, 0)
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    for q in rng.uniform(lower, upper, size=(samples, len(movable))):
        poses = link_poses(robot, {j.name: v for j, v in zip(movable, q, strict=True)})
        for link in links:
            objects[link].setTransform(fcl.Transform(poses[link][:3, :3], poses[link][:3, 3]))
        for a, b in pairs:
            if fcl.collide(objects[a], objects[b], fcl.CollisionRequest(), fcl.CollisionResult()):
                hits[a, b] += 1
    return hits, time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=sorted(ROBOTS), action="append")
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0)
    vendored = os.path.relpath(os.path.join(ROOT, "tests", "data", "robots"))
    parser.add_argument(
        "--data", default=vendored, help="a moveit_resources checkout (default: the vendored copy)"
    )
    args = parser.parse_args()
    from robot_oracle import collide, read_robot

    bad = 0
    for name in args.robot or sorted(ROBOTS):
        description, urdf_rel, package, config, srdf_rel = ROBOTS[name]
        urdf = os.path.join(args.data, description, urdf_rel)
        srdf = os.path.join(args.data, config, srdf_rel)
        with tempfile.TemporaryDirectory() as cache:
            result, pieces_s, audit_s = audit(urdf, srdf, cache)
        robot = read_robot(urdf, {package: os.path.join(args.data, description)})
        pairs = [(p.a, p.b) for p in result.pairs]
        hits, fcl_s = sampled(robot, pairs, args.samples, args.seed)
        print(f"robot: {name}")
        print(f"audit: {result.summary()}")
        print(f"convex pieces of the audited links (CoACD):  {pieces_s:.1f} s")
        print(f"audit (proof + witnesses):                   {audit_s:.1f} s")
        print(f"python-fcl, the same pairs at {args.samples} poses:  {fcl_s:.1f} s")
        print(f"ratio audit / sampling: {audit_s / fcl_s:.2f}")
        confirmed = {"contact": 0, "buried": 0, None: 0}
        for pair in result.pairs:
            seen = hits[pair.a, pair.b]
            if pair.is_wrong:
                how = collide(robot, pair.a, pair.b, pair.sweep.witness)
                confirmed[how] += 1
                values = ", ".join(f"{k}={v:.4f}" for k, v in pair.sweep.witness.items())
                print(f"  wrongly disabled ({pair.reason}): {pair.a} / {pair.b} at {values}; "
                      f"independent check: {how or 'NOT CONFIRMED'}; "
                      f"{seen} of {args.samples} samples collide")  # fmt: skip
            elif pair.status == "never" and seen:
                bad += 1
                print(f"  BUG: proven never, {seen} samples collide: {pair.a} / {pair.b}")
        sampled_never = sum(hits[p] == 0 for p in pairs)
        print(
            f"sampling at {args.samples} poses calls {sampled_never} of the {len(pairs)} pairs "
            f"never; witnesses confirmed by python-fcl contact {confirmed['contact']}, by the "
            f"winding number {confirmed['buried']}, unconfirmed {confirmed[None]}"
        )
        bad += confirmed[None]
    print(f"contradictions: {bad}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
