"""The manual cannot drift from the code: every example in README.md and docs/ runs here.

Each page's fenced blocks run in order in a folder of their own holding a copy of
``sample_meshes/``, with a fresh cache shared by the pages:

- ``sh``: every command runs in bash and must exit 0, or the status its ``# exit N`` comment
  names (one logical line per command; ``\\`` continues a line);
- ``console``: each ``$ command`` runs the same way and its standard output must be the lines
  below it (a line ``...`` stands for any number of lines);
- ``toml``: written to the file its first line names (``# meshcheck.toml``, ``# pyproject.toml``),
  read by meshcheck's configuration loader, and exercised by a later command on the page;
- ``python``: runs in a fresh interpreter and must exit 0;
- ``yaml``: a workflow using the action must give only inputs ``action.yml`` declares; a
  pre-commit configuration must name the repository's hook with its file filter;
- other blocks (``text``, ``json``...) are output shown, not run.

Not run, each for the reason given: ``NOT_RUN`` (installs from PyPI, long-running servers, and
README's two commands, which ``.ci/run`` runs as they are written, checked below), and the
benchmark commands of the Benchmarks page (``python bench/...``: minutes each; their script and
options are checked to exist).
"""

from __future__ import annotations

import ast
import glob
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import pytest
import yaml

from meshcheck.config import load_config

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGES = sorted(
    os.path.relpath(p, ROOT)
    for p in [
        os.path.join(ROOT, "README.md"),
        *glob.glob(os.path.join(ROOT, "docs", "**", "*.md"), recursive=True),
    ]
)
#: The tests that read the manual's sources, .ci/run or mkdocs.yml need the checkout (a wheel's
#: test run gets a copy of the files [tool.cibuildwheel] test-sources names).
needs_checkout = pytest.mark.skipif(
    not os.path.isfile(os.path.join(ROOT, "mkdocs.yml")),
    reason="the manual is not beside the tests (a copy of [tool.cibuildwheel] test-sources)",
)
#: Seconds one command may take (the robots' sweeps are the longest, a few seconds).
TIMEOUT = 120

#: Commands shown but not run here, and why.
NOT_RUN = {
    "pip install meshcheck-assembly": "installs from PyPI",
    'pip install "meshcheck-assembly[dask]"': "installs from PyPI",
    "python3 -m venv .venv && . .venv/bin/activate && pip install . && meshcheck "
    "sample_meshes/*.stl": "README's first command: .ci/run runs it as written (tested below)",
    '. .venv/bin/activate && pip install -e ".[dev]" && python -m pytest': "README's test "
    "command: .ci/run runs it as written (tested below)",
    '. .venv/bin/activate && pip install -e ".[docs]" && mkdocs build --strict': ".ci/run "
    "builds the manual as written (tested below)",
    "dask scheduler --port 8786": "a server that runs until stopped",
    "OMP_NUM_THREADS=1 dask worker tcp://SCHEDULER:8786 --nthreads 2": "a server, on a cluster",
    "meshcheck --scheduler tcp://SCHEDULER:8786 sample_meshes/ --cache-dir .meshcheck-cache": (
        "needs the cluster above (tests/test_dask.py runs the same on a local one)"
    ),
}


@dataclass
class Block:
    page: str
    line: int
    lang: str
    text: str


def blocks(page: str) -> list[Block]:
    """The fenced code blocks of a page, in order (indented ones, in lists, too)."""
    out, current, fence = [], None, None
    with open(os.path.join(ROOT, page), encoding="utf-8") as fh:
        for number, raw in enumerate(fh, 1):
            stripped = raw.strip()
            if current is None:
                match = re.match(r"^(\s*)(```+)\s*([\w-]*)", raw)
                if match:
                    indent, fence = len(match.group(1)), match.group(2)
                    current = Block(page, number, match.group(3), "")
                continue
            if stripped == fence:
                out.append(current)
                current = None
                continue
            current.text += raw[indent:] if raw[:indent].strip() == "" else raw
    assert current is None, f"{page}: a code block opened at line {current.line} never closes"
    return out


def commands(text: str) -> list[tuple[str, int]]:
    """A ``sh`` block's commands (continuations joined, comments dropped) and the exit status
    each expects (``# exit N``, else 0)."""
    out, pending = [], ""
    for line in text.splitlines():
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        line, pending = pending + line, ""
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        status = re.search(r"#\s*exit (\d+)\b", line)
        out.append((strip_comment(line), int(status.group(1)) if status else 0))
    return out


