"""The report summary of ``make demo``: ``python -m geoproc_cli.report_table FOLDER``."""

from __future__ import annotations

import json

import pytest

from geoproc_cli.report_table import main


def _write(folder, name, obj):
    (folder / name).write_text(obj if isinstance(obj, str) else json.dumps(obj))


def test_long_names_wrap_and_are_never_cut(tmp_path, capsys, monkeypatch):
    # off a terminal the table is 160 wide: three reports in one long folder had all been shown
    # as the same 'armadillo_scan_.../geodesic_heat_…'
    monkeypatch.setenv("COLUMNS", "160")
    sub = tmp_path / "armadillo_scan_highres_remeshed_v3" / "geodesic_heat_runs_with_long_names"
    sub.mkdir(parents=True)
    long_input = "scan_of_the_stanford_bunny_reconstructed_with_poisson_depth_ten_final.ply"
    for s in ("0.5", "1", "2"):
        _write(sub, f"time_factor_{s}.json", {"command": "info", "metrics": {"genus": 0},
                                              "inputs": [{"path": long_input, "sha256": "0"}]})
    assert main(["report_table", str(tmp_path), "-r"]) == 0
    rows = [line.split("│") for line in capsys.readouterr().out.splitlines() if line.startswith("│")]
    names, inputs = "".join(r[1].strip() for r in rows), "".join(r[3].strip() for r in rows)
    for s in ("0.5", "1", "2"):
        assert f"armadillo_scan_highres_remeshed_v3/geodesic_heat_runs_with_long_names/time_factor_{s}.json" in names
    assert inputs == long_input * 3


