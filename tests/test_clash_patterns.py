"""Pattern clash groups: findings between copies of the same two geometries at the
same relative placement are one group (IfcClash smart groups, Navisworks grouping), with a stable
ID, in text, JSON and Markdown."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from meshcheck.cli import main
from meshcheck.load import Body
from meshcheck.pipeline import check_bodies
from meshcheck.reports import render
from meshcheck.results import clash_groups

BRACKET = trimesh.creation.box((40.0, 20.0, 10.0))  # centred on its origin
BOLT = trimesh.creation.cylinder(radius=3.0, height=30.0, sections=24)


def placed(x: float, y: float, angle: float = 0.0) -> np.ndarray:
    """A rotation about z by ``angle`` degrees, then a move to (x, y, 0)."""
    m = trimesh.transformations.rotation_matrix(np.radians(angle), (0, 0, 1))
    m[:3, 3] = (x, y, 0.0)
    return m


def station(k: int, x: float, y: float, angle: float, bolt_at=(18.0, 0.0)) -> list[Body]:
    """Bracket ``k`` and its bolt, the bolt at ``bolt_at`` in the bracket's frame (18 mm from the
    middle: it sticks 1 mm out of the bracket's 20 mm half-length... clipping its end)."""
    frame = placed(x, y, angle)
    local = placed(*bolt_at)
    return [
        Body(f"bracket_{k}", "stations.glb", BRACKET, frame),
        Body(f"bolt_{k}", "stations.glb", BOLT, frame @ local),
    ]


def forty_stations() -> list[Body]:
    """Forty brackets in a ring, each turned its own way, each clipped by its bolt the same
    way; and one more whose bolt sits elsewhere (its own clash, not the pattern's)."""
    bodies = []
    for k in range(40):
        angle = 9.0 * k
        r = 200.0
        bodies += station(k, r * np.cos(np.radians(angle)), r * np.sin(np.radians(angle)), angle)
    bodies += station(40, 0.0, 0.0, 0.0, bolt_at=(0.0, 0.0))  # through the middle
    return bodies


@pytest.fixture(scope="module")
def result():
    return check_bodies(forty_stations(), cache_dir=None, jobs=1)


def test_forty_identical_clashes_are_one_pattern_group(result):
    interferences = [f for f in result.findings if f.status == "interference"]
    assert len(interferences) == 41
    groups = clash_groups(result.findings)
    (pattern,) = [g for g in groups if g.kind == "pattern"]
    assert len(pattern.members) == 40 and pattern.part is None
    assert {f.a.split("_")[1] for f in pattern.members} == {str(k) for k in range(40)}
    alone = next(f for f in result.findings if f.a == "bolt_40")
    assert alone.pattern == "" and all(alone is not f for g in groups for f in g.members)


def test_the_pattern_group_id_is_stable_and_follows_content_and_placement(result):
    again = check_bodies(list(reversed(forty_stations())), cache_dir=None, jobs=1)
    ids = [g.id for g in clash_groups(result.findings) if g.kind == "pattern"]
    assert ids == [g.id for g in clash_groups(again.findings) if g.kind == "pattern"]
    # the bolt 0.5 mm further out in every station: another pattern, another ID
    moved = []
    for k in range(40):
        angle = 9.0 * k
        x, y = 200.0 * np.cos(np.radians(angle)), 200.0 * np.sin(np.radians(angle))
        moved += station(k, x, y, angle, bolt_at=(18.5, 0.0))
    other = check_bodies(moved, cache_dir=None, jobs=1)
    (group,) = [g for g in clash_groups(other.findings) if g.kind == "pattern"]
    assert len(group.members) == 40 and [group.id] != ids


def test_a_placement_off_by_more_than_the_tolerance_leaves_the_pattern():
    bodies = forty_stations()[:80]
    bodies[1] = Body("bolt_0", "stations.glb", BOLT, placed(200.0, 0.0) @ placed(18.01, 0.0))
    result = check_bodies(bodies, cache_dir=None, jobs=1, tolerance=1e-3)
    (group,) = [g for g in clash_groups(result.findings) if g.kind == "pattern"]
    assert len(group.members) == 39
    assert "bolt_0" not in {f.a for f in group.members}


