"""The dependency rules of the shared design, checked on the source tree."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: package folder -> top-level imports it must never make
FORBIDDEN = {
    "sim/rigsim": {"viscorig"},
    "drivers/agilent35670a": {"viscorig", "rigsim"},
    "drivers/eurotherm3200": {"viscorig", "rigsim"},
}


def imported_top_levels(path: Path) -> set[str]:
    """Top-level package names that a Python file imports (absolute imports only)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_imported_top_levels_sees_both_import_forms(tmp_path: Path) -> None:
    source = tmp_path / "m.py"
    source.write_text("import viscorig.models\nfrom rigsim import engine\nfrom . import x\n")
    assert imported_top_levels(source) == {"viscorig", "rigsim"}


@pytest.mark.parametrize("folder", sorted(FORBIDDEN))
def test_package_respects_dependency_rules(folder: str) -> None:
    files = sorted((ROOT / folder).rglob("*.py"))
    assert files, f"{folder} holds no Python file"
    offenders = [
        f"{path.relative_to(ROOT)} imports {sorted(imported_top_levels(path) & FORBIDDEN[folder])}"
        for path in files
        if imported_top_levels(path) & FORBIDDEN[folder]
    ]
    assert not offenders, "; ".join(offenders)


def test_every_package_folder_is_installed() -> None:
    """Every folder with an __init__.py under the three roots is a package setup.py lists."""
    from setuptools import find_packages

    found = {
        *find_packages(str(ROOT / "src")),
        *find_packages(str(ROOT / "drivers")),
        *find_packages(str(ROOT / "sim"), include=["rigsim", "rigsim.*"]),
    }
    for root, below in (("src", "src"), ("drivers", "drivers"), ("sim", "sim/rigsim")):
        for init in (ROOT / below).rglob("__init__.py"):
            name = ".".join(init.parent.relative_to(ROOT / root).parts)
            assert name in found, f"{init.parent.relative_to(ROOT)} is not an installed package"
