"""The shell steps of meshcheck's GitHub Action (action.yml), as one script the tests can run.

Each step of action.yml calls one subcommand; everything comes in through environment variables
(the action's inputs and GitHub's own), so the steps hold no logic and no quoting hazards::

    python scripts/action/meshcheck_action.py install | key | check | summary | fail

Run locally with the variables GitHub sets (``GITHUB_OUTPUT``, ``GITHUB_STEP_SUMMARY``,
``RUNNER_OS``...) pointing at ordinary files: ``tests/test_action.py`` does. Only the standard
library: it runs before anything is installed.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

DISTRIBUTION = "meshcheck-assembly"
# The reports every run writes into the report directory, by meshcheck's report format.
REPORTS = {
    "json": "meshcheck.json",
    "junit": "meshcheck.xml",
    "sarif": "meshcheck.sarif",
    "markdown": "summary.md",
    "html": "meshcheck.html",
}
EXPORT = "meshcheck.glb"  # the assembly with the clashes marked, for a glTF viewer
CONFIG_FILES = ("meshcheck.toml", "pyproject.toml")  # read from the working directory


def env(name: str, default: str = "") -> str:
    """An input or GitHub variable; empty when unset."""
    return os.environ.get(name, default)


def set_output(name: str, value: str) -> None:
    """Set a step output (appended to ``$GITHUB_OUTPUT``)."""
    with open(env("GITHUB_OUTPUT", os.devnull), "a", encoding="utf-8") as f:
        f.write(f"{name}={value}\n")


def add_summary(markdown: str) -> None:
    """Append to the job summary (``$GITHUB_STEP_SUMMARY``)."""
    with open(env("GITHUB_STEP_SUMMARY", os.devnull), "a", encoding="utf-8") as f:
        f.write(markdown)


def annotate(kind: str, message: str) -> None:
    """A ``::notice`` or ``::warning`` workflow command, one line."""
    print(f"::{kind} title=meshcheck::{' '.join(message.split())}", flush=True)


def input_paths(files: str) -> list[str]:
    """The ``files`` input: one path per line (paths may contain spaces).

    A single line that is not an existing path is split on whitespace, as the action's first
    version did (``files: plate.stl bolts/``).
    """
    lines = [line.strip() for line in files.splitlines() if line.strip()]
    if len(lines) == 1 and not os.path.exists(lines[0]):
        return lines[0].split()
    return lines


def is_fork_pull_request() -> bool:
    """Whether this run is for a pull request from a fork: no secrets, read-only token."""
    return env("FORK_PULL_REQUEST") == "true"


# -------------------------------------------------------------------------------------------
# install


def install_commands(package: str, action_path: str, action_ref: str) -> list[list[str]]:
    """The pip commands to try in turn: the first that succeeds installs meshcheck.

    ``package`` set: exactly that. Else, when the action is used at its release tag
    (``v`` + the version in its pyproject.toml), the published wheel of that version (no
    compiler), falling back to the action's own checkout; any other ref (a branch, a commit,
    ``./``) installs the checkout, so the code run is the code at that ref.
    """
    pip = [sys.executable, "-m", "pip", "install", "--quiet"]
    if package:
        return [[*pip, package]]
    source = [*pip, action_path]
    with open(os.path.join(action_path, "pyproject.toml"), "rb") as f:
        version = tomllib.load(f)["project"]["version"]
    if action_ref == f"v{version}":
        return [[*pip, "--only-binary", DISTRIBUTION, f"{DISTRIBUTION}=={version}"], source]
    return [source]


def install() -> int:
    # github.action_ref, handed in by action.yml; GitHub also sets GITHUB_ACTION_REF.
    ref = env("ACTION_REF") or env("GITHUB_ACTION_REF")
    commands = install_commands(env("PACKAGE"), env("GITHUB_ACTION_PATH"), ref)
    for i, command in enumerate(commands):
        if subprocess.run(command).returncode == 0:
            return 0
        if i + 1 < len(commands):
            annotate("notice", "no published wheel for this platform: building from source")
    return 1


# -------------------------------------------------------------------------------------------
# cache key


def content_digest(paths: list[str]) -> str:
    """SHA-256 over every file below the inputs and the configuration files: names and bytes."""
    h = hashlib.sha256()
    for path in [*paths, *(name for name in CONFIG_FILES if os.path.isfile(name))]:
        found = (
            [path]
            if not os.path.isdir(path)
            else sorted(
                os.path.join(root, name) for root, _, names in os.walk(path) for name in names
            )
        )
        for name in found:
            h.update(name.encode() + b"\0")
            try:
                with open(name, "rb") as f:
                    h.update(hashlib.file_digest(f, "sha256").digest())
            except OSError:
                h.update(b"unreadable\0")  # meshcheck will say what is wrong with it
    return h.hexdigest()


def key() -> int:
    """Outputs ``key`` and ``prefix`` for actions/cache: the inputs' content, not the commit.

    The same inputs, arguments and meshcheck version give the same key, so an unchanged
    assembly restores its own entry and saves nothing new; restoring by ``prefix`` (the newest
    entry of this use of the action) gives a changed assembly the entries of its unchanged parts.
    """
    version = subprocess.run(
        ["meshcheck", "--version"], capture_output=True, text=True, check=True
    ).stdout.strip()
    h = hashlib.sha256()
    for part in (version, env("ARGS"), str(bool(env("MESHCHECK_CACHE_SECRET")))):
        h.update(part.encode() + b"\0")
    h.update(content_digest(input_paths(env("FILES"))).encode())
    prefix = f"meshcheck-{env('RUNNER_OS', sys.platform)}-{env('ARTIFACT_NAME')}-"
    set_output("prefix", prefix)
    set_output("key", prefix + h.hexdigest()[:32])
    return 0


# -------------------------------------------------------------------------------------------
# pruning: keep only the cache entries this run read or wrote


def atime_works(directory: str) -> bool:
    """Whether reading a file here updates its access time (relatime does, noatime does not)."""
    os.makedirs(directory, exist_ok=True)
    fd, probe = tempfile.mkstemp(dir=directory, prefix=".atime-probe-")
    try:
        os.write(fd, b"x")
        os.close(fd)
        os.utime(probe, (0, os.stat(probe).st_mtime))
        with open(probe, "rb") as f:
            f.read()
        return os.stat(probe).st_atime > 0
    finally:
        os.remove(probe)


def mark_unused(directory: str) -> bool:
    """Set every entry's access time to 1970, so the entries the run reads stand out after it.

    Returns False (and marks nothing) where reading does not update access times: nothing is
    pruned there.
    """
    if not os.path.isdir(directory) or not atime_works(directory):
        return False
    for root, _, names in os.walk(directory):
        for name in names:
            path = os.path.join(root, name)
            os.utime(path, (0, os.stat(path).st_mtime))
    return True


def prune_unused(directory: str) -> int:
    """Delete the entries still marked (not read or written since), then empty folders."""
    pruned = 0
    for root, dirs, names in os.walk(directory, topdown=False):
        for name in names:
            path = os.path.join(root, name)
            if os.stat(path).st_atime < 1:
                os.remove(path)
                pruned += 1
        for name in dirs:
            with_files = os.listdir(os.path.join(root, name))
            if not with_files:
                os.rmdir(os.path.join(root, name))
    return pruned


# -------------------------------------------------------------------------------------------
# check


def meshcheck_command(paths: list[str], report_dir: str, cache_dir: str) -> list[str]:
    """meshcheck with annotations on stdout and every report, the GLB export, the baseline."""
    command = ["meshcheck", *paths, *shlex.split(env("ARGS")), "--cache-dir", cache_dir]
    baseline = env("BASELINE")
    if baseline and os.path.isfile(baseline):
        command += ["--baseline", baseline]
    elif baseline:
        annotate("warning", f"no baseline at {baseline}: every finding is new")
    command += ["--format", "github"]
    for fmt, name in REPORTS.items():
        command += ["--report", f"{fmt}:{os.path.join(report_dir, name)}"]
    return [*command, "--export", os.path.join(report_dir, EXPORT)]


def check() -> int:
    """Run meshcheck; output its exit status; prune the cache when the check completed."""
    report_dir, cache_dir = env("REPORT_DIR", "meshcheck-reports"), env("CACHE_DIR")
    os.makedirs(report_dir, exist_ok=True)
    if not env("MESHCHECK_CACHE_SECRET"):
        why = " (a pull request from a fork gets no secrets)" if is_fork_pull_request() else ""
        annotate(
            "notice",
            f"MESHCHECK_CACHE_SECRET is not set{why}: cached pair verdicts "
            "are not reused, decompositions are",
        )
    marked = bool(cache_dir) and mark_unused(cache_dir)
    command = meshcheck_command(input_paths(env("FILES")), report_dir, cache_dir)
    status = subprocess.run(command).returncode
    set_output("exit-code", str(status))
    summary = os.path.join(report_dir, REPORTS["markdown"])
    if os.path.isfile(summary):
        add_summary(Path(summary).read_text(encoding="utf-8") + "\n")
    # Status 0 and 1 mean a completed check, which read every entry it needed; after any other
    # the entries were not all looked at, so none is pruned.
    if marked and status in (0, 1):
        print(f"meshcheck cache: pruned {prune_unused(cache_dir)} entries this run did not use")
    return 0


# -------------------------------------------------------------------------------------------
# summary and failure


def summary() -> int:
    """Link the uploaded reports from the job summary; say what a fork's run had to skip."""
    report_dir, url = env("REPORT_DIR", "meshcheck-reports"), env("ARTIFACT_URL")
    present = [
        n
        for n in (REPORTS["html"], EXPORT, *REPORTS.values())
        if os.path.isfile(os.path.join(report_dir, n))
    ]
    lines = []
    if url and present:
        names = ", ".join(dict.fromkeys(present))
        lines.append(
            f"Reports: [{env('ARTIFACT_NAME')}]({url}) ({names}). Open "
            f"`{REPORTS['html']}` in a browser for the 3D view of the clashes; "
            f"`{EXPORT}` opens in any glTF viewer."
        )
    elif present:
        lines.append(f"Reports in `{report_dir}` (the upload failed or was skipped).")
    if env("UPLOAD_SARIF") == "true" and is_fork_pull_request():
        lines.append(
            "SARIF not uploaded to code scanning: a pull request from a fork has no "
            "`security-events: write`; the findings are in the annotations and reports."
        )
    if lines:
        add_summary("\n".join(f"{line}\n" for line in lines))
    return 0


def fail() -> int:
    """Exit with meshcheck's status (4, a bug, when the check step left none)."""
    status = env("STATUS")
    if status != "0":
        print(f"meshcheck exited with status {status or 'unknown'}", file=sys.stderr)
    return int(status) if status.isdigit() else 4


def main(argv: list[str]) -> int:
    steps = {"install": install, "key": key, "check": check, "summary": summary, "fail": fail}
    if len(argv) != 2 or argv[1] not in steps:
        print(f"usage: {argv[0]} {'|'.join(steps)}", file=sys.stderr)
        return 2
    return steps[argv[1]]()


if __name__ == "__main__":
    sys.exit(main(sys.argv))
