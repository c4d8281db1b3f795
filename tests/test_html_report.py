"""The HTML report: its data round-trips, hostile names stay text, it works in a real browser."""

from __future__ import annotations

import base64
import dataclasses
import gzip
import io
import json
import os
import re
import socket
import sys

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from meshcheck.config import Approval
from meshcheck.load import Body
from meshcheck.pipeline import check_bodies
from meshcheck.reports import html as html_report
from meshcheck.reports.common import length, ordered, resolution, volume
from meshcheck.reports.html import render_html

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), "scripts"))

HOSTILE = (
    "evil</script><script>window.__pwned=1</script>\"'\n\x1b[31m\u2028"
    '<img src=x onerror="window.__pwned=2">&amp;'
)


def box(name: str, lower, upper) -> Body:
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    mesh = trimesh.creation.box(extents=upper - lower)
    mesh.apply_translation(0.5 * (lower + upper))
    return Body(name=name, path=name, mesh=mesh)


def assembly() -> list[Body]:
    """Interference, touching, clearance and an approved interference, on boxes (no CoACD)."""
    return [
        box("base.stl", [0, 0, 0], [10, 10, 1]),
        box("sunk.stl", [1, 1, 0.7], [3, 3, 3]),  # 0.3 into the base: interference
        box("resting.stl", [5, 1, 1], [7, 3, 2]),  # on the base: touching
        box("near.stl", [4, 4, 1.2], [5, 5, 2]),  # 0.2 above the base: clearance
        box(HOSTILE, [8, 8, 0.5], [9, 9, 2]),  # 0.5 into the base, approved
    ]


@pytest.fixture(scope="module")
def checked():
    bodies = assembly()
    result = check_bodies(
        bodies,
        clearance=0.25,
        jobs=1,
        approvals=[Approval("evil*", "base.stl", "press fit\n</script>\x1b[0m")],
    )
    return result, bodies


def render(checked, **options) -> str:
    result, bodies = checked
    options = {"inputs": [b.path for b in bodies], "version": "0.1.0", **options}
    return render_html(result, bodies, **options)


def embedded(text: str) -> tuple[dict, bytes]:
    """The report's JSON data and its inflated geometry buffer."""
    data = re.search(r'<script type="application/json" id="meshcheck-data">(.*?)</script>', text)
    blob = re.search(
        r'<script type="application/octet-stream" id="meshcheck-geometry">(.*?)<', text
    )
    return json.loads(data.group(1)), gzip.decompress(base64.b64decode(blob.group(1)))


def decoded_vertices(data: dict, buffer: bytes, k: int, matrix) -> np.ndarray:
    """Vertices of display mesh ``k`` placed by a column-major 4x4 ``matrix``."""
    m = data["meshes"][k]
    grid = np.frombuffer(buffer, dtype="<i2", count=3 * m["nv"], offset=m["pos"]).reshape(-1, 3)
    mat = np.asarray(matrix, dtype=np.float64).reshape(4, 4).T
    return grid @ mat[:3, :3].T + mat[:3, 3]


# ---------------------------------------------------------------------------------------------
# the file itself


def test_findings_of_every_status(checked):
    result, _ = checked
    statuses = {(f.a, f.b): (f.status, f.approval_reason) for f in result.findings}
    assert statuses[("base.stl", "sunk.stl")] == ("interference", None)
    assert statuses[("base.stl", "resting.stl")] == ("touching", None)
    assert statuses[("base.stl", "near.stl")] == ("clearance", None)
    assert statuses[("base.stl", HOSTILE)][1] == "press fit\n</script>\x1b[0m"


def test_hostile_names_are_data(checked):
    text = render(checked, units="mm</script>", inputs=[HOSTILE, "a\u2029b"])
    # Exactly the four scripts of the template; no input opened or closed an element.
    assert text.count("<script") == 4
    assert text.count("</script>") == 4
    assert "<img" not in text
    for raw in ("\x1b", "\u2028", "\u2029", "\n\x1b"):
        assert raw not in text
    data, _ = embedded(text)
    names = {p["name"] for p in data["parts"]}
    assert HOSTILE in names
    assert data["inputs"] == [HOSTILE, "a\u2029b"]
    assert data["units"] == "mm</script>"
    approved = [f for f in data["findings"] if f["approved"] is not None]
    assert [(f["b"], f["approved"]) for f in approved] == [(HOSTILE, "press fit\n</script>\x1b[0m")]
    assert not approved[0]["fails"]


def test_summary_matches_the_report_module(checked):
    from meshcheck.reports import summary

    result, _ = checked
    data, _ = embedded(render(checked))
    assert data["summary"] == summary(result)
    assert data["summary"]["passed"] is False
    report_only = dataclasses.replace(result, settings=result.settings.replace(fail_on=()))
    strict, _ = embedded(render((report_only, checked[1])))
    assert strict["summary"]["passed"] is True
    assert not any(f["fails"] for f in strict["findings"])


