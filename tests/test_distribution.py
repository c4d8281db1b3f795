"""meshcheck's distribution name (``meshcheck`` on PyPI is someone else's project) and build.

The command and the import are ``meshcheck``; pip installs ``meshcheck.DISTRIBUTION``. Every place
that names what to install, or reads the installed version, must use that name: a wrong one
installs the unrelated project, or reads its version.
"""

from __future__ import annotations

import ast
import importlib.metadata
import json
import re
import shlex
import subprocess
import sys
import sysconfig
import textwrap
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

import meshcheck
from meshcheck.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_pyproject_builds_the_distribution_the_code_names():
    with open(ROOT / "pyproject.toml", "rb") as f:
        project = tomllib.load(f)["project"]
    assert project["name"] == meshcheck.DISTRIBUTION == "meshcheck-assembly"
    assert project["scripts"] == {"meshcheck": "meshcheck.__main__:main"}


def test_version_is_read_under_the_distribution_name():
    version = importlib.metadata.version(meshcheck.DISTRIBUTION)
    result = CliRunner().invoke(main, ["--version"], prog_name="meshcheck")
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"meshcheck, version {version}"


def test_help_and_sarif_point_at_the_distribution():
    result = CliRunner().invoke(main, ["--help"], terminal_width=200)
    assert f'pip install "{meshcheck.DISTRIBUTION}[dask]"' in " ".join(result.output.split())
    samples = [str(ROOT / "sample_meshes" / n) for n in ("plate.stl", "bracket.stl")]
    result = CliRunner().invoke(main, [*samples, "--no-cache", "--no-config", "--format", "sarif"])
    driver = json.loads(result.stdout)["runs"][0]["tool"]["driver"]
    assert driver["informationUri"] == f"https://pypi.org/project/{meshcheck.DISTRIBUTION}/"


def test_readme_installs_the_distribution():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```(?:sh|yaml)\n(.*?)```", readme, flags=re.DOTALL)
    installs = [
        m[1].strip("\"'")
        for block in blocks
        for m in re.finditer(r"pip install (?:-\w+ )*(\S+)", block)
        if not m[1].startswith((".", '".')) and "meshcheck" in m[1]  # not a bench's extra tools
    ]
    assert installs and all(i.startswith(meshcheck.DISTRIBUTION) for i in installs), installs
    assert '"meshcheck[dask]"' not in readme


@pytest.mark.skipif(
    sys.platform == "win32" or sysconfig.get_config_var("Py_GIL_DISABLED"),
    reason="Windows names a stable-ABI module _kernels.pyd; free-threaded: no stable ABI",
)
def test_kernels_are_built_on_the_stable_abi():
    from meshcheck.geometry import _kernels

    assert ".abi3." in Path(_kernels.__file__).name, _kernels.__file__


# ------------------------------------------------------------------------------------------
# The wheels' tests: selected by marker, and every test that needs a platform carries its marker

#: The markers each wheel platform's test command deselects (pyproject.toml, [tool.cibuildwheel]):
#: ``browser`` tests drive Debian's chromium, which no build container or runner has (.ci/run
#: installs it and runs them); ``linux_only`` tests read /proc or write /dev/full, or name files
#: in bytes that are not UTF-8 (macOS and Windows refuse such names); ``posix_only`` tests use
#: FIFOs, resource limits, user ids, POSIX signals and file modes, or symbolic links.
DESELECTED = {
    "linux": {"browser"},
    "macos": {"browser", "linux_only"},
    "windows": {"browser", "linux_only", "posix_only"},
}
PLATFORM_MARKERS = ("browser", "linux_only", "posix_only")

#: What a test may use only on some platforms, as its code shows it.
POSIX_MODULES = {"resource", "fcntl", "pwd", "grp", "termios", "pty"}
BROWSER_MODULES = {"playwright", "chromium"}  # chromium: scripts/chromium.py, which drives it
POSIX_ATTRIBUTES = {
    "os": {
        *("mkfifo", "mknod", "fork", "setsid", "killpg", "getpgid", "symlink"),
        *("geteuid", "getuid", "getegid", "getgid", "setuid", "seteuid", "setgid"),
        *("chmod", "lchmod", "chown", "lchown", "umask"),
    },
    "signal": {
        *("SIGKILL", "SIGALRM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2"),
        *("SIGSTOP", "SIGCONT", "SIGCHLD", "SIGPIPE"),
    },
    "stat": {"S_IMODE"},  # a file's POSIX mode bits: Windows keeps only a read-only flag
}
POSIX_METHODS = {"chmod", "lchmod", "symlink_to"}  # pathlib's
POSIX_KEYWORDS = {"preexec_fn"}  # subprocess: "not supported on Windows"
POSIX_PATHS = ("/dev/zero", "/dev/null", "/dev/stdin", "/dev/stdout", "/dev/stderr")
LINUX_PATHS = ("/proc/", "/dev/full")
_IMPORTS = re.compile(r"(?m)^\s*(?:import\s+([\w., ]+)|from\s+(\w+))")


