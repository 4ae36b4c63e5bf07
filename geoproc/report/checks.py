"""Metric gates: ``--check 'name<=value'`` compares ``metrics[name]`` with a number."""

from __future__ import annotations

import difflib
import math
import operator
import re
from collections.abc import Collection, Mapping
from dataclasses import dataclass

from geoproc.errors import UsageError

_OPS = {"<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne, "<": operator.lt,
        ">": operator.gt}
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")  # ASCII, finite
_SPLIT_OPERATOR = re.compile(r"^\s*[A-Za-z_][A-Za-z0-9_.]*\s*([<>=!])\s+=\s*\S+\s*$")
_PATTERN = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_.]*)\s*(<=|>=|==|!=|<|>)\s*(\S*)\s*$")


@dataclass(frozen=True)
class Check:
    """One gate: ``metric op value``."""

    metric: str
    op: str
    value: float
    text: str

    def passes(self, measured: float) -> bool:
        """True when ``measured op value`` holds (NaN never passes, != included)."""
        return measured == measured and bool(_OPS[self.op](measured, self.value))


def parse_check(text: str) -> Check:
    """Parse ``'name<=value'`` (operators <=, <, >=, >, ==, !=); UsageError if malformed."""
    split = _SPLIT_OPERATOR.match(text)
    if split and split.group(1) + "=" in _OPS:  # 'x< =1', 'x < = 1', 'x= =1'
        raise UsageError(f"--check '{text}': a space splits the operator '{split.group(1)}='; write it without one")
    m = _PATTERN.match(text)
    if not m:
        raise UsageError(
            f"--check '{text}': expected NAME OP NUMBER with OP one of <=, <, >=, >, ==, != "
            "(for example 'rmse<=0.01')"
        )
    name, op, raw = m.groups()
    if not raw:  # 'x<=' would otherwise read as 'x' < '='
        raise UsageError(f"--check '{text}': no number after '{op}'")
    if raw[:1] in "<>=!":  # 'genus<>1', 'x<<=1', 'x==!1': an operator not in the list
        extra = re.match(r"[<>=!]+", raw).group(0)
        raise UsageError(f"--check '{text}': unknown operator '{op}{extra}'; use <=, <, >=, >, == or !=")
    if not _NUMBER.fullmatch(raw) or not math.isfinite(float(raw)):
        raise UsageError(f"--check '{text}': '{raw}' is not a finite decimal number")
    if float(raw) == 0 and re.search(r"[1-9]", raw.lower().split("e")[0]):  # 1e-400 reads as 0
        raise UsageError(f"--check '{text}': '{raw}' is too small for a double (it would compare as 0)")
    return Check(name, op, float(raw), text.strip())


def require_known_metrics(checks: list[Check], names: Collection[str], command: str,
                          needs: Mapping[str, Collection[str]] | None = None,
                          text: Collection[str] = ()) -> None:
    """Refuse a check on a metric that ``command`` never reports, will not
    report without an option that was not given, or reports as text, before
    any work is done.

    Parameters
    ----------
    checks : list of Check
    names : collection of str
        Every metric name the command can report (which of them a run reports
        depends on its options: :func:`evaluate_checks` judges what is left afterwards).
    command : str
        The subcommand, for the message.
    needs : mapping of str to collection of str, optional
        For each option not given (e.g. ``"--reference"``), the metrics only it reports.
    text : collection of str
        The metrics among ``names`` whose values are text (a method's name):
        a check compares numbers, so it cannot hold on them.

    Raises
    ------
    UsageError
        Naming the first unknown metric, the closest known name when one is
        close, and the command's metric names (those that are not text); the
        option a metric needs; or a metric that is text.
    """
    for c in checks:
        if c.metric in text:
            raise UsageError(f"--check '{c.text}': {command}'s metric '{c.metric}' is text, not a number "
                             "(--check compares numbers)")
        option = next((o for o, gated in (needs or {}).items() if c.metric in gated), None)
        if option is not None:
            raise UsageError(f"--check '{c.text}': {command} reports '{c.metric}' only with {option}")
        if c.metric in names:
            continue
        numbers = sorted(n for n in names if n not in text)  # the names a check can hold on
        close = difflib.get_close_matches(c.metric, numbers, n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        raise UsageError(f"--check '{c.text}': {command} reports no metric '{c.metric}'{hint}; "
                         f"its metrics: {', '.join(numbers)}")


def evaluate_checks(checks: list[Check], metrics: dict, subject: str | None = None) -> list[str]:
    """Compare every check with ``metrics``.

    Parameters
    ----------
    checks : list of Check
    metrics : dict of str to number, bool or None
    subject : str, optional
        What the run was on (its first input), named in each line after
        ``check failed:``, so that runs a Makefile starts at once can be told apart.

    Returns
    -------
    list of str
        One line per failed check (empty when all pass).

    Raises
    ------
    UsageError
        A check names a metric this run did not report (listing the names it did;
        a name the command never reports is refused before the run, by
        :func:`require_known_metrics`),
        or a metric that is text. A metric that is None, NaN or infinite (not
        measured; null in the report) fails its check.
    """
    unknown = [c.metric for c in checks if c.metric not in metrics]
    if unknown:
        names = ", ".join(sorted(k for k, v in metrics.items() if not isinstance(v, str)))
        raise UsageError(f"--check: metric '{unknown[0]}' was not reported by this run (it depends on the "
                         f"input's content); this run reports: {names}")
    text = [c for c in checks if isinstance(metrics[c.metric], str)]
    if text:
        raise UsageError(f"--check '{text[0].text}': metric '{text[0].metric}' is not a number "
                         f"(it is '{metrics[text[0].metric]}')")
    return [line for line in (_failure(c, metrics, subject) for c in checks) if line is not None]


def check_records(checks: list[Check], metrics: dict) -> list[dict]:
    """``[{"check": text, "passed": bool}]``, one per check in the order given,
    for the report (checks :func:`evaluate_checks` has accepted)."""
    return [{"check": c.text, "passed": _failure(c, metrics) is None} for c in checks]


def _failure(c: Check, metrics: dict, subject: str | None = None) -> str | None:
    """The line that tells how ``c`` failed on ``metrics`` (naming ``subject``
    when given), or None when it passed."""
    head = "check failed: " if subject is None else f"check failed: {subject}: "
    measured = _numeric(metrics[c.metric])
    if measured is None:
        return f"{head}{c.text} (not measured in this run: null in the report)"
    if c.passes(measured):
        return None
    # every digit: 0.0376518 could hide a miss of <=0.037651843221598626; a count as the
    # count, a flag as the flag (false had read 0.0)
    raw = metrics[c.metric]
    shown = raw if isinstance(raw, int) else measured
    return f"{head}{c.text} (measured: {shown!r})"


def _numeric(value) -> float | None:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, int | float):
        # NaN and infinities are stored as null in the report: not measured
        return float(value) if math.isfinite(value) else None
    return None
