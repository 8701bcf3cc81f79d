"""How the packages import each other: the layering protocol <- firmware_sim <- host (and inside host, the
rooms below the studies below the commands), no import cycle, and no import hidden inside a library function
(ARCHITECTURE.md; issue 11). Static: the sources are parsed, nothing is imported."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("protocol", "firmware_sim", "host", "gaitlog")
#: Layer of each package or host room: a module may import only from its own layer or a lower one.
LAYERS = {"protocol": 0, "firmware_sim": 1, "host": 2, "host.errors": 2, "host.storage": 2, "host.link": 3, "host.files": 3,
          "host.accelerometer": 3, "host.gait": 3, "host.kinematics": 3, "host.studies": 4, "host.commands": 5,
          "host.cli": 6, "gaitlog.__main__": 7, "gaitlog": 0,
          "gaitlog.units": -1, "gaitlog.atomic_write": -1}
#: Modules whose functions may import (the command line's lazy imports keep ``gaitlog --help`` fast).
LAZY_ALLOWED = ("host.commands.", "host.cli", "gaitlog.__main__")


def _modules() -> dict[str, ast.Module]:
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return out


MODULES = _modules()


def _is_type_checking(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imported(node: ast.Import | ast.ImportFrom, module: str) -> list[str]:
    """Project modules named by an import statement (``from a import b`` counts ``a.b`` when that is a module)."""
    if isinstance(node, ast.Import):
        names = [_in_repository(a.name) for a in node.names]
    else:
        assert node.level == 0, f"{module}:{node.lineno}: relative import (the project imports absolutely)"
        base = _in_repository(node.module or "")
        names = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]
    return [n for n in names if n.split(".")[0] in PACKAGES]


def _in_repository(name: str) -> str:
    """A module's name as its folder in the repository (``gaitlog.host.cli`` is ``host/cli.py``)."""
    return name.removeprefix("gaitlog.") if name.split(".")[:2][-1] in PACKAGES else name


def _module_level_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """Imports executed when the module is imported (not those under ``if TYPE_CHECKING:``, not in functions)."""
    found = []

    def walk(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) or _is_type_checking(child):
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child)
            walk(child)

    walk(tree)
    return found


def _layer(module: str) -> int:
    parts = module.split(".")
    for k in range(len(parts), 0, -1):
        if ".".join(parts[:k]) in LAYERS:
            return LAYERS[".".join(parts[:k])]
    raise AssertionError(f"{module}: no layer declared in LAYERS")


def test_no_import_inside_a_library_function() -> None:
    hidden = []
    for name, tree in MODULES.items():
        if name.startswith(LAZY_ALLOWED):
            continue
        for func in ast.walk(tree):
            if isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
                hidden += [f"{name}:{n.lineno}: {ast.unparse(n)}" for n in ast.walk(func)
                           if isinstance(n, (ast.Import, ast.ImportFrom))]
    assert not hidden, "imports inside library functions:\n" + "\n".join(sorted(set(hidden)))


#: Most imports inside the functions of ``host/commands/`` (an ``ast`` count; fewer than 80 asked, 72 reached). The
#: commands import at module level what costs ``gaitlog --help`` nothing measurable (the standard library,
#: ``host.errors``, the option helpers) and inside functions only numpy, scipy, numba, dask, matplotlib and
#: the modules that load them, and the two standard modules --help measurably does without: tempfile (loaded by
#: ``atomic_write`` and ``task_store``) and dataclasses (which loads inspect, ast, dis, tokenize).
MAX_COMMAND_FUNCTION_IMPORTS = 72


def _function_level_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """Imports whose nearest enclosing scope is a function (each statement once, nested functions included)."""
    found = []

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if in_function and isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child)
            walk(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)))

    walk(tree, False)
    return found


def test_commands_import_inside_functions_only_what_costs_start_up() -> None:
    count = {name: len(_function_level_imports(tree)) for name, tree in MODULES.items()
             if name.startswith("host.commands.")}
    total = sum(count.values())
    assert total <= MAX_COMMAND_FUNCTION_IMPORTS, (
        f"{total} imports inside functions of host/commands/ (at most {MAX_COMMAND_FUNCTION_IMPORTS}): "
        + ", ".join(f"{n} {c}" for n, c in sorted(count.items(), key=lambda x: -x[1]) if c))