def _module_needs(name: str) -> set[str]:
    top = name.split(".")[0]
    return (
        {"posix_only"} if top in POSIX_MODULES else {"browser"} if top in BROWSER_MODULES else set()
    )


def _string_needs(value: str | bytes) -> set[str]:
    """Markers a string constant calls for: a path of one platform, a file name that is not
    UTF-8, or the code of a child process importing a POSIX module."""
    text = value.decode("latin-1") if isinstance(value, bytes) else value
    needs = set()
    if any(path in text for path in LINUX_PATHS):
        needs.add("linux_only")
    if any(re.search(rf"(^|[\s\"'=]){re.escape(path)}\b", text) for path in POSIX_PATHS):
        needs.add("posix_only")
    if isinstance(value, bytes) and value.startswith(b"/"):
        try:
            value.decode("utf-8")
        except UnicodeDecodeError:
            needs.add("linux_only")
    for match in _IMPORTS.finditer(text):
        for name in (match[1] or match[2]).split(","):
            needs |= _module_needs(name.strip())
    return needs


def _needs(node: ast.AST, *, strings: bool = True) -> tuple[set[str], set[str], set[tuple]]:
    """What ``node``'s code needs by itself, the names it uses, and its ``a.b`` attributes."""
    needs, names, attributes = set(), set(), set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Import):
            for alias in sub.names:
                needs |= _module_needs(alias.name)
        elif isinstance(sub, ast.ImportFrom):
            needs |= _module_needs(sub.module or "")
        elif isinstance(sub, ast.Attribute):
            if isinstance(sub.value, ast.Name):
                owner = sub.value.id
                if owner in POSIX_MODULES or sub.attr in POSIX_ATTRIBUTES.get(owner, ()):
                    needs.add("posix_only")
                attributes.add((owner, sub.attr))
            if sub.attr in POSIX_METHODS:
                needs.add("posix_only")
        elif isinstance(sub, ast.keyword) and sub.arg in POSIX_KEYWORDS:
            needs.add("posix_only")
        elif isinstance(sub, ast.Constant) and isinstance(sub.value, str | bytes) and strings:
            needs |= _string_needs(sub.value)
        elif isinstance(sub, ast.Name):
            names.add(sub.id)
        elif isinstance(sub, ast.arg):
            names.add(sub.arg)  # a test's or fixture's parameters: the fixtures it uses
    return needs, names, attributes


def _marks(decorators) -> set[str]:
    """``pytest.mark.NAME`` (called or not) among ``decorators``, or in a ``pytestmark`` value."""
    out = set()
    for node in decorators:
        for sub in ast.walk(node):
            if (
                isinstance(sub, ast.Attribute)
                and isinstance(sub.value, ast.Attribute)
                and sub.value.attr == "mark"
            ):
                out.add(sub.attr)
    return out