def test_geometry_round_trips_within_the_grid(checked):
    """Decoding the buffer and placing each part gives its world vertices, to 16-bit accuracy."""
    _, bodies = checked
    data, buffer = embedded(render(checked))
    origin = None
    for part in data["parts"]:
        body = next(b for b in bodies if b.name == part["name"])
        v = decoded_vertices(data, buffer, part["mesh"], part["matrix"])
        world = np.asarray(body.world.vertices)
        if origin is None:  # the view is relative to the assembly's centre
            lo = np.min([b.world.bounds[0] for b in bodies], axis=0)
            hi = np.max([b.world.bounds[1] for b in bodies], axis=0)
            origin = 0.5 * (lo + hi)
        step = np.ptp(world, axis=0).max() / 65534
        np.testing.assert_allclose(v + origin, world, rtol=0, atol=step)


def test_interference_volume_is_the_shared_solid(checked):
    data, buffer = embedded(render(checked))
    (sunk,) = [f for f in data["findings"] if f["b"] == "sunk.stl"]
    m = data["meshes"][sunk["solid"]]
    v = decoded_vertices(data, buffer, sunk["solid"], m["matrix"])
    # base [0,10]^2 x [0,1], sunk [1,3]^2 x [0.7,3]: they share [1,3]^2 x [0.7,1]
    extent = np.ptp(v, axis=0)
    np.testing.assert_allclose(extent, [2, 2, 0.3], atol=1e-4)
    clearance = next(f for f in data["findings"] if f["status"] == "clearance")
    assert clearance["solid"] is None


def test_instances_and_translated_copies_share_geometry():
    plate = trimesh.creation.box(extents=[4, 4, 1])
    bodies = []
    for k in range(3):  # instances of one mesh in a glTF file: rotated, 10 apart
        transform = trimesh.transformations.rotation_matrix(0.3 * k, [0, 0, 1])
        transform[:3, 3] = [10 * k, 0, 0]
        bodies.append(Body(name=f"inst{k}", path="a.glb", mesh=plate, transform=transform))
    copy = plate.copy().apply_translation([0, 50, 1000])  # an STL file of the same part, moved
    bodies.append(Body(name="copy.stl", path="copy.stl", mesh=copy))
    other = trimesh.creation.box(extents=[4, 4, 2]).apply_translation([0, -50, 0])
    bodies.append(Body(name="other.stl", path="other.stl", mesh=other))
    result = check_bodies(bodies, jobs=1)
    data, buffer = embedded(render_html(result, bodies, version="x"))
    assert result.findings == []
    assert len(data["meshes"]) == 2  # the plate once, the thicker box once
    assert len({p["mesh"] for p in data["parts"]}) == 2
    centre = 0.5 * (
        np.min([b.world.bounds[0] for b in bodies], axis=0)
        + np.max([b.world.bounds[1] for b in bodies], axis=0)
    )
    for part, body in zip(data["parts"], bodies, strict=True):
        v = decoded_vertices(data, buffer, part["mesh"], part["matrix"]) + centre
        np.testing.assert_allclose(v, body.world.vertices, rtol=0, atol=1e-3)


def test_large_assemblies_are_simplified_for_display(monkeypatch):
    monkeypatch.setattr(html_report, "DISPLAY_TRIANGLES", 3000)
    spheres = []
    for k in range(3):  # 5120 triangles each, distinct radii so nothing is shared
        mesh = trimesh.creation.icosphere(subdivisions=4, radius=1.0 + 0.1 * k)
        spheres.append(
            Body(name=f"s{k}.stl", path=f"s{k}.stl", mesh=mesh.apply_translation([5 * k, 0, 0]))
        )
    small = box("small.stl", [0, 5, 0], [1, 6, 1])  # 12 triangles: kept as it is
    bodies = [*spheres, small]
    result = check_bodies(bodies, jobs=1)
    data, buffer = embedded(render_html(result, bodies, version="x"))
    assert data["triangles"]["parts"] == 3 * 5120 + 12
    assert data["triangles"]["shown"] <= 3000 * 1.05
    centre = 0.5 * (
        np.min([b.world.bounds[0] for b in bodies], axis=0)
        + np.max([b.world.bounds[1] for b in bodies], axis=0)
    )
    for part, body in zip(data["parts"], bodies, strict=True):
        v = decoded_vertices(data, buffer, part["mesh"], part["matrix"]) + centre
        if body is small:
            np.testing.assert_allclose(v, body.world.vertices, rtol=0, atol=1e-3)
            continue
        assert data["meshes"][part["mesh"]]["nf"] < 1500
        radius = np.linalg.norm(v - body.world.centroid, axis=1)
        np.testing.assert_allclose(radius, body.mesh.bounding_sphere.primitive.radius, rtol=0.03)


