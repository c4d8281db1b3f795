"""Open pages in the system's headless Chromium (Debian's ``chromium``), driven by Playwright.

Playwright's own browser download is never used: we start ``/usr/bin/chromium`` ourselves, with
flags that keep it off the network, read its DevTools port, and attach Playwright over CDP. Owning
the process lets the caller bound its lifetime and kill it by pid, whatever Playwright does.

Used by ``tests/test_html_report.py`` and ``scripts/report_screenshot.py``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterator

FLAGS = (
    "--headless",
    "--no-sandbox",  # we run as root in CI
    "--disable-gpu",
    "--enable-unsafe-swiftshader",  # WebGL in software, as there is no GPU
    "--use-angle=swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--remote-debugging-address=127.0.0.1",
    "--remote-debugging-port=0",
)

# No WebGL at all: the 3D APIs off, as on a machine whose GPU is blocklisted.
WITHOUT_WEBGL = ("--disable-3d-apis", "--disable-webgl", "--disable-webgl2")


def find_chromium() -> str | None:
    """Path of the system Chromium, or None."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    return None


@contextlib.contextmanager
def chromium_page(
    *, width: int = 1280, height: int = 720, timeout: float = 30.0, flags: tuple[str, ...] = ()
) -> Iterator[tuple[object, list[str]]]:
    """A Playwright page in a fresh headless Chromium, and the list its console errors go to.

    The browser runs with a new empty profile in a temporary directory and ``FLAGS`` plus
    ``flags`` (``WITHOUT_WEBGL`` to see a page as a browser without WebGL does); it is killed
    (by its process group) on exit, and any Playwright call waits at most ``timeout`` seconds.
    """
    from playwright.sync_api import sync_playwright

    executable = find_chromium()
    if executable is None:
        raise FileNotFoundError("chromium is not installed")
    profile = tempfile.mkdtemp(prefix="meshcheck-chromium-")
    proc = subprocess.Popen(
        [executable, *FLAGS, *flags, f"--user-data-dir={profile}", "about:blank"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: killing it takes the renderers too
    )
    try:
        port = _devtools_port(profile, proc, timeout)
        with sync_playwright() as p:
            browser = p.chromium.connect_over_cdp(
                f"http://127.0.0.1:{port}", timeout=timeout * 1000
            )
            context = browser.contexts[0] if browser.contexts else browser.new_context()
            page = context.new_page()
            page.set_default_timeout(timeout * 1000)
            page.set_viewport_size({"width": width, "height": height})
            errors: list[str] = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"uncaught: {e}"))
            try:
                yield page, errors
            finally:
                browser.close()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        shutil.rmtree(profile, ignore_errors=True)


def _devtools_port(profile: str, proc: subprocess.Popen, timeout: float) -> int:
    """The port Chromium writes to ``DevToolsActivePort`` in its profile once it listens."""
    path = os.path.join(profile, "DevToolsActivePort")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"chromium exited with status {proc.returncode}")
        with contextlib.suppress(FileNotFoundError, ValueError, IndexError):
            with open(path) as f:
                return int(f.read().split()[0])
        time.sleep(0.05)
    raise TimeoutError(f"chromium did not open its DevTools port within {timeout:g} s")