class _Suite:
    """The test modules and their helpers, read as code: which tests need which markers."""

    def __init__(self, folder: Path, *, leave_out=()):
        self.leave_out = set(leave_out)
        self.definitions: dict[tuple[str, str], ast.AST] = {}
        self.imports: dict[str, dict[str, tuple[str, str | None]]] = {}
        self.modules: dict[str, ast.Module] = {}
        for path in sorted(folder.glob("*.py")):
            self.modules[path.stem] = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for name, tree in self.modules.items():
            self.imports[name] = self._imports(tree)
            for node in tree.body:
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                    self.definitions[name, node.name] = node
                elif isinstance(node, ast.Assign | ast.AnnAssign):
                    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                    for target in targets:
                        if isinstance(target, ast.Name):
                            self.definitions[name, target.id] = node
        self._closure: dict[tuple[str, str], set[str]] = {}

    def _imports(self, tree: ast.Module) -> dict[str, tuple[str, str | None]]:
        """Local name -> (helper module, name in it or None for the module), for the suite's
        own modules only."""
        out = {}
        for node in tree.body:
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in self.modules:
                        out[alias.asname or alias.name] = (alias.name, None)
            elif isinstance(node, ast.ImportFrom) and node.module in self.modules:
                for alias in node.names:
                    out[alias.asname or alias.name] = (node.module, alias.name)
        return out

    def _resolve(self, module: str, name: str) -> tuple[str, str] | None:
        if (module, name) in self.definitions:
            return module, name
        target = self.imports[module].get(name)
        if target and target[1] is not None and (target[0], target[1]) in self.definitions:
            return target[0], target[1]
        if ("conftest", name) in self.definitions:  # a fixture conftest.py defines
            return "conftest", name
        return None

    def needs(self, module: str, name: str) -> set[str]:
        """Markers the definition ``module.name`` needs: its own code's, and those of every
        function, constant and fixture of the suite it uses, transitively."""
        key = (module, name)
        if key in self._closure:
            return self._closure[key]
        self._closure[key] = set()  # a cycle adds nothing
        node = self.definitions[key]
        own, names, attributes = _needs(node)
        for used in names - {name}:
            found = self._resolve(module, used)
            if found:
                own |= self.needs(*found)
        for owner, attribute in attributes:
            target = self.imports[module].get(owner)
            if target and target[1] is None and (target[0], attribute) in self.definitions:
                own |= self.needs(target[0], attribute)
        self._closure[key] = own
        return own

    def tests(self):
        """(module, test name, markers it carries) of every test function."""
        for module, tree in self.modules.items():
            if not module.startswith("test_") or module in self.leave_out:
                continue
            carried = set()
            for node in tree.body:
                if isinstance(node, ast.Assign) and any(
                    isinstance(t, ast.Name) and t.id == "pytestmark" for t in node.targets
                ):
                    carried |= _marks([node.value])
            for node in tree.body:
                if isinstance(node, ast.FunctionDef) and node.name.startswith("test"):
                    yield module, node.name, carried | _marks(node.decorator_list)

    def at_import(self, module: str) -> set[str]:
        """Markers the code ``module`` runs when it is imported (collected) needs: imports, calls
        and decorators, not the string constants it only defines."""
        out = set()
        for node in self.modules[module].body:
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                parts = [*node.decorator_list, *node.args.defaults, *node.args.kw_defaults]
            elif isinstance(node, ast.ClassDef):
                parts = [*node.decorator_list, *node.bases]
            else:
                parts = [node]
            for part in filter(None, parts):
                needs, _, _ = _needs(part, strings=False)
                out |= needs
                for sub in ast.walk(part):  # a helper of the module called at import
                    if isinstance(sub, ast.Call) and isinstance(sub.func, ast.Name):
                        found = self._resolve(module, sub.func.id)
                        if found and isinstance(self.definitions[found], ast.FunctionDef):
                            out |= self.needs(*found)
        return out


def _required(needs: set[str]) -> set[str]:
    """The markers that must be carried: Linux is POSIX, so ``linux_only`` covers
    ``posix_only``."""
    return needs - {"posix_only"} if "linux_only" in needs else needs


def _unmarked(suite: _Suite) -> dict[str, set[str]]:
    out = {}
    for module, name, carried in suite.tests():
        missing = _required(suite.needs(module, name)) - carried
        if missing:
            out[f"{module}.py::{name}"] = missing
    return out


#: The suite as code, but for this module, whose tables above name every facility as data.
SUITE = _Suite(ROOT / "tests", leave_out={Path(__file__).stem})


def _wheel_commands() -> dict[str, str]:
    """Each wheel platform's test command: its own section's, else [tool.cibuildwheel]'s."""
    with open(ROOT / "pyproject.toml", "rb") as f:
        cibw = tomllib.load(f)["tool"]["cibuildwheel"]
    return {p: cibw.get(p, {}).get("test-command", cibw["test-command"]) for p in DESELECTED}


def _marker_names(expression: str) -> set[str]:
    return set(re.findall(r"[A-Za-z_]\w*", expression)) - {"not", "and", "or"}


def _selects(expression: str, marks: set[str]) -> bool:
    """Whether ``pytest -m EXPRESSION`` selects a test carrying ``marks`` (the grammar of -m,
    ``not``/``and``/``or`` and parentheses over marker names, is Python's)."""
    names = {name: name in marks for name in _marker_names(expression)}
    return eval(expression, {"__builtins__": {}}, names)


def test_wheel_test_commands_select_by_marker_alone():
    with open(ROOT / "pyproject.toml", "rb") as f:
        declared = tomllib.load(f)["tool"]["pytest"]["ini_options"]["markers"]
    registered = {line.split(":")[0] for line in declared}
    assert set(PLATFORM_MARKERS) <= registered
    for platform, command in _wheel_commands().items():
        args = shlex.split(command)
        assert not {"-k", "--ignore", "--ignore-glob", "--deselect"} & set(args), command
        assert args.count("-m") == 1, command
        expression = args[args.index("-m") + 1]
        assert _marker_names(expression) <= registered, expression
        for marks in [set(), {"slow"}, *({m} for m in PLATFORM_MARKERS), set(PLATFORM_MARKERS)]:
            wanted = not marks & DESELECTED[platform]
            assert _selects(expression, marks) == wanted, (platform, marks)