def test_context_parts_become_hulls_when_decimation_is_not_enough(monkeypatch):
    monkeypatch.setattr(html_report, "DISPLAY_TRIANGLES", 600)
    # 4096 long thin triangles, in no finding: quadric decimation stops near 2600
    rod = trimesh.creation.cylinder(radius=1, height=20, sections=64).subdivide().subdivide()
    far = Body("far.stl", "far.stl", rod.apply_translation([10, 0, 0]))
    a = box("a.stl", [0, 0, 0], [1, 1, 1])
    b = box("b.stl", [0.5, 0, 0], [2, 1, 1])
    bodies = [a, b, far]
    result = check_bodies(bodies, jobs=1)
    assert {(f.a, f.b) for f in result.findings} == {("a.stl", "b.stl")}
    data, _ = embedded(render_html(result, bodies, version="x"))
    by_name = {p["name"]: data["meshes"][p["mesh"]] for p in data["parts"]}
    assert by_name["a.stl"]["nf"] == by_name["b.stl"]["nf"] == 12  # kept as they are
    assert by_name["far.stl"]["nf"] == len(ConvexHull(rod.vertices).simplices)
    assert data["triangles"]["shown"] <= 600 < data["triangles"]["parts"]


def test_clearance_line_joins_the_closest_points():
    """Edges 0.2 apart diagonally: x grows from a to b while y falls, so the box of the two
    points has them on its (x max, y min) diagonal, not on (min, max)."""
    a = box("a.stl", [0, 0, 0], [1, 1, 1])
    b = box("b.stl", [1.2, -1.2, 0], [2.2, -0.2, 1])
    result = check_bodies([a, b], clearance=0.5, jobs=1)
    (finding,) = result.findings
    assert finding.status == "clearance"
    p, q = finding.closest  # the verify stage's points, on a and on b
    np.testing.assert_allclose(np.linalg.norm(q - p), finding.distance, rtol=1e-9)
    np.testing.assert_allclose(p[:2], [1, 0], atol=1e-9)
    np.testing.assert_allclose(q[:2], [1.2, -0.2], atol=1e-9)
    data, _ = embedded(render_html(result, [a, b], version="x"))
    line = np.asarray(data["findings"][0]["line"])
    np.testing.assert_allclose(np.linalg.norm(line[1] - line[0]), finding.distance, rtol=1e-6)
    origin = np.array([1.1, -0.1, 0.5])  # the centre of the scene's box
    np.testing.assert_allclose(line, [p - origin, q - origin], atol=1e-9)


def test_names_nothing_from_the_machine(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name, lower, upper in (("a.stl", [0, 0, 0], [1, 1, 1]), ("b.stl", [0.5, 0, 0], [2, 1, 1])):
        box(name, lower, upper).mesh.export(name)
    from meshcheck.load import load_bodies
    from meshcheck.pipeline import check

    result = check(["a.stl", "b.stl"], jobs=1)
    text = render_html(
        result,
        load_bodies(["a.stl", "b.stl"]),
        inputs=["a.stl", "b.stl"],
        version="0.1.0",
    )
    data, _ = embedded(text)
    # Everything but the fixed assets (checked not to vary below) and the geometry's base64.
    readable = text.replace(re.search(r'id="meshcheck-geometry">(.*?)<', text).group(1), "")
    for asset in ("three.min.js", "viewer.js", "viewer.css", "three.LICENSE"):
        readable = readable.replace(html_report._asset(asset), "")
    for secret in (str(tmp_path), os.path.expanduser("~"), socket.gethostname(), sys.prefix):
        assert secret not in readable
    assert {p["name"] for p in data["parts"]} == {"a.stl", "b.stl"}
    assert len(readable) < 10_000  # the assets were found and removed


def test_output_is_deterministic(checked):
    assert render(checked) == render(checked)


def test_inlined_scripts_cannot_close_their_element():
    with pytest.raises(ValueError):
        html_report._script("x = '</SCRIPT>'")
    with pytest.raises(ValueError):
        html_report._script("x = '<!--'")
    assert html_report._asset("three.min.js").startswith("/* three.js 0.187.0")
    assert "MIT License" in html_report._asset("three.LICENSE")


# ---------------------------------------------------------------------------------------------
# in a real browser


def pixel_spread(png: bytes) -> float:
    from PIL import Image

    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.float64)
    return float(pixels.std(axis=(0, 1)).mean())