def strip_comment(line: str) -> str:
    """``line`` without a trailing shell comment (`` #`` outside quotes)."""
    cut = line.find(" #")
    while cut >= 0:
        head = line[:cut]
        if head.count('"') % 2 == 0 and head.count("'") % 2 == 0:
            return head.strip()
        cut = line.find(" #", cut + 1)
    return line.strip()


def environment(cache: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MESHCHECK_", "COLUMNS"))}
    env.update(
        PATH=os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", ""),
        XDG_CACHE_HOME=os.path.join(cache, "cache"),
        XDG_STATE_HOME=os.path.join(cache, "state"),
        MESHCHECK_CACHE_SECRET="documentation examples",
    )
    return env


def run(command: str, where: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["bash", "-c", command],
        cwd=where,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        stdin=subprocess.DEVNULL,
    )


def matches(expected: list[str], got: list[str]) -> bool:
    """``got`` equals ``expected``, where an expected line ``...`` stands for any lines and
    ``...`` inside a line for any text."""
    if not expected:
        return not got
    if expected[0] == "...":
        return any(matches(expected[1:], got[k:]) for k in range(len(got) + 1))
    pattern = ".*".join(re.escape(part) for part in expected[0].split("..."))
    return (
        bool(got) and re.fullmatch(pattern, got[0]) is not None and matches(expected[1:], got[1:])
    )


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory) -> dict[str, str | None]:
    """Each page's examples run, two pages at a time (the commands are single processes, the
    machine has two cores): page -> None, or what went wrong."""
    cache = str(tmp_path_factory.mktemp("docs-cache"))

    def outcome(page: str) -> str | None:
        where = str(tmp_path_factory.mktemp("page"))
        try:
            run_page(page, where, cache)
        except AssertionError as exc:
            return str(exc)
        return None

    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(zip(PAGES, pool.map(outcome, PAGES), strict=True))


@pytest.mark.parametrize("page", PAGES)
def test_every_example_of_the_page_runs(page, outcomes):
    assert outcomes[page] is None, outcomes[page]


def run_page(page: str, where: str, cache: str) -> None:
    """Run the page's blocks in order in ``where`` (see the module's docstring)."""
    shutil.copytree(os.path.join(ROOT, "sample_meshes"), os.path.join(where, "sample_meshes"))
    env = environment(cache)
    unused_config = None
    for block in blocks(page):
        at = f"{block.page}:{block.line}"
        if block.lang == "sh":
            for command, status in commands(block.text):
                if command in NOT_RUN or command.startswith("python bench/"):
                    continue
                done = run(command, where, env)
                assert done.returncode == status, f"{at}: {command}\n{done.stdout}{done.stderr}"
                assert "Traceback" not in done.stderr, f"{at}: {command}\n{done.stderr}"
                unused_config = None
        elif block.lang == "console":
            for command, status, expected in console(block.text):
                if command.startswith("python bench/"):
                    continue
                done = run(command, where, env)
                assert done.returncode == status, f"{at}: {command}\n{done.stdout}{done.stderr}"
                got = done.stdout.splitlines()
                assert matches(expected, got), f"{at}: {command}\n" + "\n".join(got)
                unused_config = None
        elif block.lang == "toml":
            assert unused_config is None, f"{unused_config}: no command runs with this config"
            first = block.text.splitlines()[0]
            name = re.fullmatch(r"#\s*(meshcheck\.toml|pyproject\.toml)\b.*", first)
            assert name, f"{at}: a config snippet's first line names its file: # meshcheck.toml"
            path = os.path.join(where, name.group(1))
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(block.text)
            load_config(path)  # the schema: keys, types, ranges
            unused_config = at
        elif block.lang == "python":
            done = subprocess.run(
                [sys.executable, "-c", block.text],
                cwd=where,
                env=env,
                capture_output=True,
                text=True,
                timeout=TIMEOUT,
            )
            assert done.returncode == 0, f"{at}\n{done.stdout}{done.stderr}"
        elif block.lang == "yaml":
            check_yaml(block)
    assert unused_config is None, f"{unused_config}: no command runs with this config"


def console(text: str) -> list[tuple[str, int, list[str]]]:
    """A ``console`` block's commands (``$ ...``), the status each expects, and its output."""
    out = []
    for line in text.splitlines():
        if line.startswith("$ "):
            status = re.search(r"#\s*exit (\d+)\b", line)
            out.append((strip_comment(line[2:]), int(status.group(1)) if status else 0, []))
        else:
            assert out, f"output before any command: {line!r}"
            out[-1][2].append(line)
    return out


