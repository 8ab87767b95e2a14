"""The shape of the G-code package (fusioncut.io.gcode): modules of one concern that import one another
in one direction, none reaching into another's private names, none over 800 lines."""
from __future__ import annotations

import ast
from pathlib import Path

import fusioncut.io.gcode as gcode

PACKAGE = Path(gcode.__file__).parent
NAME = "fusioncut.io.gcode"
MAX_LINES = 800


def _imports() -> dict[str, list[tuple[str, list[str]]]]:
    """Module -> the package modules it imports (every import statement, wherever it stands) with the
    names it takes from them."""
    modules = {p.stem: p for p in PACKAGE.glob("*.py")}
    found: dict[str, list[tuple[str, list[str]]]] = {m: [] for m in modules}
    for m, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                raise AssertionError(f"{path.name}: relative import")
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(NAME):
                target = node.module[len(NAME) + 1:] or "__init__"  # type: ignore[index]
                names = [a.name for a in node.names]
                if target == "__init__":  # "from fusioncut.io.gcode import comp" takes a module
                    found[m] += [(n, []) for n in names if n in modules] + [("__init__", names)]
                else:
                    found[m].append((target, names))
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith(NAME + "."):
                        found[m].append((a.name[len(NAME) + 1:], []))
                    elif a.name == NAME:
                        found[m].append(("__init__", []))
    return found


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """An import circle of ``graph`` (a path that comes back to its start), or ``None``."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(v: str, path: list[str]) -> list[str] | None:
        state[v] = 1
        for w in sorted(graph[v]):
            if state.get(w) == 1:  # on the current path: the path from w comes back to it
                return path[path.index(w):] + [w]
            if w not in state:
                found = visit(w, path + [w])
                if found:
                    return found
        state[v] = 2
        return None

    for v in sorted(graph):
        if v not in state:
            found = visit(v, [v])
            if found:
                return found
    return None


def test_no_module_imports_the_package_or_a_module_that_imports_it_back() -> None:
    imports = _imports()
    graph = {m: {t for t, _ in targets if t != m} for m, targets in imports.items()}
    assert {t for targets in graph.values() for t in targets} <= set(graph)
    assert _circle(graph) is None, f"import circle: {' -> '.join(_circle(graph) or [])}"
    # only outside code goes through the package's front; its modules import each other directly
    assert [m for m, targets in graph.items() if "__init__" in targets] == []


def test_the_circle_finder_finds_a_circle() -> None:
    assert _circle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert _circle({"a": {"b"}, "b": set()}) is None


def test_no_module_takes_another_modules_private_names() -> None:
    taken = [(m, t, n) for m, targets in _imports().items() for t, names in targets for n in names
             if n.startswith("_")]
    assert taken == []


def test_every_module_is_under_800_lines() -> None:
    sizes = {p.name: len(p.read_text().splitlines()) for p in PACKAGE.glob("*.py")}
    assert len(sizes) >= 10
    assert {name: n for name, n in sizes.items() if n >= MAX_LINES} == {}


def test_the_package_exports_what_it_lists() -> None:
    assert len(gcode.__all__) == len(set(gcode.__all__))
    namespace: dict[str, object] = {}
    exec(f"from {NAME} import *", namespace)
    assert set(gcode.__all__) <= set(namespace)
    assert {"GCodeInterpreter", "ModalState", "parse_gcode_text", "read_gcode", "rewrite_feeds", "write_gcode"} <= set(
        gcode.__all__)
