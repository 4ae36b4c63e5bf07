"""Checks every command-line test gets: each report a test leaves in its
``tmp_path`` names only metrics its subcommand declares (the ``METRICS`` tuple
of its ``cli`` module, against which ``--check`` names are judged before a run)."""

from __future__ import annotations

import json

import pytest

from geoproc_cli import denoise, geodesic, info, morse_simplify, perturb, wos_solve

DECLARED = {"denoise": denoise.METRICS, "geodesic": geodesic.METRICS, "info": info.METRICS,
            "morse-simplify": morse_simplify.METRICS, "perturb": perturb.METRICS, "wos-solve": wos_solve.METRICS}


def undeclared_metrics(path) -> list[str]:
    """Metric names in the report at ``path`` that its subcommand does not declare
    (empty for files that are not geoproc reports, or reports of other commands)."""
    try:
        rep = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return []
    if not isinstance(rep, dict) or rep.get("command") not in DECLARED or not isinstance(rep.get("metrics"), dict):
        return []
    return sorted(set(rep["metrics"]) - set(DECLARED[rep["command"]]))


@pytest.fixture(autouse=True)
def _reports_name_declared_metrics(tmp_path):
    yield
    for path in sorted(tmp_path.rglob("*.json")):
        extra = undeclared_metrics(path)
        assert not extra, f"{path.name}: metrics missing from the command's METRICS: {extra}"
