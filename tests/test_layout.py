"""The package's rooms and the one direction of imports between them (read with ``ast``).

Each subpackage of ``drake_clutter`` may import only the rooms listed for it in ALLOWED (its
own modules always); ``solvers`` imports no pydrake; nothing in the package, the apps, the
benchmarks or the studies imports ``drake_clutter.cli`` or ``apps``; no test or script reaches
a helper through ``sys.path``; every subpackage says in its docstring what it owns and may
import; no module imports itself back through others (an import cycle), at module level or
inside a function.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "drake_clutter"

BASE = {"common", "robot", "scene", "trajectory"}
ALLOWED = {
    "__init__": set(),
    "common": set(),
    "robot": {"common"},
    "scene": {"common", "robot"},
    "trajectory": {"common", "robot"},
    "worlds": BASE,
    "solvers": {"common"},
    "phi": BASE | {"worlds"},
    "planners": BASE | {"worlds", "solvers", "phi"},
    "evaluation": BASE | {"worlds"},
    "experiments": BASE | {"worlds", "solvers", "phi", "planners", "evaluation"},
    "viz": BASE | {"worlds", "evaluation"},
    "conformance": BASE | {"worlds", "phi"},
    "testing": BASE | {"worlds", "solvers", "phi", "planners", "evaluation"},
    "cli": BASE | {"worlds", "solvers", "phi", "planners", "evaluation", "experiments", "viz"},
}


def _room(path: Path) -> str:
    """The room of a file of the package: its subpackage, or the top-level module's name."""
    parts = path.relative_to(PACKAGE).parts
    return parts[0] if len(parts) > 1 else Path(parts[0]).stem


def _imports(source: str, name: str = "<source>") -> list[tuple[int, str]]:
    """(line, dotted module) of every import in a file's source."""
    found = []
    for node in ast.walk(ast.parse(source, name)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{name}:{node.lineno}: relative import"
            found += [(node.lineno, f"{node.module}.{alias.name}") for alias in node.names]
    return found


def _violations(source: str, room: str) -> list[str]:
    """The imports of a package file in ``room`` that point against the direction."""
    allowed = ALLOWED[room] | {room}
    bad = []
    for line, module in _imports(source):
        target = _target_room(module)
        if target is not None and target not in allowed:
            bad.append(f"line {line}: {room} imports {module}")
        if room == "solvers" and module.split(".")[0] == "pydrake":
            bad.append(f"line {line}: solvers import {module}")
    return bad


def _package_files() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py"))


def _target_room(module: str) -> str | None:
    """The room a ``drake_clutter.…`` import lands in (None for other packages)."""
    parts = module.split(".")
    if parts[0] != "drake_clutter" or len(parts) < 2:
        return None
    return parts[1]


def test_every_room_is_known_and_documented():
    rooms = {_room(p) for p in _package_files()}
    assert rooms == set(ALLOWED), "a new room needs its line in ALLOWED"
    for sub in sorted(p for p in PACKAGE.iterdir() if p.is_dir() and p.name in ALLOWED):
        doc = ast.get_docstring(ast.parse((sub / "__init__.py").read_text(encoding="utf-8")))
        assert doc and "May import" in doc, f"{sub.name}/__init__.py: say what it owns and imports"


@pytest.mark.parametrize("path", _package_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_imports_point_one_way(path):
    assert _violations(path.read_text(encoding="utf-8"), _room(path)) == []


def _outside_files() -> list[Path]:
    return sorted([*(REPO / "apps").glob("*.py"), *(REPO / "benchmarks").glob("*.py"),
                   *(REPO / "studies").glob("*.py"), *(REPO / "tests").rglob("*.py")])


@pytest.mark.parametrize("path", [*_package_files(), *_outside_files()],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_nothing_imports_the_command_line_or_the_apps_or_edits_sys_path(path):
    is_test = path.relative_to(REPO).parts[0] == "tests"
    text = path.read_text(encoding="utf-8")
    assert "sys.path" not in text or path.name == "test_layout.py", \
        f"{path.relative_to(REPO)}: a shared helper belongs in drake_clutter.testing"
    for line, module in _imports(text, str(path)):
        assert not module.startswith("apps"), f"{path.relative_to(REPO)}:{line}: imports {module}"
        if module.startswith("drake_clutter.cli") and path.name != "cli.py":
            assert is_test, f"{path.relative_to(REPO)}:{line}: only tests may import the CLI"
        assert not module.startswith("test_"), f"{path.relative_to(REPO)}:{line}: imports a test"


@pytest.mark.parametrize("path", _outside_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_no_script_or_test_loads_a_file_by_path_or_imports_a_private_name(path):
    text = path.read_text(encoding="utf-8")
    if path.name != "test_layout.py":
        for loader in ("spec_from_file_location", "runpy", "SourceFileLoader"):
            assert loader not in text, f"{path.relative_to(REPO)}: loads a file by path " \
                "(a tool belongs in the package or the CLI)"
    for line, module in _imports(text, str(path)):
        if module.startswith("drake_clutter.") and path.relative_to(REPO).parts[0] != "tests":
            private = [p for p in module.split(".")[1:] if p.startswith("_") and p != "__init__"]
            assert not private, f"{path.relative_to(REPO)}:{line}: imports private {module}"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph(sources: dict[str, str]) -> dict[str, set[str]]:
    """{module: the package's modules it imports} (``from a.b import c`` lands on a.b.c if that
    is a module, else on a.b); a module's imports of its own enclosing packages are left out."""
    def resolve(dotted: str) -> str | None:
        parts = dotted.split(".")
        while parts and ".".join(parts) not in sources:
            parts.pop()
        return ".".join(parts) or None

    graph = {}
    for module, source in sources.items():
        targets = {resolve(dotted) for _, dotted in _imports(source, module)}
        graph[module] = {t for t in targets
                         if t is not None and t != module and not module.startswith(t + ".")}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected sets of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = stack[stack.index(v):]
            del stack[stack.index(v):]
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_module_imports_itself_back():
    sources = {_module_name(p): p.read_text(encoding="utf-8") for p in _package_files()}
    assert _cycles(_import_graph(sources)) == []


def test_the_cycle_rule_catches_a_cycle_through_a_function_local_import():
    sources = {"drake_clutter.phi.a": "from drake_clutter.phi.b import f\n",
               "drake_clutter.phi.b": "def f():\n    from drake_clutter.phi import a\n",
               "drake_clutter.phi.c": "import drake_clutter.phi.a\n"}
    assert _cycles(_import_graph(sources)) == [["drake_clutter.phi.a", "drake_clutter.phi.b"]]


def test_the_rule_catches_imports_against_the_direction():
    assert _violations("from drake_clutter.planners import baseline\n", "solvers")
    assert _violations("import pydrake.all\n", "solvers")
    assert _violations("from drake_clutter.planners.baseline import plan_baseline\n",
                       "evaluation")
    assert _violations("from drake_clutter.cli import main\n", "experiments")
    assert not _violations("from drake_clutter.evaluation.judge import evaluate\n", "viz")


@pytest.mark.parametrize("path", sorted((REPO / "studies").glob("*.py")),
                         ids=lambda p: p.name)
def test_every_study_names_the_log_that_holds_its_dated_results(path):
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    logs = [word.strip(".,") for word in doc.split() if word.startswith("docs/log/")]
    assert logs, f"studies/{path.name}: its docstring names no docs/log/ file"
    for log in logs:
        assert path.name in (REPO / log).read_text(encoding="utf-8"), \
            f"studies/{path.name}: {log} does not mention it"
