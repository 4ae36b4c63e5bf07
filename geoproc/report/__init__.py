"""Metric reports (``--report``) and metric gates (``--check``)."""

from geoproc.report.checks import Check, check_records, evaluate_checks, parse_check, require_known_metrics
from geoproc.report.report import build_report, json_bytes, json_safe, report_schema, validate_report

__all__ = [
    "Check",
    "build_report",
    "check_records",
    "evaluate_checks",
    "json_bytes",
    "json_safe",
    "parse_check",
    "report_schema",
    "require_known_metrics",
    "validate_report",
]