@pytest.mark.browser
@pytest.mark.slow
def test_report_in_chromium(checked, browser_page, tmp_path):
    page, errors = browser_page
    result, _ = checked
    path = tmp_path / "report.html"
    path.write_text(render(checked, inputs=[HOSTILE]), encoding="utf-8")
    requests = []
    page.on("request", lambda r: requests.append(r.url))
    open_report(page, path)
    assert page.evaluate("window.__pwned") is None
    assert errors == []
    assert requests == [path.as_uri()]  # the page itself, nothing else: no network

    # The 3D view drew something: a blank canvas is one colour.
    canvas = page.locator("#view canvas")
    assert pixel_spread(canvas.screenshot()) > 10
    (tmp_path / "screenshot.png").write_bytes(page.screenshot())

    # Header and table.
    assert page.locator("#verdict").inner_text() == "FAIL"
    rows = page.locator("#findings tbody tr")
    assert rows.count() == len(result.findings)
    ids = [rows.nth(k).get_attribute("data-id") for k in range(rows.count())]
    assert ids == [f.id for f in ordered(result)]  # most severe first, as every format
    hostile_row = page.locator("#findings tbody tr[data-status=approved]")
    assert hostile_row.count() == 1
    shown = hostile_row.inner_text()
    assert "evil</script><script>window.__pwned=1</script>" in shown
    assert "\\u001b[31m" in shown and "\\u2028" in shown  # control characters shown as escapes
    assert "approved: press fit\\u000a</script>\\u001b[0m" in shown
    inputs = page.locator("#header .inputs li").all_text_contents()  # folded: not "inner"
    assert inputs == [printable(HOSTILE)]

    # Clicking a row frames that finding: the camera moves and looks at its clashing region.
    before = page.evaluate("window.meshcheckView.camera.position.toArray()")
    resting = next(f for f in result.findings if f.b == "resting.stl")
    page.locator(f"#findings tbody tr[data-id='{resting.id}']").click()
    after = page.evaluate("window.meshcheckView.camera.position.toArray()")
    target = np.array(page.evaluate("window.meshcheckView.controls.target.toArray()"))
    assert np.linalg.norm(np.subtract(after, before)) > 1.0
    data, _ = embedded(path.read_text(encoding="utf-8"))
    box = np.asarray(next(f for f in data["findings"] if f["id"] == resting.id)["box"])
    np.testing.assert_allclose(target, box.mean(axis=0), atol=1e-6)
    assert label_lines(page) == ["touching", "base.stl", "resting.stl"]
    # A contact has no volume: its location box is outlined in the strong blue, over the parts.
    pixels = canvas_pixels(page)
    assert strong(pixels, "blue").sum() > 20

    # Filtering by status hides those rows only.
    page.locator("#filters input[data-status=touching]").uncheck()
    visible = page.locator("#findings tbody tr:visible")
    assert visible.count() == len(result.findings) - 1
    assert not page.locator("#clash-label .card").is_visible()  # the selected one was touching
    page.locator("#filters input[data-status=touching]").check()
    page.wait_for_selector("#clash-label .card", state="visible")  # on the next frame
    assert label_lines(page) == ["touching", "base.stl", "resting.stl"]
    assert errors == []


# ---------------------------------------------------------------------------------------------
# the view frames the clash


def open_report(page, path) -> None:
    page.goto(path.as_uri())
    page.wait_for_function("document.body.dataset.ready")
    assert page.evaluate("document.body.dataset.ready") == "true"


def printable(text: str) -> str:
    """A name as the page shows it: control characters as ``\\uXXXX``."""
    unprintable = r"[\x00-\x1f\x7f-\x9f\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff]"
    return re.sub(unprintable, lambda m: f"\\u{ord(m.group()):04x}", text)


def project(page, points) -> np.ndarray:
    """``points`` (n, 3), scene coordinates, in the view's normalised device coordinates
    (x and y in [-1, 1] inside the view), from the camera's own matrices."""
    camera = page.evaluate(
        "[window.meshcheckView.camera.projectionMatrix.elements,"
        " window.meshcheckView.camera.matrixWorldInverse.elements]"
    )
    projection, view = (np.asarray(m, dtype=np.float64).reshape(4, 4).T for m in camera)
    p = np.c_[np.asarray(points, dtype=np.float64), np.ones(len(points))] @ (projection @ view).T
    assert np.all(p[:, 3] > 0), "a point is behind the camera"
    return p[:, :3] / p[:, 3:]


def canvas_pixels(page) -> np.ndarray:
    """What WebGL drew (the canvas alone: no label or page over it), (h, w, 3) uint8."""
    from PIL import Image

    url = page.evaluate("window.meshcheckView.renderer.domElement.toDataURL('image/png')")
    raw = base64.b64decode(url.partition(",")[2])
    return np.asarray(Image.open(io.BytesIO(raw)).convert("RGB"))


def strong(pixels: np.ndarray, hue: str) -> np.ndarray:
    """Mask of the pixels in one of the view's strong colours (red: an interference's shared
    solid; magenta: a clearance witness; blue: a contact box), whatever the lighting."""
    r, g, b = (pixels[..., k].astype(np.int64) for k in range(3))
    if hue == "red":
        return (r > 110) & (r > 2.5 * g) & (r > 2.5 * b)
    if hue == "magenta":
        return (r > 110) & (b > 110) & (r > 2.5 * g) & (b > 2.5 * g)
    return (b > 110) & (b > 2 * r) & (b > 1.6 * g)


def saturated(pixels: np.ndarray) -> np.ndarray:
    """Mask of strongly coloured pixels of any hue (the muted part colours are not)."""
    p = pixels.astype(np.int64)
    return p.max(axis=2) - p.min(axis=2) > 100


def pixel_box(ndc: np.ndarray, shape: tuple[int, ...], margin: int = 3) -> tuple[slice, slice]:
    """The canvas pixels covering the projected points' 2D box, with a margin."""
    h, w = shape[:2]
    x = (ndc[:, 0] + 1) / 2 * w
    y = (1 - ndc[:, 1]) / 2 * h
    x0, x1 = max(int(x.min()) - margin, 0), min(int(np.ceil(x.max())) + margin, w)
    y0, y1 = max(int(y.min()) - margin, 0), min(int(np.ceil(y.max())) + margin, h)
    return slice(y0, y1), slice(x0, x1)