def test_every_test_that_needs_a_platform_carries_its_marker():
    assert _unmarked(SUITE) == {}
    browser = [name for module, name, carried in SUITE.tests() if "browser" in carried]
    uses_browser = [
        name
        for module, name, _ in SUITE.tests()
        if "browser_page" in {a.arg for a in SUITE.definitions[module, name].args.args}
    ]
    assert sorted(browser) == sorted(uses_browser) and len(browser) == 13, browser


def test_collecting_the_tests_needs_no_platform():
    """Module-level code (imports, decorators, calls at import) uses nothing a wheel platform
    lacks: collection works everywhere, and markers do the selecting."""
    found = {m: SUITE.at_import(m) for m in SUITE.modules if m not in SUITE.leave_out}
    assert {m: needs for m, needs in found.items() if needs} == {}


#: Code a test may hold, what it needs, and whether running it at import is seen too (a string
#: constant only counts where a test uses it: a module may define paths and child code freely).
USES = [
    ("import resource", {"posix_only"}, True),
    ("path.chmod(0o600)", {"posix_only"}, True),
    ("path.symlink_to(target)", {"posix_only"}, True),
    ("os.kill(pid, signal.SIGKILL)", {"posix_only"}, True),
    ("subprocess.run(args, preexec_fn=cap)", {"posix_only"}, True),
    ("os.mkfifo(path)", {"posix_only"}, True),
    ("is_root = os.geteuid() == 0", {"posix_only"}, True),
    ("from chromium import find_chromium", {"browser"}, True),
    ("code = 'import resource, runpy'", {"posix_only"}, False),
    ("open('/dev/zero', 'rb')", {"posix_only"}, False),
    ("open('/proc/meminfo')", {"linux_only"}, False),
    ("write_output('/dev/full', 'x')", {"linux_only"}, False),
    ("name = b'/caf\\xe9.stl'", {"linux_only"}, False),
    ("open(os.devnull)", set(), False),
    ("os.link(a, b)", set(), False),
    ("os.kill(pid, 9)", set(), False),
    ("name = b'/caf\\xc3\\xa9.stl'", set(), False),
]


@pytest.mark.parametrize(("code", "needs", "at_import"), USES, ids=[u[0] for u in USES])
def test_the_reader_finds_what_a_test_needs(tmp_path, code, needs, at_import):
    """The checks above can fail: each use makes a test that lacks the marker an offence, used
    directly, through a helper or through a fixture; at a module's top it is seen at import."""
    body = textwrap.indent(code, "    ")
    (tmp_path / "test_x.py").write_text(
        "import os, signal, subprocess\nimport pytest\n"
        f"def helper():\n{body}\n"
        "@pytest.fixture\ndef thing():\n    return helper()\n"
        f"def test_direct():\n{body}\n"
        "def test_through_a_helper():\n    helper()\n"
        "def test_through_a_fixture(thing):\n    pass\n"
        "@pytest.mark.browser\n@pytest.mark.linux_only\n@pytest.mark.posix_only\n"
        "def test_marked(thing):\n    helper()\n",
        encoding="utf-8",
    )
    (tmp_path / "test_y.py").write_text(f"import os, signal, subprocess\n{code}\n")
    suite = _Suite(tmp_path)
    tests = ("test_direct", "test_through_a_helper", "test_through_a_fixture")
    want = {f"test_x.py::{t}": _required(needs) for t in tests} if needs else {}
    assert _unmarked(suite) == want
    assert suite.at_import("test_y") == (needs if at_import else set())
    assert suite.at_import("test_x") == set()


@pytest.mark.slow
def test_each_wheel_platform_collects_no_test_it_cannot_run():
    """Collected with each platform's marker expression, the suite holds none of the tests the
    reader found needing what that platform lacks, and ``-m browser`` collects exactly the tests
    that open the browser."""
    needing = {
        f"tests/{module}.py::{name}": _required(SUITE.needs(module, name))
        for module, name, _ in SUITE.tests()
    }

    def collected(expression: str) -> set[str]:
        command = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"]
        done = subprocess.run(
            [*command, "-m", expression, "tests"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, done.stdout + done.stderr
        return {line.split("[")[0] for line in done.stdout.splitlines() if "::" in line}

    for platform, command in _wheel_commands().items():
        args = shlex.split(command)
        tests = collected(args[args.index("-m") + 1])
        assert len(tests) > 400, (platform, len(tests))
        cannot = {t for t, needs in needing.items() if needs & DESELECTED[platform]}
        assert tests & cannot == set(), platform
    browser = {t for t, needs in needing.items() if "browser" in needs}
    assert collected("browser") == browser and len(browser) == 13, browser