def test_table_lists_reports_and_skips_other_json(tmp_path, capsys):
    _write(tmp_path, "a.json", {"command": "example", "metrics": {"mean_relative_error": 0.0123, "nested": {"x": 1}},
                                "inputs": [{"path": "/x/torus.ply", "sha256": "0"}], "timings_s": {"total": 1.5}})
    _write(tmp_path, "critical.json", {"critical": []})  # not a report
    _write(tmp_path, "notes.json", "not json")
    assert main(["report_table", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "a.json" in out and "torus.ply" in out and "mean_relative_error=0.0123" in out and "1.50" in out
    assert "critical.json" not in out and "notes.json" not in out


def test_the_checks_column_names_failed_gates(tmp_path, capsys):
    good, bad = {"check": "genus==1", "passed": True}, {"check": "faces<10", "passed": False}
    _write(tmp_path, "a.json", {"command": "info", "metrics": {"genus": 1}, "checks": [good, bad]})
    _write(tmp_path, "b.json", {"command": "info", "metrics": {"genus": 1}, "checks": [good]})
    _write(tmp_path, "c.json", {"command": "info", "metrics": {"genus": 1}, "checks": "x"})  # left blank
    assert main(["report_table", str(tmp_path)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "1 of 2 failed: faces<10" in out and "1 passed" in out


def test_reports_named_in_capitals_are_read_and_json_past_the_parser_limits_is_skipped(tmp_path, capsys):
    # --report accepts R.JSON, which the table had not looked at ("no geoproc reports"); an
    # integer of 5000 digits and arrays nested 100,000 deep had raised ValueError and
    # RecursionError (a traceback, exit 1)
    _write(tmp_path, "T.JSON", {"command": "info", "metrics": {"genus": 1}})
    _write(tmp_path, "big.json", '{"command": "big", "metrics": {"n": ' + "9" * 5000 + "}}")
    _write(tmp_path, "deep.json", "[" * 100000 + "]" * 100000)
    # a total past the doubles' range is left blank (formatting it had raised OverflowError)
    huge = '{"command": "huge", "metrics": {"m": 1}, "timings_s": {"total": 1' + "0" * 400 + "}}"
    _write(tmp_path, "huge.json", huge)
    assert main(["report_table", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "T.JSON" in out and "genus=1" in out and "big" not in out and "deep" not in out and "huge" in out


@pytest.mark.parametrize("report", [
    {"command": "x", "metrics": {"rmse": 0.5}, "inputs": [{"p": "x"}]},
    {"command": "x", "metrics": {"rmse": 0.5}, "inputs": None},
    {"command": "x", "metrics": {"rmse": 0.5}, "timings_s": None},
    {"command": "x", "metrics": {"rmse": 0.5}, "timings_s": {"total": "x"}},
])
def test_malformed_fields_of_a_report_are_left_blank(tmp_path, capsys, report):
    # these raised AttributeError / KeyError / TypeError / ValueError (a traceback, exit 1)
    _write(tmp_path, "a.json", report)
    assert main(["report_table", str(tmp_path)]) == 0
    assert "rmse=0.5" in capsys.readouterr().out


@pytest.mark.parametrize("metrics", [[1, 2], None, "x"])
def test_a_report_whose_metrics_are_not_an_object_is_not_a_report(tmp_path, capsys, metrics):
    _write(tmp_path, "a.json", {"command": "x", "metrics": metrics})
    (tmp_path / "b.json").mkdir()  # a folder named like a report: IsADirectoryError before
    assert main(["report_table", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no geoproc reports" in err and len(err.strip().splitlines()) == 1


def test_bad_folder_arguments_exit_2_with_one_line(tmp_path, capsys):
    # a missing folder, a file and an option printed an empty table with exit 0
    (tmp_path / "f.json").write_text("{}")
    for args in ([str(tmp_path / "nope")], [str(tmp_path / "f.json")], ["--bogus"], ["a", "b"]):
        assert main(["report_table", *args]) == 2
        err = capsys.readouterr().err
        assert err.startswith("report_table: error:") and len(err.strip().splitlines()) == 1
    assert main(["report_table", "--help"]) == 0
    assert "usage:" in capsys.readouterr().out


def test_missing_and_non_folder_arguments_are_told_apart(tmp_path, capsys):
    # a folder that does not exist had been called "not a folder"
    (tmp_path / "f.json").write_text("{}")
    assert main(["report_table", str(tmp_path / "nope")]) == 2
    assert capsys.readouterr().err.strip().endswith("nope: no such folder")
    assert main(["report_table", str(tmp_path / "f.json")]) == 2
    assert capsys.readouterr().err.strip().endswith("f.json: not a folder")


def test_a_full_standard_output_and_a_termination_are_one_error_line(tmp_path):
    # a full disk gave rich's OSError traceback and exit 1; SIGTERM a KeyboardInterrupt traceback
    import os
    import subprocess
    import sys

    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full on this system")
    _write(tmp_path, "a.json", {"command": "x", "metrics": {"rmse": 0.5}})
    with open("/dev/full", "w") as full:
        p = subprocess.run([sys.executable, "-m", "geoproc_cli.report_table", str(tmp_path)], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=60)
    assert p.returncode == 2
    assert p.stderr == "report_table: error: cannot write standard output: No space left on device\n"
    with open("/dev/full", "w") as full:  # --help too
        p = subprocess.run([sys.executable, "-m", "geoproc_cli.report_table", "--help"], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=60)
    assert p.returncode == 2 and p.stderr.startswith("report_table: error: cannot write standard output"), p.stderr
    script = ("import os, signal, sys\n"
              "from geoproc_cli import report_table\n"
              "report_table.summary_table = lambda *a, **k: os.kill(os.getpid(), signal.SIGTERM)\n"
              "sys.exit(report_table.run(['report_table', sys.argv[1]]))\n")
    p = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert p.returncode == 143 and p.stderr == "report_table: error: terminated (SIGTERM)\n", p.stderr


def test_csv_has_a_column_per_name_and_every_digit(tmp_path, capsys):
    import csv

    folder = tmp_path / "reports"
    folder.mkdir()
    x = 0.1 + 0.2  # 0.30000000000000004: the CSV keeps every digit
    _write(folder, "a.json", {"command": "example", "geoproc_version": "1.2", "params": {"method": "heat", "t": 2},
                              "metrics": {"faces": 10, "mean_relative_error": x, "note": None},
                              "inputs": [{"path": "/x/a.ply"}, {"path": "/x/b.npy"}],
                              "checks": [{"check": "faces<9", "passed": False}], "timings_s": {"total": 1.5}})
    _write(folder, "b.json", {"command": "other", "metrics": {"genus": 2, "closed": True, "faces": 4}})
    _write(folder, "other.json", {"critical": []})
    out = tmp_path / "r.csv"
    assert main(["report_table", str(folder), "--csv", str(out)]) == 0
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert [r["report"] for r in rows] == ["a.json", "b.json"]
    header = out.read_text().splitlines()[0].split(",")
    # metrics: the headline names first (mean_relative_error before faces), then as they appear
    assert header.index("metrics.mean_relative_error") < header.index("metrics.genus") < header.index(
        "metrics.faces") < header.index("metrics.note")
    a, b = rows
    assert float(a["metrics.mean_relative_error"]) == x and a["metrics.faces"] == "10"
    assert a["metrics.note"] == "" and a["metrics.genus"] == "" and b["metrics.closed"] == "true"
    assert a["inputs"] == "/x/a.ply;/x/b.npy" and a["checks_failed"] == "1" and b["checks_failed"] == ""
    assert a["params.method"] == "heat" and b["params.method"] == "" and a["timings_s.total"] == "1.5"
    assert a["geoproc_version"] == "1.2" and b["command"] == "other"
    capsys.readouterr()
    assert main(["report_table", str(folder), "--csv", "-"]) == 0
    assert capsys.readouterr().out == out.read_text()


def test_csv_arguments_and_unwritable_files_exit_2_with_one_line(tmp_path, capsys):
    _write(tmp_path, "a.json", {"command": "info", "metrics": {"genus": 0}})
    for args in (["--csv"], [str(tmp_path), "--csv"], ["--csv=", str(tmp_path)],
                 [str(tmp_path), "--csv", "a.csv", "--csv", "b.csv"], [str(tmp_path), "extra"]):
        assert main(["report_table", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("report_table: error: usage:")
    assert main(["report_table", str(tmp_path), "--csv", str(tmp_path / "a.json")]) == 2  # never over a report
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a.json: the name must end in .csv" in err[0]
    assert json.loads((tmp_path / "a.json").read_text())["command"] == "info"
    # nor through a link named .csv (symbolic or hard) to a report, written through before
    import os

    os.symlink("a.json", tmp_path / "s.csv")
    os.link(tmp_path / "a.json", tmp_path / "h.csv")
    (tmp_path / "other").mkdir()  # a report it does not read is not written over either
    _write(tmp_path / "other", "c.json", {"command": "info", "metrics": {"genus": 0}})
    os.symlink("other/c.json", tmp_path / "o.csv")
    os.symlink("other/new.json", tmp_path / "d.csv")  # dangling: writing through it makes a .json
    for name in ("s.csv", "h.csv", "o.csv", "d.csv"):
        assert main(["report_table", str(tmp_path), "--csv", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        what = "is the report" if name in ("s.csv", "h.csv") else "is a link to"
        assert len(err) == 1 and f"--csv {tmp_path / name}: {what}" in err[0], err
        assert json.loads((tmp_path / "a.json").read_text())["command"] == "info"
    assert json.loads((tmp_path / "other" / "c.json").read_text())["command"] == "info"
    assert not (tmp_path / "other" / "new.json").exists()
    missing = tmp_path / "no" / "r.csv"
    assert main(["report_table", str(tmp_path), f"--csv={missing}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0] and "cannot write" in err[0]
    assert not missing.parent.exists()


def test_csv_keeps_file_names_that_are_not_utf8(tmp_path, capsys):
    # a report of an input named with a byte that is not UTF-8 holds it as a lone surrogate:
    # written back as that byte, as on standard output (it had been a UnicodeEncodeError)
    import json as _json

    (tmp_path / "r.json").write_text(_json.dumps({"command": "info", "metrics": {"genus": 0},
                                                  "inputs": [{"path": "t\udcff.ply"}]}))
    out = tmp_path / "r.csv"
    assert main(["report_table", str(tmp_path), "--csv", str(out)]) == 0
    assert b"t\xff.ply" in out.read_bytes()


def test_names_that_are_not_utf8_on_a_strict_standard_output(tmp_path):
    # under a UTF-8 locale standard output is strict: a report naming a file with a byte that
    # is not UTF-8 had made the table and --csv - end in a UnicodeEncodeError traceback
    import os
    import subprocess
    import sys

    (tmp_path / "r.json").write_text(json.dumps({"command": "info", "metrics": {"genus": 0},
                                                 "inputs": [{"path": "t\udcff.ply"}]}))
    env = {**os.environ, "PYTHONIOENCODING": "utf-8:strict", "COLUMNS": "200"}
    for extra in ([], ["--csv", "-"]):
        p = subprocess.run([sys.executable, "-m", "geoproc_cli.report_table", str(tmp_path), *extra],
                           capture_output=True, env=env, timeout=60)
        assert p.returncode == 0, p.stderr.decode()
        assert (b"t\xff.ply" if extra else b"t\\udcff.ply") in p.stdout


def test_recursive_reads_the_reports_in_subfolders(tmp_path, capsys):
    # a batch writing out/<mesh>/<run>.json: -r gives one row per report, named by its path below the folder
    for sub, rmse in (("bunny", 0.25), ("cow/heat", 0.5), (".hidden", 9.0)):
        (tmp_path / sub).mkdir(parents=True)
        _write(tmp_path / sub, "r.json", {"command": "example", "metrics": {"rmse": rmse}})
    _write(tmp_path, "top.json", {"command": "example", "metrics": {"rmse": 0.125}})
    (tmp_path / "loop").symlink_to(tmp_path, target_is_directory=True)  # not followed: no endless walk
    assert main(["report_table", str(tmp_path), "--csv", "-", "-r"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["bunny/r.json", "cow/heat/r.json", "top.json"]
    assert [r.rsplit(",", 1)[-1] for r in rows[1:]] == ["0.25", "0.5", "0.125"]
    assert main(["report_table", "--recursive", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "cow/heat/r.json" in out and "bunny/r.json" in out and ".hidden" not in out
    assert main(["report_table", str(tmp_path), "--csv", "-"]) == 0  # without -r: the folder's own
    assert [r.split(",")[0] for r in capsys.readouterr().out.splitlines()[1:]] == ["top.json"]
    (tmp_path / "top.json").unlink()
    assert main(["report_table", str(tmp_path)]) == 2
    assert "no geoproc reports (*.json with command and metrics); -r also reads its subfolders" in \
        capsys.readouterr().err
    assert main(["report_table", str(tmp_path / "cow" / "heat"), "-r"]) == 0
    capsys.readouterr()
    (tmp_path / "cow" / "heat" / "r.json").unlink()
    assert main(["report_table", str(tmp_path / "cow" / "heat")]) == 2  # no subfolder: no hint
    assert capsys.readouterr().err.rstrip().endswith("(*.json with command and metrics)")


def test_folders_that_cannot_be_read_are_named(tmp_path, capsys, monkeypatch):
    # an unreadable subfolder had been skipped without a word; an unreadable folder itself
    # was blamed on standard output ("cannot write standard output: Permission denied")
    import os

    for sub in ("open", "locked"):
        (tmp_path / sub).mkdir()
        _write(tmp_path / sub, "r.json", {"command": "example", "metrics": {"rmse": 0.5}})
    scandir = os.scandir

    def refusing(path="."):
        if "locked" in str(path):
            raise PermissionError(13, "Permission denied", str(path))
        return scandir(path)

    monkeypatch.setattr(os, "scandir", refusing)
    assert main(["report_table", str(tmp_path), "-r", "--csv", "-"]) == 0
    captured = capsys.readouterr()
    assert [r.split(",")[0] for r in captured.out.splitlines()[1:]] == ["open/r.json"]
    assert f"report_table: {tmp_path / 'locked'}: cannot read the folder (Permission denied)" in captured.err
    assert main(["report_table", str(tmp_path / "locked")]) == 2
    assert capsys.readouterr().err == (f"report_table: error: {tmp_path / 'locked'}: cannot read the folder "
                                       "(Permission denied)\n")


def test_the_command_column_names_the_method(tmp_path, capsys):
    # runs of one command over several methods had read alike but for the report's name
    for name, method in (("a.json", "log-heat"), ("b.json", None), ("c.json", 3)):
        params = {"method": method} if method is not None else {}
        _write(tmp_path, name, {"command": "example", "params": params, "metrics": {"rmse": 0.5}})
    assert main(["report_table", str(tmp_path)]) == 0
    lines = [" ".join(line.split()) for line in capsys.readouterr().out.splitlines()]
    row = {n: next(line for line in lines if n in line) for n in ("a.json", "b.json", "c.json")}
    assert "example -m log-heat" in row["a.json"]
    assert "-m" not in row["b.json"] and "-m" not in row["c.json"]  # none, or not a name: the command alone