def corners(lower, upper) -> np.ndarray:
    return np.array(np.meshgrid(*np.c_[lower, upper])).reshape(3, -1).T


def label_lines(page) -> list[str]:
    card = page.locator("#clash-label .card")
    assert card.is_visible()
    return card.locator("div").all_text_contents()


def solid_box(data, buffer, finding: dict) -> np.ndarray:
    """The (2, 3) box of a finding's shared solid as the report stores it, scene coordinates."""
    v = decoded_vertices(data, buffer, finding["solid"], data["meshes"][finding["solid"]]["matrix"])
    return np.array([v.min(axis=0), v.max(axis=0)])


@pytest.mark.browser
@pytest.mark.slow
def test_view_frames_the_worst_failing_clash_on_load(checked, browser_page, tmp_path):
    """On load, the camera fits the deepest failing interference's shared solid (not the whole
    assembly), a label at it names the parts and the depth, and only the solid is strong red."""
    page, errors = browser_page
    result, bodies = checked
    path = tmp_path / "report.html"
    path.write_text(render(checked), encoding="utf-8")
    open_report(page, path)
    worst = next(f for f in ordered(result) if result.is_failing(f))
    assert (worst.a, worst.b) == ("base.stl", "sunk.stl")
    assert page.locator("#findings tbody tr.selected").get_attribute("data-id") == worst.id

    data, buffer = embedded(path.read_text(encoding="utf-8"))
    row = next(f for f in data["findings"] if f["id"] == worst.id)
    box = solid_box(data, buffer, row)
    centre, region = project(page, box.mean(axis=0)[None])[0], project(page, corners(*box))
    assert np.all(np.abs(centre[:2]) < 0.1)  # the clash is in the middle of the view
    assert np.all(np.abs(region[:, :2]) < 1)  # all of it is in view
    assert np.ptp(region[:, :2], axis=0).max() > 0.5  # and it fills much of it
    scene_origin = 0.5 * (  # the view works relative to the assembly's centre
        np.min([b.world.bounds[0] for b in bodies], axis=0)
        + np.max([b.world.bounds[1] for b in bodies], axis=0)
    )
    base = next(b for b in bodies if b.name == "base.stl").world.bounds - scene_origin
    assert np.abs(project(page, corners(*base))[:, :2]).max() > 1  # the assembly is not fitted

    # The label: anchored at the clash, with the parts and the depth, as text.
    assert label_lines(page) == [
        f"interference \u00b7 {length(worst.depth, resolution(result))} mm deep \u00b7 "
        f"{volume(worst.volume)} mm\u00b3",  # the figures as every format prints them
        "base.stl",
        "sunk.stl",
    ]
    pin = page.locator("#clash-label .pin").bounding_box()
    view = page.locator("#view canvas").bounding_box()
    pin_ndc = [
        2 * (pin["x"] + pin["width"] / 2 - view["x"]) / view["width"] - 1,
        1 - 2 * (pin["y"] + pin["height"] / 2 - view["y"]) / view["height"],
    ]
    np.testing.assert_allclose(pin_ndc, centre[:2], atol=0.02)

    # Colour: the shared solid's pixels are strong red, and nothing else in the view is strong.
    pixels = canvas_pixels(page)
    rows, cols = pixel_box(region, pixels.shape)
    red = strong(pixels, "red")
    inside = red[rows, cols].sum()
    assert inside > 0.3 * red[rows, cols].size
    outside_mask = np.ones(red.shape, dtype=bool)
    outside_mask[rows, cols] = False
    assert red[outside_mask].sum() < 30
    assert saturated(pixels)[outside_mask].sum() < 0.002 * outside_mask.sum()
    page.screenshot(path=str(tmp_path / "framed.png"))
    assert errors == []


@pytest.mark.browser
@pytest.mark.slow
def test_selecting_a_clearance_frames_its_witness(checked, browser_page, tmp_path):
    page, errors = browser_page
    result, _ = checked
    path = tmp_path / "report.html"
    path.write_text(render(checked), encoding="utf-8")
    open_report(page, path)
    near = next(f for f in result.findings if f.b == "near.stl")
    page.locator(f"#findings tbody tr[data-id='{near.id}']").click()
    data, _ = embedded(path.read_text(encoding="utf-8"))
    line = np.asarray(next(f for f in data["findings"] if f["id"] == near.id)["line"])
    ends = project(page, line)
    assert np.all(np.abs(ends.mean(axis=0)[:2]) < 0.1)
    assert label_lines(page) == [
        f"clearance \u00b7 {length(near.distance, resolution(result))} mm apart",
        "base.stl",
        "near.stl",
    ]
    # The witness segment between the closest points is drawn in the strong magenta.
    pixels = canvas_pixels(page)
    rows, cols = pixel_box(ends, pixels.shape, margin=8)
    assert strong(pixels, "magenta")[rows, cols].sum() > 20
    assert errors == []


