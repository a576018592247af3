"""No import cycle inside the core, the driver or the simulator: every module's imports (at the
top, in functions, or for type checking only) form a graph without loops, so each part can be
read and tested on its own.

The core imports its own modules at the top of the module that uses them, so a reader sees every
dependency there. An import of a ``viscorig`` module inside a function is allowed only with a
comment saying why (``# keeps ...``: a command's start fast, ``import viscorig`` light), on its
line or on the line above the block of imports it belongs to; what those comments promise is
checked too (the heavy libraries they keep out are not loaded)."""

from __future__ import annotations

import ast
import subprocess
import sys
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


#: The comment that justifies a function-level import of a ``viscorig`` module.
JUSTIFICATION = "# keeps "


def _is_import_line(line: str) -> bool:
    return line.lstrip().startswith(("from ", "import "))


def unjustified_local_imports(source: str, package: str = "viscorig") -> list[str]:
    """``line: statement`` of every import of ``package`` inside a function that carries no
    justification comment, on its first line or above the run of imports it starts or joins."""
    lines = source.splitlines()
    found: list[str] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if in_function and isinstance(child, ast.Import | ast.ImportFrom):
                if isinstance(child, ast.Import):
                    modules = [alias.name for alias in child.names]
                else:
                    modules = ["." if child.level else child.module or ""]
                ours = any(m == "." or m.split(".")[0] == package for m in modules)
                above = child.lineno - 1
                while above > 0 and _is_import_line(lines[above - 1]):
                    above -= 1
                comments = lines[child.lineno - 1] + (lines[above - 1] if above > 0 else "")
                if ours and JUSTIFICATION not in comments:
                    found.append(f"{child.lineno}: {ast.unparse(child)}")
            visit(child, in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef))

    visit(ast.parse(source), False)
    return found


def test_the_core_imports_its_modules_at_the_top() -> None:
    folder = PACKAGES["viscorig"]
    offenders = [
        f"{path.relative_to(ROOT)}:{where}"
        for path in sorted(folder.rglob("*.py"))
        for where in unjustified_local_imports(path.read_text(encoding="utf-8"))
    ]
    assert not offenders, (
        "import these at the top of the module, or say why not in a '# keeps ...' comment: "
        + "; ".join(offenders)
    )


def test_the_local_import_detector() -> None:
    source = (
        "import viscorig.errors\n"
        "def f():\n"
        "    from viscorig.fitting import fit\n"
        "    import json\n"
        "    class C:\n"
        "        def g(self):\n"
        "            from . import numbers\n"
        "def h():\n"
        "    # keeps the command's start fast: scipy\n"
        "    from viscorig.identify import store_fit\n"
        "    from viscorig.planning import design_bound\n"
        "    x = 1\n"
        "    from viscorig.models import parse_spec\n"
        "    from viscorig.strain import payne  # keeps the start fast\n"
    )
    assert unjustified_local_imports(source) == [
        "3: from viscorig.fitting import fit",
        "7: from . import numbers",
        "13: from viscorig.models import parse_spec",
    ]


def test_the_local_imports_keep_what_they_say_out() -> None:
    """The modules whose local imports keep a command's start fast load none of scipy,
    matplotlib or the web server when imported, and ``import viscorig`` loads no numpy."""
    probe = (
        "import sys, viscorig\n"
        "assert 'numpy' not in sys.modules, 'import viscorig loads numpy'\n"
        "import viscorig.acquisition, viscorig.sequences, viscorig.cli.bench, viscorig.cli.show\n"
        "import viscorig.cli.exchange, viscorig.cli.plan, viscorig.cli.run, viscorig.cli.check\n"
        "heavy = {'scipy', 'matplotlib', 'starlette', 'uvicorn'} & set(sys.modules)\n"
        "assert not heavy, sorted(heavy)\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 0, done.stderr
