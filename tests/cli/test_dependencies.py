"""The runtime dependencies in pyproject.toml against what geoproc and its
command line import.

A module imported by ``geoproc/`` or ``cli/`` and missing from the runtime
dependencies breaks a plain ``pip install geoproc``; a runtime dependency that
nothing imports costs every install its download (pymeshlab, 280 MB, had been
one: only tests and benchmarks use it).
"""

from __future__ import annotations

import ast
import importlib.metadata as md
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

OPTIONAL = {"cvxpy": "test", "clarabel": "test"}
"""Imported only by ``geodesic --solver cvxpy`` (and log-splitting), which refuses
with a pointer to the extra when they are missing."""

INDIRECT = {"charset-normalizer": "trimesh decodes STL text and headers that are not UTF-8 with it"}
"""Runtime dependencies that geoproc never imports itself."""


def _normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement_names(requirements: list[str]) -> set[str]:
    return {_normalized(re.match(r"[A-Za-z0-9_.-]+", r).group(0)) for r in requirements}


def _imported_top_level_modules() -> set[str]:
    found = set()
    for folder in ("geoproc", "cli"):
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Import):
                    found |= {alias.name.split(".")[0] for alias in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    found.add(node.module.split(".")[0])
    return {m for m in found if m not in sys.stdlib_module_names and m not in ("geoproc", "geoproc_cli")}


def _distributions_of_imports() -> dict[str, str]:
    """Top-level module -> its distribution's normalized name (installed ones only)."""
    owners = md.packages_distributions()
    return {m: _normalized(owners[m][0]) for m in _imported_top_level_modules() if m in owners}


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def test_every_imported_distribution_is_a_runtime_dependency_or_a_guarded_extra():
    project = _project()
    runtime = _requirement_names(project["dependencies"])
    imports = _distributions_of_imports()
    assert set(imports) == _imported_top_level_modules(), "a module geoproc imports is not installed"
    missing = {m: d for m, d in imports.items() if d not in runtime and m not in OPTIONAL}
    assert not missing, f"imported but not a runtime dependency: {missing}"
    for module, extra in OPTIONAL.items():
        assert imports.get(module) in _requirement_names(project["optional-dependencies"][extra])


def test_every_runtime_dependency_is_imported_or_named_as_indirect():
    runtime = _requirement_names(_project()["dependencies"])
    used = set(_distributions_of_imports().values()) | set(INDIRECT)
    assert runtime - used == set(), "runtime dependencies nothing imports"
    assert set(INDIRECT) <= runtime


def test_the_peer_libraries_are_extras_only():
    project = _project()
    runtime = _requirement_names(project["dependencies"])
    for peer in ("pymeshlab", "potpourri3d", "gudhi", "fcpw"):
        assert peer not in runtime
    assert "pymeshlab" in _requirement_names(project["optional-dependencies"]["test"])
    assert "pymeshlab" in _requirement_names(project["optional-dependencies"]["bench"])
