"""Make the manual's screenshot of the sample assembly's HTML report: docs/report.png.

Run from anywhere (needs the dev extra and Debian's chromium)::

    python scripts/report_screenshot.py [--out docs/report.png] [--html report.html]

It checks ``sample_meshes/*.stl`` as README's first command does, renders the HTML report, opens
it in headless Chromium at 1280x720 as it is on load (framing the failing clash, labelled), and
saves a palette PNG (kept under 300 KB for the repository).
"""

from __future__ import annotations

import argparse
import glob
import io
import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

from chromium import chromium_page  # noqa: E402

LIMIT = 300_000  # bytes


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(ROOT, "docs", "report.png"))
    parser.add_argument("--html", help="also keep the HTML report here")
    args = parser.parse_args(argv)

    from importlib.metadata import version

    from PIL import Image

    import meshcheck
    from meshcheck.load import load_bodies
    from meshcheck.outcome import exit_status
    from meshcheck.pipeline import check
    from meshcheck.reports.html import render_html

    os.chdir(ROOT)  # part names as the manual shows them: sample_meshes/...
    paths = sorted(glob.glob("sample_meshes/*.stl"))
    result = check(paths, jobs=1)
    text = render_html(
        result, load_bodies(paths), inputs=paths, version=version(meshcheck.DISTRIBUTION)
    )
    with tempfile.TemporaryDirectory() as tmp:
        page_path = os.path.join(tmp, "report.html")
        with open(page_path, "w", encoding="utf-8") as f:
            f.write(text)
        if args.html:
            with open(args.html, "w", encoding="utf-8") as f:
                f.write(text)
        with chromium_page(width=1280, height=720, timeout=60) as (page, errors):
            page.goto("file://" + page_path)
            page.wait_for_function("document.body.dataset.ready")
            if page.locator("#findings tbody tr.fails.selected").count() != 1:
                raise SystemExit("error: the report did not select the failing finding on load")
            page.wait_for_timeout(300)
            png = page.screenshot()
            if errors:
                raise SystemExit("error: the report logged errors: " + "; ".join(errors))

    image = Image.open(io.BytesIO(png)).convert("RGB")
    out = io.BytesIO()
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, "PNG", optimize=True)
    if out.tell() > LIMIT:
        raise SystemExit(f"error: {args.out}: {out.tell()} bytes, over {LIMIT}")
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "wb") as f:
        f.write(out.getvalue())
    print(
        f"{args.out}: {out.tell()} bytes, {image.width}x{image.height}; "
        f"sample exit status {int(exit_status(result))}"
    )


if __name__ == "__main__":
    main()
