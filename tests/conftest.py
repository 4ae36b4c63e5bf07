"""Shared pytest fixtures: the project's generated fixtures and ../shared/data."""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


@functools.cache
def load_fixture_module(name: str = "make_fixtures"):
    """Import ``fixtures/<name>.py`` (the project's deterministic input generators)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "fixtures" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _load_fixture_module():
    return load_fixture_module("make_fixtures")


@pytest.fixture(scope="session")
def fixture_dir(tmp_path_factory) -> Path:
    """Folder with every file fixtures/make_fixtures.py generates (made once per run)."""
    out = tmp_path_factory.mktemp("fixtures")
    _load_fixture_module().make_all(out)
    return out


@pytest.fixture(scope="session")
def make_fixtures():
    """The fixtures/make_fixtures.py module (its generators: icosphere, torus, grid, cube)."""
    return _load_fixture_module()


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` beside the project root; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA} (tests on real meshes need ../shared)")
    return SHARED_DATA


def run_cli(*args: str, stdin: bytes | None = None, cwd: Path | None = None):
    """Run the real ``geoproc`` command line in a subprocess.

    Returns the CompletedProcess with bytes ``stdout`` and text ``stderr``
    (decoded as UTF-8) so tests can check exit codes and one-line messages.
    """
    import subprocess
    import sys

    proc = subprocess.run(
        [sys.executable, "-m", "geoproc_cli.main", *map(str, args)],
        input=stdin,
        capture_output=True,
        cwd=cwd,
        timeout=600,
    )
    proc.stderr = proc.stderr.decode("utf-8", "replace")
    return proc


def run_cli_under(script: str, *args):
    """Run ``python -c script args`` (a script that sets up what it injects,
    then calls geoproc's entry point, which reads ``args``), text output."""
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-c", script, *map(str, args)], capture_output=True, text=True,
                          timeout=120)


@pytest.fixture(scope="session")
def cli():
    """The :func:`run_cli` helper, as a fixture."""
    return run_cli