def test_identical_parts_clashing_with_each_other_match_either_way_round():
    """Two identical gears meshing too deep, in three places: the pair's order by name is not
    the order of their placement, and the pattern is found whichever way round."""
    gear = trimesh.creation.cylinder(radius=10.0, height=5.0, sections=32)
    bodies = []
    for k, (x, flip) in enumerate([(0.0, False), (100.0, True), (200.0, False)]):
        first, second = placed(x, 0.0), placed(x + 19.0, 0.0)
        if flip:
            first, second = second, first
        bodies += [Body(f"g{k}a", "g.glb", gear, first), Body(f"g{k}b", "g.glb", gear, second)]
    result = check_bodies(bodies, cache_dir=None, jobs=1)
    (group,) = clash_groups(result.findings)
    assert group.kind == "pattern" and len(group.members) == 3


def test_pattern_groups_render_in_text_json_and_markdown(result):
    (pattern,) = [g for g in clash_groups(result.findings) if g.kind == "pattern"]
    text = render(result, "text").splitlines()
    head = text.index(f"group {pattern.id}  pattern: 40 interference,")
    assert text[head + 1] == " " * 14 + "copies of two parts at one relative placement"
    first = pattern.members[0]
    assert text[head + 2].split() == [first.id, first.a, "and", first.b]
    doc = json.loads(render(result, "json"))
    entry = next(g for g in doc["groups"] if g["kind"] == "pattern")
    assert entry == {
        "id": pattern.id,
        "kind": "pattern",
        "part": None,
        "status": "interference",
        "findings": [f.id for f in pattern.members],
    }
    md = render(result, "markdown")
    assert f"- `{pattern.id}` pattern: 40 interference, copies of two parts" in md
    assert f"  - `{first.id}` {first.a.replace('_', chr(92) + '_')} and" in md


def test_instances_in_a_glb_make_a_pattern_end_to_end(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(BRACKET, geom_name="bracket", node_name="bracket_0", transform=placed(0, 0))
    scene.add_geometry(BOLT, geom_name="bolt", node_name="bolt_0", transform=placed(18, 0))
    for k in (1, 2, 3):
        frame = placed(100.0 * k, 50.0, 30.0 * k)
        scene.graph.update(frame_to=f"bracket_{k}", matrix=frame, geometry="bracket")
        scene.graph.update(frame_to=f"bolt_{k}", matrix=frame @ placed(18, 0), geometry="bolt")
    path = tmp_path / "stations.glb"
    scene.export(path)
    out = CliRunner().invoke(
        main, [str(path), "--units", f"{path}=mm", "--no-cache", "--no-config", "-j", "1"]
    )
    assert out.exit_code == 1, out.output
    lines = [line for line in out.stdout.splitlines() if line.startswith("group ")]
    assert len(lines) == 1 and "pattern: 4 interference" in lines[0], out.stdout


def test_copies_written_to_files_at_other_places_are_one_geometry(tmp_path):
    """An array of STL exports: each copy's coordinates went through float32 at its own place,
    so the copies' bits differ, and they are one geometry all the same (one pattern of 6)."""
    from meshcheck.load import load_bodies, local_geometries

    paths = []
    for k in range(6):
        offset = np.array([123.456 * k, 77.7 * k, 0.0])
        bracket = BRACKET.copy().apply_translation(offset)
        bolt = BOLT.copy().apply_translation(offset + np.array([18.0, 0.0, 0.0]))
        for name, mesh in (("bracket", bracket), ("bolt", bolt)):
            path = tmp_path / f"{name}_{k}.stl"
            mesh.export(path)
            paths.append(str(path))
    bodies = load_bodies(paths)
    digests = {local_geometries(bodies)[id(b.mesh)][3] for b in bodies if "bolt" in b.name}
    assert len(digests) > 1  # the bits differ: a digest alone would split the pattern
    result = check_bodies(bodies, cache_dir=None, jobs=1)
    (group,) = clash_groups(result.findings)
    assert group.kind == "pattern" and len(group.members) == 6