@pytest.mark.browser
@pytest.mark.slow
def test_label_keeps_hostile_names_as_text(checked, browser_page, tmp_path):
    page, errors = browser_page
    result, _ = checked
    path = tmp_path / "report.html"
    path.write_text(render(checked), encoding="utf-8")
    open_report(page, path)
    hostile = next(f for f in result.findings if f.b == HOSTILE)
    page.locator(f"#findings tbody tr[data-id='{hostile.id}']").click()
    lines = label_lines(page)
    assert lines[0] == (
        f"interference \u00b7 {length(hostile.depth, resolution(result))} mm deep \u00b7 "
        f"{volume(hostile.volume)} mm\u00b3 \u00b7 approved"
    )
    assert lines[1:] == ["base.stl", printable(HOSTILE)]
    # Only the label's own elements: the pin, the leader, the card and its three lines.
    tags = page.evaluate("[...document.querySelectorAll('#clash-label *')].map(e => e.tagName)")
    assert sorted(tags) == ["DIV", "DIV", "DIV", "DIV", "SPAN", "SPAN"]
    assert page.locator("img").count() == 0
    assert page.evaluate("window.__pwned") is None
    assert errors == []


PEG3 = 'peg3<img src=x onerror="window.__pwned=3">\u202e.stl'  # a hostile name in a group


def grouped_assembly() -> list[Body]:
    """A plate with three pegs sunk into it (one clash group on the plate) and a loose block."""
    return [
        box("plate.stl", [0, 0, 0], [30, 10, 2]),
        box("peg1.stl", [2, 2, 1.5], [4, 4, 5]),
        box("peg2.stl", [12, 2, 1.0], [14, 4, 5]),
        box(PEG3, [22, 2, 1.8], [24, 4, 5]),
        box("block.stl", [0, 20, 0], [5, 25, 5]),
    ]


@pytest.mark.browser
@pytest.mark.slow
def test_clash_groups_are_listed_and_framed(browser_page, tmp_path):
    page, errors = browser_page
    bodies = grouped_assembly()
    result = check_bodies(bodies, jobs=1)
    path = tmp_path / "groups.html"
    path.write_text(render_html(result, bodies, version="0.1.0"), encoding="utf-8")
    open_report(page, path)
    data, buffer = embedded(path.read_text(encoding="utf-8"))
    (group,) = data["groups"]
    assert group["part"] == "plate.stl" and len(group["findings"]) == 3
    # On load: the deepest interference (peg2, 1 deep), not the first by name (peg1, 0.5 deep).
    peg2 = next(f for f in data["findings"] if f["a"] == "peg2.stl")
    assert page.locator("#findings tbody tr.selected").get_attribute("data-id") == peg2["id"]
    target = np.array(page.evaluate("window.meshcheckView.controls.target.toArray()"))
    np.testing.assert_allclose(target, solid_box(data, buffer, peg2).mean(axis=0), atol=1e-3)

    node = page.locator(f"#groups .group[data-id='{group['id']}']")
    head = node.locator(".group-head").inner_text()
    assert group["id"] in head and "plate.stl" in head and "3 findings" in head
    members = node.locator("li")
    assert [members.nth(k).get_attribute("data-id") for k in range(3)] == group["findings"]
    assert [members.nth(k).locator(".part").inner_text() for k in range(3)] == [
        "peg2.stl",  # deepest first
        "peg1.stl",
        printable(PEG3),
    ]
    # The group's line frames all its clashes at once, and marks its rows.
    node.locator(".group-head").click()
    boxes = [solid_box(data, buffer, f) for f in data["findings"]]
    union = np.array([np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)])
    target = np.array(page.evaluate("window.meshcheckView.controls.target.toArray()"))
    np.testing.assert_allclose(target, union.mean(axis=0), atol=1e-3)
    assert np.abs(project(page, corners(*union))[:, :2]).max() < 1
    selected = page.locator("#findings tbody tr.selected")
    assert sorted(selected.nth(k).get_attribute("data-id") for k in range(3)) == sorted(
        group["findings"]
    )
    assert label_lines(page)[0] == f"3 interference \u00b7 group {group['id']}"
    # A member frames that finding alone.
    members.nth(2).click()
    peg3 = next(f for f in data["findings"] if f["a"] == PEG3)
    target = np.array(page.evaluate("window.meshcheckView.controls.target.toArray()"))
    np.testing.assert_allclose(target, solid_box(data, buffer, peg3).mean(axis=0), atol=1e-3)
    assert page.locator("#findings tbody tr.selected").get_attribute("data-id") == peg3["id"]
    assert label_lines(page)[1:] == [printable(PEG3), "plate.stl"]
    assert page.locator("img").count() == 0
    assert page.evaluate("window.__pwned") is None
    assert errors == []


