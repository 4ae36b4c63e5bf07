"""Shared helpers for the wos tests: the fixtures/wos_fixtures.py module."""

import functools
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@functools.cache
def wos_fixtures():
    spec = importlib.util.spec_from_file_location("wos_fixtures", ROOT / "fixtures" / "wos_fixtures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
