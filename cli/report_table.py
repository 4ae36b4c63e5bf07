"""Print a summary table of geoproc JSON reports: ``python -m geoproc_cli.report_table DIR``,
or write them all as CSV with ``--csv OUT.csv``.

Used by ``make demo``; reads every ``*.json`` in DIR that is a geoproc report.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

HEADLINE = (
    "mean_relative_error", "pearson_r", "rmse", "mae", "max_abs_error", "bias",
    "mean_normal_angle_deg", "flipped_faces", "hausdorff", "f1", "precision", "recall",
    "pairs_kept", "pairs_removed", "max_abs_change", "steps_per_second",
    "genus", "euler_characteristic", "components", "boundary_loops", "vertices", "faces",
)
SKIP_PREFIXES = ("input_", "merged_", "removed_", "triangulated_")


def headline_metrics(metrics: dict) -> list[tuple[str, float]]:
    """Numeric metrics, the well-known accuracy/topology names first."""
    numeric = {k: v for k, v in metrics.items()
               if isinstance(v, int | float) and not isinstance(v, bool) and not k.startswith(SKIP_PREFIXES)}
    first = [(k, numeric[k]) for k in HEADLINE if k in numeric]
    rest = [(k, v) for k, v in numeric.items() if k not in HEADLINE]
    return first + rest


def _shown_value(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _input_names(rep: dict) -> str:
    """The input files' names; entries without a path show as ``?``."""
    inputs = rep.get("inputs")
    if not isinstance(inputs, list):
        return ""
    return ", ".join(Path(i["path"]).name if isinstance(i, dict) and isinstance(i.get("path"), str) else "?"
                     for i in inputs)


def _total_seconds(rep: dict) -> str:
    timings = rep.get("timings_s")
    total = timings.get("total") if isinstance(timings, dict) else None
    if not isinstance(total, int | float) or isinstance(total, bool):
        return ""
    try:
        return f"{total:.2f}"
    except OverflowError:  # an integer past the doubles' range (a hand-edited report)
        return ""


def read_report(path: Path) -> dict | None:
    """The report in ``path``, or None when it is not a geoproc report (not
    JSON, not an object with ``command`` and a ``metrics`` object). Raises
    OSError when the file cannot be read."""
    try:
        rep = json.loads(path.read_bytes())
    except (ValueError, RecursionError):  # not JSON, not UTF-8, an integer past 4300 digits, nested too deep
        return None
    if not isinstance(rep, dict) or "command" not in rep or not isinstance(rep.get("metrics"), dict):
        return None
    return rep


def folder_reports(folder: Path, recursive: bool = False) -> tuple[list[tuple[Path, dict]], list[str]]:
    """Every geoproc report in ``folder`` (``*.json``, any case, sorted by
    name; with ``recursive``, in its subfolders too, sorted by path, not
    entering hidden folders nor following links to folders) with its path,
    and one note per such file that could not be read."""
    reports, notes = [], []
    paths, unread = _json_files(folder, recursive)
    notes += [f"{f}: cannot read the folder ({e.strerror or e})" for f, e in unread]
    for path in paths:
        if not path.is_file():
            continue
        try:
            rep = read_report(path)
        except OSError as e:
            notes.append(f"{path}: cannot read ({e.strerror or e})")
            continue
        if rep is not None:
            reports.append((path, rep))
    return reports, notes


def _json_files(folder: Path, recursive: bool) -> tuple[list[Path], list[tuple[str, OSError]]]:
    """The ``*.json`` names (any case, as --report accepts them) in ``folder``,
    sorted; with ``recursive`` also those in its subfolders, by their path
    below ``folder`` (the parts compared in turn). Also the folders that could
    not be listed, with the error."""
    unread: list[tuple[str, OSError]] = []
    if not recursive:
        try:
            return sorted(p for p in folder.iterdir() if p.suffix.lower() == ".json"), unread
        except OSError as exc:
            return [], [(str(folder), exc)]
    found = []

    def unlisted(exc: OSError) -> None:
        unread.append((exc.filename or str(folder), exc))

    for root, dirs, files in os.walk(folder, onerror=unlisted):  # followlinks=False: no loop
        dirs[:] = [d for d in dirs if not d.startswith(".")]
        found += [Path(root) / f for f in files if Path(f).suffix.lower() == ".json"]
    return sorted(found, key=lambda p: p.relative_to(folder).parts), unread


def summary_table(folder: Path, max_metrics: int = 5, recursive: bool = False) -> tuple[Table, int, list[str]]:
    """One row per report in ``folder`` (and its subfolders with ``recursive``):
    its path below ``folder``, command, input, a few metrics, total time.

    Returns the table, the number of reports in it and one note per
    ``*.json`` file that could not be read."""
    from geoproc_cli.common import escaped  # undecodable bytes in names shown escaped, as in error lines

    t = Table(title=Text(escaped(f"geoproc reports in {folder}")))
    for col in ("report", "command", "input", "metrics", "checks", "total s"):
        # names wrap, never cut: long ones had been cut to the same text ('runs/time_…' three times)
        t.add_column(col, overflow="fold" if col in ("report", "input") else "ellipsis")
    reports, notes = folder_reports(folder, recursive)
    for path, rep in reports:
        shown = [f"{k}={_shown_value(v)}" for k, v in headline_metrics(rep["metrics"])][:max_metrics]
        t.add_row(Text(escaped(_report_name(path, folder))), Text(escaped(_command_shown(rep))),
                  Text(escaped(_input_names(rep))), Text(escaped(" ".join(shown))),
                  _check_summary(rep), _total_seconds(rep))
    return t, len(reports), notes