@pytest.mark.browser
@pytest.mark.slow
def test_pattern_group_names_both_parts_of_each_copy(browser_page, tmp_path):
    """Two brackets each clipped by their peg the same way: one pattern group (no shared part);
    the list and the label name both parts of each copy, the line frames both clashes."""
    page, errors = browser_page
    bodies = [
        box("bracket_a.stl", [0, 0, 0], [10, 10, 2]),
        box("peg_a.stl", [2, 2, 1.5], [4, 4, 5]),
        box("bracket_b.stl", [40, 0, 0], [50, 10, 2]),
        box(PEG3, [42, 2, 1.5], [44, 4, 5]),
    ]
    result = check_bodies(bodies, jobs=1)
    path = tmp_path / "pattern.html"
    path.write_text(render_html(result, bodies, version="0.1.0"), encoding="utf-8")
    open_report(page, path)
    data, buffer = embedded(path.read_text(encoding="utf-8"))
    (group,) = data["groups"]
    assert group["kind"] == "pattern" and group["part"] is None
    node = page.locator(f"#groups .group[data-id='{group['id']}']")
    head = node.locator(".group-head").inner_text()
    assert group["id"] in head and "pattern" in head and "2 findings" in head
    members = node.locator("li .part").all_text_contents()
    by_id = {f["id"]: f for f in data["findings"]}
    assert members == [
        f"{printable(by_id[i]['a'])} \u00b7 {printable(by_id[i]['b'])}" for i in group["findings"]
    ]
    node.locator(".group-head").click()
    boxes = [solid_box(data, buffer, f) for f in data["findings"]]
    union = np.array([np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)])
    target = np.array(page.evaluate("window.meshcheckView.controls.target.toArray()"))
    np.testing.assert_allclose(target, union.mean(axis=0), atol=1e-3)
    assert label_lines(page)[0] == f"2 interference \u00b7 pattern group {group['id']}"
    assert page.locator("img").count() == 0
    assert page.evaluate("window.__pwned") is None
    assert errors == []


