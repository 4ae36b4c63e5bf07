"""The JSON metric report every subcommand writes with ``--report``.

Layout (see ``report.schema.json`` beside this file)::

    {"command": str, "geoproc_version": str, "created": ISO-8601 UTC,
     "inputs": [{"path": str, "sha256": hex}], "params": {...},
     "metrics": {name: number | bool | str | null}, "timings_s": {name: seconds}}

Non-finite floats are not valid JSON: they are stored as null, and their
count is reported by the command as a metric of its own where it matters.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from functools import cache
from importlib import resources

import numpy as np

import geoproc


def json_safe(value):
    """Convert numpy scalars/arrays, tuples and non-finite floats for JSON."""
    kind = type(value)  # the plain types first: a critical-cell table holds millions of them
    if kind is int or kind is str or kind is bool or value is None:
        return value
    if kind is float:
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k if type(k) is str else str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating | float):
        v = float(value)
        return v if math.isfinite(v) else None
    return value


def json_bytes(value) -> bytes:
    """``value`` as JSON text (UTF-8, ``json.dumps``'s separators), the text
    ``json.dumps(json_safe(value))`` gives for documents whose keys are strings
    (every document geoproc writes).

    A document of plain finite numbers, strings, lists and dicts (a
    critical-cell table of a large mesh: millions of entries) goes straight to
    the C encoder, numpy scalars and arrays through its ``default``; a
    document with a non-finite float, or a key the encoder refuses, is walked
    by :func:`json_safe` first.
    """
    def plain(v):
        if isinstance(v, np.ndarray | np.generic):
            return json_safe(v)
        raise TypeError(f"{type(v).__name__} is not JSON serializable")

    try:
        text = json.dumps(value, allow_nan=False, default=plain)
    except (ValueError, TypeError):  # a non-finite float (stored as null), a numpy key
        text = json.dumps(json_safe(value))
    return text.encode()


def build_report(
    command: str,
    inputs: list[dict],
    params: dict,
    metrics: dict,
    timings_s: dict,
    checks: list[dict] | None = None,
) -> dict:
    """Assemble a report dict (JSON-safe) for ``command``.

    Parameters
    ----------
    command : str
        Subcommand name, e.g. ``"info"``.
    inputs : list of {"path": str, "sha256": str}
    params : dict
        The options the run used, defaults included.
    metrics : dict
        Scalar results (numbers, booleans, strings or None).
    timings_s : dict of str to float
        Wall-clock seconds per phase; ``total`` covers the whole run.
    checks : list of {"check": str, "passed": bool}, optional
        The run's ``--check`` gates and their outcomes (the key is left out
        when there are none).
    """
    report = {
        "command": command,
        "geoproc_version": geoproc.__version__,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "inputs": inputs,
        "params": params,
        "metrics": metrics,
        "timings_s": timings_s,
    }
    if checks:
        report["checks"] = checks
    return json_safe(report)


def report_json(report: dict) -> str:
    """Serialize a report (strict JSON: no NaN or Infinity)."""
    return json.dumps(report, indent=2, allow_nan=False) + "\n"


@cache
def report_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a report."""
    text = resources.files("geoproc.report").joinpath("report.schema.json").read_text()
    return json.loads(text)


def validate_report(report: dict) -> None:
    """Raise ``jsonschema.ValidationError`` when ``report`` breaks the schema."""
    import jsonschema

    jsonschema.validate(report, report_schema())
