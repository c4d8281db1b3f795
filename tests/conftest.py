"""Test-wide isolation: the pair cache's signing key lives in a throwaway state directory, never
in the user's own, and no Dask scheduler from the environment applies."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _isolated_state(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.getbasetemp() / "state"))
    monkeypatch.delenv("MESHCHECK_CACHE_SECRET", raising=False)
    monkeypatch.delenv("MESHCHECK_SCHEDULER", raising=False)
