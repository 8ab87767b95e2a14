"""The shape of the G-code package (fusioncut.io.gcode): modules of one concern that import one another
directly, none reaching into another's private names, none of 800 lines or more (import circles:
tests/test_architecture.py)."""
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


def test_no_module_imports_the_package_front() -> None:
    """Only outside code goes through the package's front; its modules import each other directly (an
    import circle among them is found by tests/test_architecture.py, over the whole package)."""
    graph = {m: {t for t, _ in targets if t != m} for m, targets in _imports().items()}
    assert {t for targets in graph.values() for t in targets} <= set(graph)
    assert [m for m, targets in graph.items() if "__init__" in targets] == []


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