def _command_shown(rep: dict) -> str:
    """The command, with its method when the report's params name one
    (``geodesic -m log-heat``): runs of one command differ most by it."""
    params = rep.get("params")
    method = params.get("method") if isinstance(params, dict) else None
    return f"{rep['command']} -m {method}" if isinstance(method, str) and method else str(rep["command"])


def _report_name(path: Path, folder: Path) -> str:
    """The report's path below ``folder`` (its name, for one directly in it)."""
    return path.relative_to(folder).as_posix()


def _csv_value(v) -> str:
    """A report value as CSV text: numbers as JSON writes them (every digit),
    true/false, empty for null or absent, lists and objects as JSON."""
    if v is None:
        return ""
    if isinstance(v, str):
        return v
    return json.dumps(v, separators=(",", ":"), allow_nan=True)


def reports_csv(reports: list[tuple[Path, dict]], folder: Path | None = None) -> str:
    """One CSV row per report: ``report`` (its path below ``folder``, its name
    without one), ``command``, ``geoproc_version``, ``created``,
    ``inputs`` (paths joined by ``;``), ``checks_failed`` (count, empty
    without checks), then a column ``params.NAME``, ``metrics.NAME`` and
    ``timings_s.NAME`` for every name in any report (metrics in the order of
    :data:`HEADLINE`, then as they first appear). A cell is empty where a
    report lacks the name or holds null."""
    import csv
    import io

    def names(section: str) -> list[str]:
        seen: dict[str, None] = {}
        for _, rep in reports:
            block = rep.get(section)
            if isinstance(block, dict):
                seen.update(dict.fromkeys(block))
        if section == "metrics":
            return [k for k in HEADLINE if k in seen] + [k for k in seen if k not in HEADLINE]
        return list(seen)

    sections = [(sec, names(sec)) for sec in ("params", "metrics", "timings_s")]
    header = ["report", "command", "geoproc_version", "created", "inputs", "checks_failed"]
    header += [f"{sec}.{k}" for sec, keys in sections for k in keys]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(header)
    for path, rep in reports:
        inputs = rep.get("inputs")
        paths = [i["path"] for i in inputs if isinstance(i, dict) and isinstance(i.get("path"), str)] \
            if isinstance(inputs, list) else []
        checks = rep.get("checks")
        failed = sum(1 for c in checks if not (isinstance(c, dict) and c.get("passed") is True)) \
            if isinstance(checks, list) and checks else None
        name = _report_name(path, folder) if folder is not None else path.name
        row = [name, *(_csv_value(rep.get(k)) for k in ("command", "geoproc_version", "created")), ";".join(paths),
               _csv_value(failed)]
        for sec, keys in sections:
            block = rep.get(sec) if isinstance(rep.get(sec), dict) else {}
            row += [_csv_value(block.get(k)) for k in keys]
        w.writerow(row)
    return out.getvalue()


def _check_summary(rep: dict) -> Text:
    """``2 passed``, ``1 of 2 failed`` (and which), or blank: the report's ``checks``."""
    checks = rep.get("checks")
    if not isinstance(checks, list) or not checks:
        return Text("")
    failed = [str(c.get("check")) for c in checks if isinstance(c, dict) and c.get("passed") is not True]
    if not failed:
        return Text(f"{len(checks)} passed")
    return Text(f"{len(failed)} of {len(checks)} failed: {', '.join(failed)}", style="bold red")


USAGE = ("usage: python -m geoproc_cli.report_table [FOLDER] [-r|--recursive] [--csv OUT.csv|-]  "
         "(FOLDER default out/demo)")
HELP = """Prints one row per geoproc JSON report in FOLDER.
  -r, --recursive  also the reports in FOLDER's subfolders (not hidden ones,
                   not through links to folders); rows named by their path
                   below FOLDER
  --csv OUT.csv    write every report's params, metrics and timings as CSV
                   instead (one row per report, one column per name; - for
                   standard output)"""


def _arguments(args: list[str]) -> tuple[str | None, str | None, bool] | None:
    """(folder, csv path, recursive) from the arguments, None when they are not usable."""
    folder, csv_path, recursive, i = None, None, False, 0
    while i < len(args):
        a = args[i]
        if a in ("-r", "--recursive") and not recursive:
            recursive, i = True, i + 1
        elif a == "--csv" and i + 1 < len(args) and csv_path is None:
            csv_path, i = args[i + 1], i + 2
        elif a.startswith("--csv=") and csv_path is None:
            csv_path, i = a[len("--csv="):], i + 1
        elif folder is None and not a.startswith("-"):
            folder, i = a, i + 1
        else:
            return None
    if csv_path == "":
        return None
    return folder, csv_path, recursive


