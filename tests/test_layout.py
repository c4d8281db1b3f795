"""The package is a picture of the flow: no import cycle among meshcheck's modules, and no stage
importing a later one.

Imports are read with ``ast`` from the source, every one of them: at module level and inside
functions (a lazy import still ties the stages together). Only imports under
``if TYPE_CHECKING:`` are left out: they never run, and annotations may name a later stage's
types. A module's own parent packages are not counted (importing ``meshcheck.load.files``
runs ``meshcheck.load`` first whatever the code says), nor is ``meshcheck`` itself, which
``from .. import x`` names only to reach ``x``.
"""

from __future__ import annotations

import ast
import os

import pytest

PACKAGE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "meshcheck")

#: Stages in data-flow order: a module may import its own stage and earlier ones only.
STAGES = [
    (
        "base",
        [
            "_process",  # the process-wide settings of the command and its workers
            "errors",
            "_lazy",
            "units",
            "tolerances",
            "motion",
            "settings",
            "results",
            "config",
            "baseline",
            "outcome",
            "output",
            "progress",
        ],
    ),
    ("kernels and shared tools", ["mesh", "geometry", "cache", "execute", "_worker", "progress"]),
    ("load", ["load"]),  # load.robot: the robot model every mechanism of a run shares
    ("decompose", ["decompose"]),
    ("verify", ["verify"]),
    # sweep.mechanisms, .kinematics, .distances, .search, .run: asks the verify stage's kernels
    # for distances along the joint ranges
    ("sweep", ["sweep"]),
    ("pipeline", ["pipeline"]),
    ("reports", ["reports"]),
    (
        "command line",
        ["cli", "__main__", ""],
    ),  # "": the package itself (its lazy names)
]
RANK = {top: k for k, (_, tops) in enumerate(STAGES) for top in tops}
#: Inside a package, its modules in data-flow order, by the same rule; the package's
#: ``__init__`` is its face and comes last.
ROOMS = {
    # one signed store, then the entries kept in it
    "meshcheck.cache": [["store"], ["decompositions", "verdicts", "tessellations"]],
    # bytes -> document (its structure checked) -> products -> meshes; the file's unit beside;
    # a worker reading a file ahead runs the same rooms, before ``read`` takes what it read
    "meshcheck.load.step": [
        ["units", "assembly"],
        ["document"],
        ["tessellate"],
        ["ahead"],
        ["read"],
    ],
}


def _modules() -> dict[str, str]:
    """Dotted module name -> its file, for every module of the package."""
    out = {}
    for folder, dirs, files in os.walk(PACKAGE):
        dirs[:] = [d for d in dirs if not d.startswith((".", "_"))]
        for file in files:
            if file.endswith(".py"):
                rel = os.path.relpath(os.path.join(folder, file), os.path.dirname(PACKAGE))
                parts = rel[: -len(".py")].split(os.sep)
                if parts[-1] == "__init__":
                    parts = parts[:-1]
                out[".".join(parts)] = os.path.join(folder, file)
    return out


MODULES = _modules()


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _import_nodes(tree: ast.AST):
    """Every import statement, skipping the bodies of ``if TYPE_CHECKING:``."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                yield from _import_nodes(child)
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        yield from _import_nodes(node)


def imports(module: str) -> set[str]:
    """The meshcheck modules ``module`` imports (resolved; parents and the package left out)."""
    path = MODULES[module]
    package = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    with open(path, encoding="utf-8") as fh:
        tree = ast.parse(fh.read(), path)
    found = set()
    for node in _import_nodes(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        else:
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            # ``from X import name``: the submodule X.name when there is one, else X itself
            targets = [
                f"{source}.{a.name}" if f"{source}.{a.name}" in MODULES else source
                for a in node.names
            ]
        for target in targets:
            while target and target not in MODULES:  # a name inside a module: the module
                target = target.rpartition(".")[0]
            if target and target != "meshcheck" and not module.startswith(target + "."):
                found.add(target)
    found.discard(module)
    return found


def stage(module: str) -> int:
    top = module.split(".")[1] if "." in module else ""
    return RANK[top]


def test_every_module_has_a_stage():
    assert len(MODULES) > 40
    missing = sorted(m for m in MODULES if (m.split(".")[1] if "." in m else "") not in RANK)
    assert missing == []


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_stage_imports_a_later_one(module):
    later = sorted(t for t in imports(module) if stage(t) > stage(module))
    assert later == [], f"{module} ({STAGES[stage(module)][0]}) imports later stages: {later}"


def room(module: str) -> int:
    package, _, name = module.rpartition(".")
    if module in ROOMS:  # the face
        return len(ROOMS[module])
    return next(k for k, names in enumerate(ROOMS[package]) if name in names)


def test_every_module_of_a_divided_package_has_a_room():
    for package, rooms in ROOMS.items():
        found = sorted(m.rpartition(".")[2] for m in MODULES if m.startswith(package + "."))
        assert found == sorted(name for names in rooms for name in names), package


@pytest.mark.parametrize(
    "module", sorted(m for m in MODULES if m in ROOMS or m.rpartition(".")[0] in ROOMS)
)
def test_no_room_imports_a_later_one(module):
    package = module if module in ROOMS else module.rpartition(".")[0]
    inside = [t for t in imports(module) if t.rpartition(".")[0] == package]
    later = sorted(t for t in inside if room(t) > room(module))
    assert later == [], f"{module} imports later modules of {package}: {later}"


def test_no_import_cycle():
    graph = {m: imports(m) for m in MODULES}
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    cycles = []

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                cycles.append([*path[path.index(t) :], t])
            elif t not in state:
                visit(t, [*path, t])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert cycles == []


def test_the_scan_sees_lazy_and_relative_imports():
    """The scan itself: a later stage imported inside a function is found, and
    ``from .. import results`` resolves to the module."""
    assert "meshcheck.results" in imports("meshcheck.verify.pair")  # from .. import results
    assert "meshcheck.reports.gltf" in imports("meshcheck.cli")  # inside a function
    assert "meshcheck.pipeline" not in imports("meshcheck")  # only under TYPE_CHECKING or lazy