@pytest.mark.browser
@pytest.mark.slow
def test_a_mesh_placed_many_times_is_drawn_as_instances(browser_page, tmp_path):
    """Twenty plates and their sunk pegs: two instanced meshes, not forty objects; selecting a
    finding draws its two parts as tinted meshes of their own and hides their instances."""
    page, errors = browser_page
    plate = trimesh.creation.box(extents=(10.0, 10.0, 2.0)).apply_translation((5, 5, 1))
    peg = trimesh.creation.box(extents=(2.0, 2.0, 3.5)).apply_translation((3, 3, 3.25))
    bodies = []
    for k in range(20):
        at = np.eye(4)
        at[:3, 3] = (20.0 * (k % 5), 20.0 * (k // 5), 0.0)
        bodies += [Body(f"plate{k:02d}.stl", "", plate, at), Body(f"peg{k:02d}.stl", "", peg, at)]
    result = check_bodies(bodies, jobs=1)
    assert len(result.findings) == 20
    path = tmp_path / "instances.html"
    path.write_text(render_html(result, bodies, version="0.1.0"), encoding="utf-8")
    open_report(page, path)
    seen = """() => {
        const scene = window.meshcheckView.scene;
        const sets = scene.children.filter((o) => o.isInstancedMesh);
        const hidden = sets.map((s) => [...Array(s.count).keys()].filter(
            (i) => s.instanceMatrix.array[16 * i] === 0).length);
        const tinted = scene.children.filter(
            (o) => o.isMesh && !o.isInstancedMesh && sets.some((s) => s.geometry === o.geometry));
        return { sets: sets.map((s) => s.count), hidden,
                 tinted: tinted.map((o) => o.matrix.elements.slice(12, 14)) };
    }"""

    def selected_module() -> np.ndarray:
        row = page.locator("#findings tbody tr.selected").get_attribute("data-id")
        finding = next(f for f in result.findings if f.id == row)
        return next(b for b in bodies if b.name == finding.a).transform[:2, 3]

    on_load, first = page.evaluate(seen), selected_module()
    assert sorted(on_load["sets"]) == [20, 20]  # forty parts, two objects
    assert on_load["hidden"] == [1, 1] and len(on_load["tinted"]) == 2  # the worst finding's
    page.locator("#findings tbody tr").nth(7).click()
    after, second = page.evaluate(seen), selected_module()
    assert not np.allclose(first, second)
    assert after["hidden"] == [1, 1] and len(after["tinted"]) == 2  # the first back in its set
    for before, now in zip(on_load["tinted"], after["tinted"], strict=True):
        np.testing.assert_allclose(np.subtract(now, before), second - first, atol=1e-6)
    assert errors == []


# Runs in its own process: one process drives one Playwright at a time, and the module's
# browser (with WebGL) is open while these tests run.
WITHOUT_WEBGL_PROBE = """
import json, sys
sys.path.insert(0, sys.argv[1])
from chromium import WITHOUT_WEBGL, chromium_page

with chromium_page(flags=WITHOUT_WEBGL, timeout=30) as (page, errors):
    page.goto(sys.argv[2])
    page.wait_for_function("document.body.dataset.ready")
    seen = page.evaluate(\"\"\"() => ({
        ready: document.body.dataset.ready,
        webgl2: Boolean(document.createElement("canvas").getContext("webgl2")),
        message: document.querySelector("#view .no-view")?.textContent ?? null,
        canvases: document.querySelectorAll("#view canvas").length,
        view: window.meshcheckView,
        rows: [...document.querySelectorAll("#findings tbody tr")].map((r) => r.dataset.id),
        selected: document.querySelector("#findings tbody tr.selected")?.dataset.id ?? null,
    })\"\"\")
    seen["message_visible"] = page.locator("#view .no-view").is_visible()
    seen["home_visible"] = page.locator("#home").is_visible()
    page.locator("#findings tbody tr").nth(2).click()  # selecting still works
    seen["clicked"] = page.locator("#findings tbody tr.selected").get_attribute("data-id")
    seen["errors"] = errors
print(json.dumps(seen))
"""


@pytest.mark.browser
@pytest.mark.slow
def test_report_without_webgl_says_so_and_lists_the_findings(checked, browser_page, tmp_path):
    """Chromium with its 3D APIs off: a sentence where the view was, and the whole table."""
    import subprocess

    result, _ = checked
    path = tmp_path / "report.html"
    path.write_text(render(checked), encoding="utf-8")
    scripts = os.path.join(os.path.dirname(os.path.dirname(__file__)), "scripts")
    run = subprocess.run(
        [sys.executable, "-c", WITHOUT_WEBGL_PROBE, scripts, path.as_uri()],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    seen = json.loads(run.stdout)
    assert seen["ready"] == "true"
    assert seen["webgl2"] is False
    assert seen["message"].startswith("WebGL is unavailable in this browser")
    assert seen["message_visible"] and not seen["home_visible"]
    assert seen["canvases"] == 0 and seen["view"] is None
    ordered_ids = [f.id for f in ordered(result)]
    assert seen["rows"] == ordered_ids  # the findings, all of them, most severe first
    worst = next(f for f in ordered(result) if result.is_failing(f))
    assert seen["selected"] == worst.id
    assert seen["clicked"] == ordered_ids[2]
    assert seen["errors"] == []


@pytest.mark.browser
@pytest.mark.slow
def test_report_without_findings_in_chromium(browser_page, tmp_path):
    page, errors = browser_page
    bodies = [box("a.stl", [0, 0, 0], [1, 1, 1]), box("b.stl", [3, 0, 0], [4, 1, 1])]
    result = check_bodies(bodies, jobs=1)
    path = tmp_path / "clear.html"
    path.write_text(render_html(result, bodies, version="0.1.0"), encoding="utf-8")
    open_report(page, path)
    assert page.locator("#verdict").inner_text() == "PASS"
    assert "No findings" in page.locator("#findings tbody").inner_text()
    assert pixel_spread(page.locator("#view canvas").screenshot()) > 5
    assert not page.locator(
        "#clash-label .card"
    ).is_visible()  # nothing to frame: the whole assembly
    assert errors == []


@pytest.mark.browser
def test_a_mechanism_colliding_in_motion_is_listed_and_fails(browser_page, tmp_path):
    """--sweep of a door that hits its stop within its range: the page says FAIL with no
    finding at the pose, counts the pair as colliding in motion, and lists it open, failing
    first, with its witness pose; the door meeting its frame is listed as adjacent, approved."""
    from click.testing import CliRunner

    from meshcheck.cli import main

    page, errors = browser_page
    trimesh.creation.box(bounds=[(0, -50, -100), (1000, 50, 100)]).export(tmp_path / "door.stl")
    trimesh.creation.box(bounds=[(500, 300, -100), (800, 500, 100)]).export(tmp_path / "stop.stl")
    trimesh.creation.box(bounds=[(-85, -25, -100), (-35, 25, 100)]).export(tmp_path / "frame.stl")
    (tmp_path / "meshcheck.toml").write_text(
        '[[joint]]\nname = "hinge"\nparent = "frame.stl"\nchild = "door.stl"\n'
        'type = "revolute"\naxis = [0, 0, 1]\norigin = [0, 0, 0]\nrange = ["-30deg", "90deg"]\n'
    )
    files = [str(tmp_path / n) for n in ("door.stl", "stop.stl", "frame.stl")]
    path = tmp_path / "door.html"
    out = CliRunner().invoke(
        main,
        [*files, "--config", str(tmp_path / "meshcheck.toml"), "--no-cache", "-j", "1",
         "--sweep", "--format", "html", "--output", str(path)],
    )  # fmt: skip
    assert out.exit_code == 1, out.output
    open_report(page, path)
    assert page.locator("#verdict").inner_text() == "FAIL"
    assert "1 colliding in motion" in page.locator("#counts").inner_text()
    items = page.locator("#sweeps li").all_inner_texts()
    assert page.locator("#sweeps").get_attribute("open") is not None
    assert items[0].startswith("FAIL sometimes: ") and "stop.stl" in items[0]
    assert "interference at --pose hinge=" in items[0]
    assert any("(adjacent)" in t and "(approved: adjacent)" in t for t in items[1:])
    assert errors == []