def main(argv: list[str]) -> int:
    """Print the table of the reports in the folder argument, or write them
    as CSV with ``--csv``. Exit 0; 2 for a bad argument, a missing folder or
    one without reports, or a CSV file that cannot be written (one line on
    stderr)."""
    args = argv[1:]
    if args and args[0] in ("-h", "--help"):
        print(USAGE + "\n" + HELP)
        return 0
    parsed = _arguments(args)
    if parsed is None:
        print(f"report_table: error: {USAGE}", file=sys.stderr)
        return 2
    folder = Path(parsed[0]) if parsed[0] else Path("out/demo")
    csv_path, recursive = parsed[1], parsed[2]
    if csv_path is not None and csv_path != "-" and not csv_path.lower().endswith(".csv"):
        # (a report's own .json among them is then never overwritten)
        print(f"report_table: error: --csv {csv_path}: the name must end in .csv (or be - for standard output)",
              file=sys.stderr)
        return 2
    if not folder.is_dir():
        what = "not a folder" if folder.exists() else "no such folder"
        print(f"report_table: error: {folder}: {what}", file=sys.stderr)
        return 2
    try:
        with os.scandir(folder) as entries:
            next(entries, None)
    except OSError as exc:  # (had been blamed on standard output)
        print(f"report_table: error: {folder}: cannot read the folder ({exc.strerror or exc})", file=sys.stderr)
        return 2
    if csv_path is not None:
        reports, notes = folder_reports(folder, recursive)
        count = len(reports)
    else:
        table, count, notes = summary_table(folder, recursive=recursive)
    for note in notes:
        print(f"report_table: {note}", file=sys.stderr)
    if not count:
        where = " in it or its subfolders" if recursive else \
            "; -r also reads its subfolders" if _has_subfolders(folder) else ""
        print(f"report_table: error: {folder}: no geoproc reports (*.json with command and metrics){where}",
              file=sys.stderr)
        return 2
    if csv_path is not None:
        clash = _report_at(csv_path, [path for path, _ in reports])
        if clash is not None:  # a link named .csv to a report had been written through, over the report
            what = (f"is the report {clash} (through a link)" if clash in [p for p, _ in reports]
                    else f"is a link to {clash}, a .json file")
            print(f"report_table: error: --csv {csv_path}: {what}; write the CSV elsewhere", file=sys.stderr)
            return 2
        return _write_csv(csv_path, reports_csv(reports, folder))
    console = Console()
    if not console.is_terminal:
        console = Console(width=160)
    console.print(table)
    return 0


def _report_at(csv_path: str, paths: list[Path]) -> Path | None:
    """The report among ``paths`` that the file ``csv_path`` is (a symbolic or
    a hard link to it), or the ``.json`` file a symbolic link ``csv_path``
    leads to (a report elsewhere, which writing through the link would
    replace), else None (also for ``-`` and a file not yet made)."""
    if csv_path == "-":
        return None
    target = os.path.realpath(csv_path)
    if os.path.islink(csv_path) and target.lower().endswith(".json"):  # (a dangling one too: it makes the file)
        return Path(target)
    if not os.path.exists(csv_path):
        return None
    for path in paths:
        try:
            if os.path.samefile(csv_path, path):
                return path
        except OSError:
            continue
    return None


def _has_subfolders(folder: Path) -> bool:
    try:
        return any(p.is_dir() and not p.name.startswith(".") for p in folder.iterdir())
    except OSError:
        return False


def _write_csv(path: str, text: str) -> int:
    """Write the CSV to ``path`` (a temporary file renamed into place) or to
    standard output for ``-``; 2 with one line when the file cannot be written."""
    data = text.encode("utf-8", "surrogateescape")  # names that are not UTF-8 come back as they were stored
    if path == "-":
        sys.stdout.flush()
        sys.stdout.buffer.write(data)
        return 0
    from geoproc.fileio import write_bytes_atomic

    try:
        write_bytes_atomic(path, data)
    except OSError as e:
        print(f"report_table: error: {path}: cannot write ({e.strerror or e})", file=sys.stderr)
        return 2
    return 0


def run(argv: list[str]) -> int:
    """:func:`main`, with Ctrl-C or a termination signal one error line and
    status 130 or 128 + the signal's number, as for geoproc's commands."""
    from geoproc_cli.entry import install_signal_handlers, interruption_line, outputs_committed

    install_signal_handlers()
    try:
        code = main(argv)
        sys.stdout.flush()
        outputs_committed()  # a signal from here on would only misreport a finished run
        return code
    except KeyboardInterrupt as exc:
        text, code = interruption_line(exc)
        print(f"report_table: error: {text}", file=sys.stderr)
        return code
    except OSError as exc:  # standard output full or closed (the table, or --help): one line
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, "w")  # nothing left to flush at exit  # noqa: SIM115
        print(f"report_table: error: cannot write standard output: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(run(sys.argv))
