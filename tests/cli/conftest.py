"""Checks every command-line test gets: each report a test leaves in its
``tmp_path`` names only metrics its subcommand declares (the ``METRICS`` tuple
of its ``cli`` module, against which ``--check`` names are judged before a run),
none that is declared to need an option the run was not given, and text
values exactly for the metrics declared as text (``TEXT_METRICS``)."""

from __future__ import annotations

import json

import pytest

from geoproc_cli import denoise, geodesic, info, morse_simplify, perturb, wos_solve

MODULES = {"denoise": denoise, "geodesic": geodesic, "info": info, "morse-simplify": morse_simplify,
           "perturb": perturb, "wos-solve": wos_solve}
DECLARED = {command: module.METRICS for command, module in MODULES.items()}


# (command, parameter, metrics reported only when the parameter is set): what --check refuses early without it
GATED = (("denoise", "reference", denoise.REFERENCE_METRICS),
         ("geodesic", "reference", geodesic.REFERENCE_METRICS),
         ("wos-solve", "exact", wos_solve.EXACT_METRICS),
         ("morse-simplify", "barycentric", morse_simplify.BARYCENTRIC_METRICS))


def text_metrics(command: str) -> set[str]:
    """The metrics ``command`` declares as text (its module's ``TEXT_METRICS``; none when absent)."""
    return set(getattr(MODULES[command], "TEXT_METRICS", ()))


def undeclared_metrics(path) -> list[str]:
    """Metric names in the report at ``path`` that its subcommand does not declare,
    that it reports without the option they are declared to need, or whose
    value is text where the name is not declared as text or the reverse
    (empty for files that are not geoproc reports, or reports of other commands)."""
    if not path.is_file():  # a FIFO named like a report would block the read
        return []
    try:
        rep = json.loads(path.read_text())
    except (OSError, ValueError, RecursionError):
        return []
    if not isinstance(rep, dict) or rep.get("command") not in DECLARED or not isinstance(rep.get("metrics"), dict):
        return []
    names = set(rep["metrics"])
    extra = names - set(DECLARED[rep["command"]])
    for command, param, gated in GATED:
        if rep["command"] == command and not rep.get("params", {}).get(param):
            extra |= names & set(gated)
    text = text_metrics(rep["command"])
    extra |= {k for k, v in rep["metrics"].items() if isinstance(v, str) != (k in text) and v is not None}
    return sorted(extra)


@pytest.fixture(autouse=True)
def _reports_name_declared_metrics(tmp_path):
    yield
    for path in sorted(p for p in tmp_path.rglob("*") if p.suffix.lower() == ".json"):
        extra = undeclared_metrics(path)
        assert not extra, (f"{path.name}: metrics undeclared, reported without the option they need, "
                           f"or text where not declared so (or the reverse): {extra}")
