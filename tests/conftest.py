"""Test-wide isolation (the pair cache's signing key lives in a throwaway state directory, never
in the user's own, and no Dask scheduler from the environment applies), the count of pairs the
verify stage runs, and the browser the HTML report's tests open."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(autouse=True)
def _isolated_state(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.getbasetemp() / "state"))
    monkeypatch.delenv("MESHCHECK_CACHE_SECRET", raising=False)
    monkeypatch.delenv("MESHCHECK_SCHEDULER", raising=False)


@pytest.fixture
def counted(monkeypatch):
    """Count the verify_pair calls of this process (the real verify runs)."""
    from meshcheck.verify import batch

    calls = []
    real = batch.verify_pair

    def spy(a, b, **kw):
        calls.append(1)
        return real(a, b, **kw)

    monkeypatch.setattr(batch, "verify_pair", spy)
    return calls


@pytest.fixture(scope="module")
def browser_page():
    """A page of Debian's chromium driven by Playwright, and the console errors it logs."""
    from chromium import chromium_page, find_chromium  # playwright: the dev extra

    if find_chromium() is None:  # a system package: optional but in CI, which installs it
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed (.ci/run installs it)")
        pytest.skip("chromium is not installed (apt-get install chromium)")
    with chromium_page(width=1280, height=720, timeout=30) as (page, errors):
        yield page, errors