def test_imports_go_only_downwards() -> None:
    upward = []
    for name, tree in MODULES.items():
        for node in _module_level_imports(tree):
            upward += [f"{name} imports {t}" for t in _imported(node, name) if _layer(t) > _layer(name)]
    assert not upward, "\n".join(upward)


def test_no_import_cycle() -> None:
    graph = {name: {t for node in _module_level_imports(tree) for t in _imported(node, name) if t != name}
             for name, tree in MODULES.items()}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph[node] & MODULES.keys()):
            if state.get(nxt) == 1:  # on the current path: a cycle
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert not cycles, "\n".join(" -> ".join(c) for c in cycles)


def test_benchmarks_import_what_exists() -> None:
    """The benchmarks are not run by the suite: at least every project name they import must exist (a module
    move once left ``bench_record.py --wire-time`` importing ``serve_pty`` from its old home)."""
    import importlib.util

    missing = []
    for path in sorted((ROOT / "benchmarks").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
                    and node.module.split(".")[0] == "gaitlog"):
                continue
            module = importlib.import_module(node.module)
            missing += [f"{path.name}:{node.lineno}: {node.module}.{a.name}" for a in node.names
                        if not hasattr(module, a.name)
                        and importlib.util.find_spec(f"{node.module}.{a.name}") is None]
    assert not missing, "\n".join(missing)


def test_every_import_goes_through_the_gaitlog_namespace() -> None:
    """``host``, ``protocol`` and ``firmware_sim`` install only as ``gaitlog.*``: a bare ``import host`` works in
    a checkout and fails in an installed copy."""
    bare = []
    for path in sorted(ROOT.glob("*/**/*.py")):
        if path.parts[len(ROOT.parts)] in (".ci", ".git", "build", "docs") or ".venv" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            bare += [f"{path.relative_to(ROOT)}:{node.lineno}: {n}" for n in names
                     if n.split(".")[0] in ("host", "protocol", "firmware_sim")]
    assert not bare, "\n".join(bare)


def test_pyproject_installs_every_package_under_gaitlog() -> None:
    import tomllib

    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    folders = {"gaitlog"} | {".".join(("gaitlog", *p.parent.relative_to(ROOT).parts))
                             for package in PACKAGES[:3] for p in (ROOT / package).rglob("__init__.py")}
    assert set(setuptools["packages"]) == folders
    assert setuptools["package-dir"] == {"gaitlog": "gaitlog", **{f"gaitlog.{p}": p for p in PACKAGES[:3]}}


#: Calls that touch files: none may stand in ``protocol/`` (the binary contract works on bytes; the one place
#: that writes files for every package is ``gaitlog/atomic_write.py``, below all of them).
FILE_CALLS = {"open", "read_bytes", "write_bytes", "read_text", "write_text", "fdopen", "mkstemp",
              "NamedTemporaryFile", "rename", "unlink"}


def test_protocol_opens_no_file() -> None:
    found = []
    for name, tree in MODULES.items():
        if name.split(".")[0] != "protocol":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                f = node.func
                called = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
                if called in FILE_CALLS:
                    found.append(f"{name}:{node.lineno}: {ast.unparse(node)[:80]}")
    assert not found, "\n".join(found)


def test_no_loop_between_host_subpackages() -> None:
    """Inside ``host``, one subpackage per concept and no two that import each other, even through other
    modules (``files`` -> ``accelerometer`` -> ``files`` was one, until the storage utilities moved below both)."""
    def room(module: str) -> str:
        parts = module.split(".")
        return ".".join(parts[:2]) if parts[0] == "host" and len(parts) > 1 else parts[0]

    graph: dict[str, set[str]] = {}
    for name, tree in MODULES.items():
        if not name.startswith("host."):
            continue
        for node in _module_level_imports(tree):
            graph.setdefault(room(name), set()).update(
                room(t) for t in _imported(node, name) if t.startswith("host.") and room(t) != room(name))
    loops = []
    for a, targets in graph.items():
        seen, todo = set(), list(targets)
        while todo:
            b = todo.pop()
            if b == a:
                loops.append(a)
                break
            if b not in seen:
                seen.add(b)
                todo.extend(graph.get(b, ()))
    assert not loops, f"host subpackages that reach themselves through imports: {sorted(loops)}"
