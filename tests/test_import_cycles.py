"""No import cycle inside the core, the driver or the simulator: every module's imports (at the
top, in functions, or for type checking only) form a graph without loops, so each part can be
read and tested on its own."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "agilent35670a": ROOT / "drivers" / "agilent35670a",
    "rigsim": ROOT / "sim" / "rigsim",
    "viscorig": ROOT / "src" / "viscorig",
}


def module_name(package: str, folder: Path, path: Path) -> str:
    parts = [package, *path.relative_to(folder).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(package: str, folder: Path, path: Path, known: set[str]) -> set[str]:
    """Modules of the package that ``path`` imports (packages count as their ``__init__``)."""
    here = module_name(package, folder, path)
    base = here if path.name == "__init__.py" else here.rsplit(".", 1)[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                module = ".".join([*anchor, node.module] if node.module else anchor)
            else:
                module = node.module or ""
            # ``from pkg import mod`` imports ``mod``; ``from mod import name`` imports ``mod``
            names = [f"{module}.{alias.name}" if f"{module}.{alias.name}" in known else module
                     for alias in node.names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name != here:
                found.add(name)
    return found


def graph(package: str, folder: Path) -> dict[str, set[str]]:
    paths = sorted(folder.rglob("*.py"))
    known = {module_name(package, folder, p) for p in paths}
    return {module_name(package, folder, p): imports(package, folder, p, known) for p in paths}


def cycle(edges: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt):], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(edges):
        if node not in state and (found := visit(node)):
            return found
    return None


@pytest.mark.parametrize("package", sorted(PACKAGES))
def test_no_import_cycle(package: str) -> None:
    found = cycle(graph(package, PACKAGES[package]))
    assert found is None, " -> ".join(found or [])


def test_the_detector_finds_a_cycle() -> None:
    assert cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert cycle({"a": {"b"}, "b": set()}) is None
