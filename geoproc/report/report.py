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
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
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


def build_report(
    command: str,
    inputs: list[dict],
    params: dict,
    metrics: dict,
    timings_s: dict,
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
    """
    return json_safe(
        {
            "command": command,
            "geoproc_version": geoproc.__version__,
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
            "inputs": inputs,
            "params": params,
            "metrics": metrics,
            "timings_s": timings_s,
        }
    )


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