def check_yaml(block: Block) -> None:
    """A workflow step using the action gives declared inputs only; a pre-commit config names
    the repository's hook with the same file filter."""
    at = f"{block.page}:{block.line}"
    doc = yaml.safe_load(block.text)
    with open(os.path.join(ROOT, "action.yml"), encoding="utf-8") as fh:
        inputs = set(yaml.safe_load(fh)["inputs"])
    with open(os.path.join(ROOT, ".pre-commit-hooks.yaml"), encoding="utf-8") as fh:
        (hook,) = yaml.safe_load(fh)
    steps = doc if isinstance(doc, list) else []
    if isinstance(doc, dict) and "jobs" in doc:
        steps = [s for job in doc["jobs"].values() for s in job.get("steps", [])]
    for step in steps:
        if "meshcheck@" in str(step.get("uses", "")):
            assert set(step.get("with", {})) <= inputs, f"{at}: {step['with']} vs {inputs}"
    if isinstance(doc, dict) and "repos" in doc:
        for repo in doc["repos"]:
            for entry in repo["hooks"]:
                assert entry["id"] == hook["id"], at
                if repo["repo"] == "local":
                    assert entry["files"] == hook["files"], f"{at}: the hook's file filter"
                    assert entry["entry"] == hook["entry"], at


@needs_checkout
def test_readme_and_ci_agree():
    """.ci/run installs exactly as README says, runs README's test command and builds the
    manual as README says: each step of each of those commands is in .ci/run."""
    readme = [c for b in blocks("README.md") if b.lang == "sh" for c, _ in commands(b.text)]
    install, test = readme[0], readme[1]
    docs = next(c for c in readme if "mkdocs build --strict" in c)
    with open(os.path.join(ROOT, ".ci", "run"), encoding="utf-8") as fh:
        script = fh.read()
    for command in (install, test, docs):
        for step in command.split(" && "):  # each step a whole command of the script
            whole = rf"(^|&&)\s*{re.escape(step)}\s*($|&&|\|\|)"
            assert re.search(whole, script, re.M), (step, script)


@needs_checkout
def test_not_run_is_kept_short_and_current():
    shown = set()
    for page in PAGES:
        for block in blocks(page):
            if block.lang == "sh":
                shown.update(c for c, _ in commands(block.text))
    assert set(NOT_RUN) <= shown, set(NOT_RUN) - shown  # no stale entry
    assert len(NOT_RUN) <= 10


@needs_checkout
def test_benchmark_commands_name_real_scripts_and_options():
    page = "docs/internals/benchmarks.md"
    found = [
        c
        for b in blocks(page)
        if b.lang in ("sh", "console")
        for c in (
            [x for x, _ in commands(b.text)]
            if b.lang == "sh"
            else [x for x, _, _ in console(b.text)]
        )
        if c.startswith("python bench/")
    ]
    assert len(found) >= 8
    for command in found:
        words = shlex.split(command)
        script = os.path.join(ROOT, words[1])
        assert os.path.isfile(script), command
        with open(script, encoding="utf-8") as fh:
            source = fh.read()
        ast.parse(source)
        for word in words[2:]:
            if word.startswith("--"):
                assert f'"{word}"' in source, f"{command}: {word} is not an option of {words[1]}"


@needs_checkout
def test_the_manual_links_resolve_and_every_page_is_in_the_nav():
    with open(os.path.join(ROOT, "mkdocs.yml"), encoding="utf-8") as fh:
        nav = yaml.safe_load(fh)["nav"]

    def pages(entry):
        if isinstance(entry, str):
            yield entry
        elif isinstance(entry, list):
            for e in entry:
                yield from pages(e)
        else:
            for value in entry.values():
                yield from pages(value)

    listed = set(pages(nav))
    on_disk = {
        os.path.relpath(p, os.path.join(ROOT, "docs"))
        for p in glob.glob(os.path.join(ROOT, "docs", "**", "*.md"), recursive=True)
    }
    assert listed == on_disk


def test_pyproject_has_the_docs_extra():
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as fh:
        extra = tomllib.load(fh)["project"]["optional-dependencies"]["docs"]
    names = {re.split(r"[<>=\[]", req)[0] for req in extra}
    assert {"mkdocs-material", "mkdocstrings-python"} <= names
    assert all(">=" in req for req in extra)
