"""The command-line contract, through the real `geoproc` executable and the shared harness."""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from geoproc.errors import InputError
from geoproc.mesh import Mesh, load_mesh, read_mesh_bytes
from geoproc.report import validate_report
from geoproc_cli.common import CheckOpt, ReportOpt, command_run, metrics_epilog
from geoproc_cli.main import app
from tests.conftest import run_cli_under

BAD_INPUTS = [
    ("truncated.ply", "PLY header declares 42 vertex rows and 80 face rows (at least 1088 bytes)"),
    ("nan.ply", "non-finite coordinates"),
    ("out_of_range.obj", "face index out of range"),
    ("empty.obj", "no faces"),
]


def _one_error_line(stderr: str, path: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    assert lines[0].startswith(f"error: {path}: "), lines[0]
    return lines[0]


@pytest.mark.parametrize("name, fragment", BAD_INPUTS)
def test_bad_input_exits_2_with_one_line_and_no_report(cli, fixture_dir, tmp_path, name, fragment):
    path = str(fixture_dir / name)
    report = tmp_path / "r.json"
    p = cli("info", path, "--report", report)
    assert p.returncode == 2
    assert fragment in _one_error_line(p.stderr, path)
    assert not report.exists() and list(tmp_path.iterdir()) == []
    assert p.stdout == b""


def test_missing_file_unknown_extension_and_folder(cli, tmp_path):
    for path, fragment in [
        (tmp_path / "missing.ply", "no such file"),
        (tmp_path / "mesh.xyz", "unknown mesh format"),
        (tmp_path, "folder holds no frame meshes"),  # info reads a folder as an animation's frames
    ]:
        if path.suffix == ".xyz":
            path.write_text("0 0 0\n")
        p = cli("info", path)
        assert p.returncode == 2, p.stderr
        assert fragment in _one_error_line(p.stderr, str(path))


def test_info_table_shows_names_as_given(cli, tmp_path):
    # the file name and property names went to rich as markup: '[/x]' ended in
    # MarkupError (exit 3) and '[red]' vanished from the title
    folder = tmp_path / "d["
    folder.mkdir()
    header = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nproperty float [/q]\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n")
    for name in ("d[/x].ply", "d[/[red]x.ply"):  # relative to tmp_path
        (tmp_path / name).write_text(header)
        p = cli("info", name, "--quiet", cwd=tmp_path)
        assert p.returncode == 0, p.stderr
        out = p.stdout.decode()
        assert out.splitlines()[0].strip() == name and "[/q]" in out, out


def test_info_table_escapes_what_is_not_printable(cli, tmp_path):
    # a newline or an escape sequence in the file name or a property name reached the terminal
    name = "a\nb\x1b[31m\u2028.ply"
    (tmp_path / name).write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                 "property float z\nproperty float q\x1b[31mred\nelement face 1\n"
                                 "property list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 1\n0 1 0 1\n"
                                 "3 0 1 2\n", encoding="utf-8")
    p = cli("info", name, "--quiet", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    out = p.stdout.decode()
    assert out.splitlines()[0].strip() == "a\\nb\\x1b[31m\\u2028.ply" and "\x1b" not in out, out
    assert "q\\x1b[31mred" in out


def test_a_malformed_stored_stl_normal_is_ignored_quietly(cli, tmp_path):
    # trimesh logged 'failed to extract face_normals' with a traceback on stderr, even with --quiet
    facet = "facet normal {n}\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n endloop\nendfacet\n"
    path = tmp_path / "n.stl"
    path.write_text("solid s\n" + facet.format(n="0 0 1x") + facet.format(n="0 0 1") + "endsolid s\n")
    p = cli("info", path, "--quiet", "--no-clean", "--json")
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert '"faces": 2' in p.stdout.decode()


def test_debug_shows_the_traceback(cli, fixture_dir):
    p = cli("info", fixture_dir / "nan.ply", "--debug")
    assert p.returncode == 2 and "Traceback" in p.stderr and "InputError" in p.stderr


def test_report_is_valid_and_hashes_the_input(cli, fixture_dir, tmp_path):
    mesh = fixture_dir / "torus.ply"
    report = tmp_path / "r.json"
    p = cli("info", mesh, "--report", report, "--quiet")
    assert p.returncode == 0, p.stderr
    rep = json.loads(report.read_text())
    validate_report(rep)
    assert rep["command"] == "info"
    assert rep["inputs"] == [{"path": str(mesh), "sha256": hashlib.sha256(mesh.read_bytes()).hexdigest()}]
    assert rep["metrics"]["genus"] == 1 and rep["timings_s"]["total"] > 0
    assert rep["params"] == {"mesh": str(mesh), "json": False, "clean": True}  # --json had been left out
    # -0 is recorded as 0 (perturb --noise -0 had read -0.0)
    p = cli("perturb", mesh, "--noise", "-0", "--seed", "1", "-o", tmp_path / "z.ply", "--report", report)
    assert p.returncode == 0 and '"noise": 0.0,' in report.read_text()


def test_checks_gate_the_exit_code(cli, fixture_dir, tmp_path):
    mesh = fixture_dir / "torus.ply"
    ok = cli("info", mesh, "--check", "genus==1", "--check", "vertices>1000")
    assert ok.returncode == 0, ok.stderr
    report = tmp_path / "r.json"
    bad = cli("info", mesh, "--check", "genus==0", "--check", "faces<10", "--check", "vertices>1",
              "--report", report)
    assert bad.returncode == 1
    lines = bad.stderr.strip().splitlines()
    # each names the input, which tells runs apart under make -j (error lines named it, check lines had not)
    assert len(lines) == 2 and lines[0].startswith(f"check failed: {mesh}: genus==0") and "faces<10" in lines[1]
    rep = json.loads(report.read_text())
    validate_report(rep)  # the run itself succeeded
    # the report tells a failed gate from a passing one (it had recorded no check at all)
    assert rep["checks"] == [{"check": "genus==0", "passed": False}, {"check": "faces<10", "passed": False},
                             {"check": "vertices>1", "passed": True}]
    cli("info", mesh, "--report", report)
    assert "checks" not in json.loads(report.read_text())  # none given: no key


def test_unknown_metric_and_malformed_check_are_usage_errors(cli, fixture_dir, tmp_path):
    report = tmp_path / "r.json"
    p = cli("info", fixture_dir / "torus.ply", "--check", "nonsense<1", "--report", report)
    assert p.returncode == 2 and "info reports no metric 'nonsense'" in p.stderr
    assert not report.exists()
    # a metric only an option not given reports: refused before the run as well
    out = tmp_path / "g.ply"
    p = cli("geodesic", tmp_path / "missing.ply", "-s", "0", "-o", out, "--check", "rmse<1")
    assert p.returncode == 2 and p.stderr == "error: --check 'rmse<1': geodesic reports 'rmse' only with --reference\n"
    # so is one that depends on the method (iterations: log-ode with lu or newton only)
    p = cli("geodesic", tmp_path / "missing.ply", "-s", "0", "-o", out, "--check", "iterations<9")
    assert p.returncode == 2 and p.stderr == ("error: --check 'iterations<9': geodesic reports 'iterations' only "
                                              "with -m log-ode --solver lu or newton\n")
    # one that depends on the input's content (f1 needs an 'outlier' property) is refused once the
    # input is read, before the work (it had been judged after the scoring), and nothing is written
    cloud = tmp_path / "cloud.ply"
    cloud.write_text("ply\nformat ascii 1.0\nelement vertex 20\nproperty float x\nproperty float y\n"
                     "property float z\nend_header\n" + "".join(f"{i} {i % 3} {i % 5}\n" for i in range(20)))
    p = cli("denoise", cloud, "--outliers", "--k", "8", "-o", out, "--check", "f1>=0.9", "--report", report)
    assert p.returncode == 2 and p.stderr == (f"error: --check on f1: {cloud} has no 'outlier' property to score "
                                              "against (perturb --outliers writes one)\n"), p.stderr
    assert not out.exists() and not report.exists()
    moving = tmp_path / "moving.npz"
    np.savez(moving, vertices=np.random.default_rng(1).random((4, 30, 3)), faces=np.zeros((0, 3), int))
    p = cli("denoise", moving, "--outliers", "-o", tmp_path / "m.npz", "--check", "recall>=0.9", "--check",
            "precision>0")
    assert p.returncode == 2 and "error: --check on precision, recall: " in p.stderr and "moving.npz has no" in p.stderr
    p = cli("info", fixture_dir / "torus.ply", "--check", "genus=1")
    assert p.returncode == 2 and "--check 'genus=1'" in p.stderr


def test_an_empty_output_name_is_refused_as_such(cli, fixture_dir, tmp_path):
    # os.path.realpath('') is the working folder: the refusal had read 'is a folder'
    p = cli("perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", "")
    assert p.returncode == 2 and p.stderr == "error: an output file name is empty\n", p.stderr
    # --report was a Path option, and Path('') is '.': it had read '--report .: must end in .json'
    p = cli("info", fixture_dir / "torus.ply", "--report", "")
    assert p.returncode == 2 and p.stderr == "error: --report: the file name is empty\n", p.stderr
    out = tmp_path / "m.ply"
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", "x", "-p", "0.1", "-o", out, "--diagram", "")
    assert p.returncode == 2 and "empty" in p.stderr and not out.exists(), p.stderr


@pytest.mark.parametrize(("command", "args", "typo", "closest"), [
    ("info", [], "genuss==1", "genus"),
    ("geodesic", ["-s", "0", "-o", "o.ply"], "rmsee<=0.1", "rmse"),
    ("denoise", ["-o", "o.ply"], "mean_normal_angle<=2", "mean_normal_angle_deg"),
    ("perturb", ["--seed", "1", "-o", "o.ply"], "rms_displacemnt<1", "rms_displacement"),
    ("morse-simplify", ["-f", "z", "-p", "0.1", "-o", "o.ply"], "minima==1", "minima_after"),
    ("wos-solve", ["--boundary", "x", "-o", "u.exr"], "rmse_<0.1", "rmse"),
])
def test_a_metric_the_command_never_reports_is_refused_before_the_input_is_read(cli, tmp_path, command, args,
                                                                                  typo, closest):
    # the input does not exist: the check is judged first, so a batch job fails at once, not after the work
    missing = tmp_path / ("missing.json" if command == "wos-solve" else "missing.ply")
    p = cli(command, missing, *args, "--check", typo, "--report", tmp_path / "r.json", cwd=tmp_path)
    name = typo.split("<")[0].split("=")[0]
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith(f"error: --check '{typo}': {command} reports no metric '{name}' "
                               f"(did you mean '{closest}'?); its metrics: "), p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "missing" not in p.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("command", "args", "check", "option"), [
    ("denoise", ["-o", "o.ply"], "new_flipped_faces==0", "--reference"),
    ("wos-solve", ["--boundary", "x", "-o", "u.exr"], "rmse<0.1", "--exact"),
    ("morse-simplify", ["-f", "z", "-p", "0.1", "-o", "o.ply"], "subdivision_vertices>0", "--barycentric"),
])
def test_a_metric_that_needs_an_option_not_given_is_refused_before_the_input_is_read(cli, tmp_path, command, args,
                                                                                      check, option):
    missing = tmp_path / ("missing.json" if command == "wos-solve" else "missing.ply")
    p = cli(command, missing, *args, "--check", check, cwd=tmp_path)
    name = check.split("<")[0].split("=")[0].split(">")[0]
    assert p.returncode == 2
    assert p.stderr == f"error: --check '{check}': {command} reports '{name}' only with {option}\n"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("command", "args", "check"), [
    ("geodesic", ["-s", "0", "-o", "o.ply"], "method==1"),
    ("geodesic", ["-s", "0", "-o", "o.ply"], "operators>=0"),
    ("denoise", ["-o", "o.ply"], "feature_method==0"),
    ("denoise", ["--dynamic", "-o", "o.npz"], "coherence==1"),
])
def test_a_metric_that_is_text_is_refused_before_the_input_is_read(cli, tmp_path, command, args, check):
    p = cli(command, tmp_path / "missing.ply", *args, "--check", check, cwd=tmp_path)
    name = check.split("<")[0].split("=")[0].split(">")[0]
    assert p.returncode == 2
    assert p.stderr == (f"error: --check '{check}': {command}'s metric '{name}' is text, not a number "
                        "(--check compares numbers)\n")
    assert list(tmp_path.iterdir()) == []


def test_report_and_critical_need_json_names(cli, fixture_dir, tmp_path):
    p = cli("info", fixture_dir / "torus.ply", "--report", tmp_path / "r.txt")
    assert p.returncode == 2 and "r.txt: must end in .json (or be -)" in p.stderr
    assert list(tmp_path.iterdir()) == []
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", "z", "-p", "0.1", "-o", tmp_path / "m.ply",
            "--critical", tmp_path / "c.png")
    assert p.returncode == 2 and "--critical" in p.stderr and "must end in .json" in p.stderr
    assert list(tmp_path.iterdir()) == []


def test_report_into_missing_folder_is_a_usage_error(cli, fixture_dir, tmp_path):
    p = cli("info", fixture_dir / "torus.ply", "--report", tmp_path / "no" / "r.json")
    assert p.returncode == 2 and "does not exist" in p.stderr


def test_stdin_input_and_clean_stdout(cli, fixture_dir):
    data = (fixture_dir / "torus.ply").read_bytes()
    p = cli("info", "-", "--json", stdin=data)
    assert p.returncode == 0, p.stderr
    info = json.loads(p.stdout)  # stdout holds the result only
    assert info["genus"] == 1


def test_an_animation_on_stdin_is_named(cli, tmp_path):
    # animations are read from files or folders only; an .npz piped in had been "cannot tell
    # the mesh format"
    import numpy as np

    npz = tmp_path / "a.npz"
    np.savez(npz, vertices=np.zeros((2, 3, 3)), faces=np.array([[0, 1, 2]]))
    p = cli("perturb", "-", "--noise", "0.1", "--seed", "1", "-o", tmp_path / "o.npz", stdin=npz.read_bytes())
    assert p.returncode == 2 and not (tmp_path / "o.npz").exists()
    assert p.stderr.strip() == ("error: -: looks like a .npz animation; animations are read from a file or "
                                "folder, not from standard input")


def test_notes_go_to_stderr_and_quiet_silences_them(cli, tmp_path):
    path = tmp_path / "dup.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nv 9 9 9\nv 1 1 0\nf 1 2 3\nf 4 6 3\n")
    p = cli("info", path, "--json")
    assert p.returncode == 0 and p.stderr.splitlines() == [
        f"note: {path}: merged 1 coincident vertices, dropped 1 unreferenced vertices "
        "(--no-clean keeps the mesh as stored)"]
    info = json.loads(p.stdout)
    assert info["vertices"] == 4
    load = {k: info["load"][k] for k in ("input_vertices", "input_faces", "merged_vertices",
                                         "removed_unreferenced_vertices")}  # the report's names
    assert load == {"input_vertices": 6, "input_faces": 2, "merged_vertices": 1, "removed_unreferenced_vertices": 1}
    q = cli("info", path, "--json", "--quiet")
    assert q.stderr == "" and json.loads(q.stdout)["vertices"] == 4
    raw = cli("info", path, "--json", "--no-clean", "--quiet")
    assert json.loads(raw.stdout)["vertices"] == 6


def test_a_failed_run_prints_its_error_line_alone(cli, tmp_path):
    path = tmp_path / "points.obj"  # merging leaves one point: notes, then a degenerate mesh
    path.write_text("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n")
    p = cli("geodesic", path, "-s", "0", "-o", tmp_path / "d.ply")
    assert p.returncode == 2 and "every face has zero area" in _one_error_line(p.stderr, str(path))


def test_every_option_of_every_command_has_help():
    root = typer.main.get_command(app)
    assert root.commands, "no subcommands registered"
    for name, command in root.commands.items():
        assert command.help, name
        for param in command.params:
            if param.param_type_name == "option":
                assert param.help and len(param.help) > 10, f"{name} {param.opts}"
        result = CliRunner().invoke(app, [name, "--help"])
        assert result.exit_code == 0, name
        # the closing paragraph lists the metric names --check accepts, then the text ones
        module = importlib.import_module(f"geoproc_cli.{name.replace('-', '_')}")
        text = getattr(module, "TEXT_METRICS", ())
        units = getattr(module, "METRIC_UNITS", None)
        assert command.epilog == metrics_epilog(module.METRICS, text, units), name
        assert set(text) <= set(module.METRICS), name
        for names in units or ():  # the units name metrics the command reports
            assert {n.strip() for n in names.split(",")} - {"mean_relative_error (= mae)"} <= set(module.METRICS), names
        for metric in module.METRICS:
            assert (f" {metric}," in command.epilog or f" {metric}." in command.epilog), (name, metric)


def test_every_single_value_option_given_twice_is_refused():
    # the parser kept the last one: -o a -o b wrote only b, --seed 1 --seed 2 ran seed 2
    from geoproc_cli.main import command

    root = command()
    checked = 0
    for name, sub in root.commands.items():
        for param in sub.params:
            if param.param_type_name != "option" or param.is_flag:
                continue
            opt = param.opts[-1]
            if param.multiple or param.count:
                continue
            with pytest.raises(Exception) as err:
                sub.make_context(name, [opt, "1", param.opts[0], "2"])
            assert " ".join(err.value.format_message().split()) == (
                f"{' / '.join(param.opts)} given more than once; it takes one value"), (name, opt)
            checked += 1
    assert checked >= 60  # 60 when this test was written


def test_repeatable_options_and_repeated_flags_stay_allowed(cli, fixture_dir, tmp_path):
    out, r1, r2 = tmp_path / "d.ply", tmp_path / "r1.json", tmp_path / "r2.json"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-s", "5", "--check", "max_distance<=100",
            "--check", "mean_distance<=100", "-q", "-q", "-o", out)
    assert p.returncode == 0, p.stderr
    p = cli("perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", tmp_path / "a.ply", "--report", r1,
            "--report", r2)
    assert p.returncode == 2 and p.stderr.startswith(
        "error: --report given more than once; it takes one value (see '") and p.stderr.count("\n") == 1
    assert not any(f.exists() for f in (tmp_path / "a.ply", r1, r2))


def test_flags_show_no_value_in_help(cli):
    # typer labelled every flag <bool> in the value column, as if --quiet took a value
    # (--quiet true was then refused as an extra argument)
    root = typer.main.get_command(app)
    flags = [(name, p.opts[0]) for name, c in root.commands.items() for p in c.params
             if p.param_type_name == "option" and p.is_flag]
    assert len(flags) >= 20  # 26 when this test was written
    for name, opt in flags:
        p = next(q for q in root.commands[name].params if q.opts[0] == opt)
        assert p.metavar == "", (name, opt)
    # nor --help itself, in the command the console script runs
    for args in [[name, "--help"] for name in root.commands] + [["--help"]]:
        p = cli(*args)
        assert p.returncode == 0 and b"--help" in p.stdout and b"<bool>" not in p.stdout, (args, p.stdout)


def test_top_level_help_lists_every_exit_status():
    import signal

    from geoproc_cli.entry import Terminated

    codes = {0, 1, 2, 3, 128 + signal.SIGINT, Terminated(signal.SIGTERM).exit_code,
             Terminated(signal.SIGHUP).exit_code}
    assert codes == {0, 1, 2, 3, 129, 130, 143}
    text = " ".join(app.info.help.split())
    for code in codes:
        assert f" {code} " in text, code


def test_options_taking_one_of_a_few_names_show_them_in_help():
    from geoproc.denoise import COHERENCE, METHODS
    from geoproc.perturb import DIRECTIONS
    from geoproc_cli.denoise import FEATURE_RULES

    root = typer.main.get_command(app)
    shown = {(name, p.opts[0]): p.metavar for name, c in root.commands.items() for p in c.params}
    assert shown[("denoise", "--method")] == "<bilateral|guided|rpca>" == "<" + "|".join(METHODS) + ">"
    assert shown[("denoise", "--features")] == "<" + "|".join(FEATURE_RULES) + ">"
    assert shown[("denoise", "--coherence")] == "<" + "|".join(COHERENCE) + ">"
    assert shown[("perturb", "--direction")] == "<normal|random>" == "<" + "|".join(DIRECTIONS) + ">"


# ---- the harness itself, on a small command that writes a mesh -------------

def _toy_app() -> typer.Typer:
    toy = typer.Typer()

    @toy.command()
    def flip(mesh: str, output: str = typer.Option(..., "-o"), fail: bool = False, huge: bool = False,
             interrupt: bool = False, report: ReportOpt = None, check: CheckOpt = None) -> None:
        with command_run("flip", {"fail": fail}, report=report, checks=check) as run:
            m = run.load_mesh(mesh)
            run.write_mesh(output, Mesh(m.V, m.F[:, ::-1], {"one": m.V[:, 0] * 0 + 1}))
            run.metrics["faces"] = len(m.F)
            if fail:
                raise InputError(mesh, "refused after writing")
            if huge:
                raise MemoryError("Unable to allocate 74.5 GiB for an array")
            if interrupt:  # Ctrl-C inside a numba kernel reaches Python as a SystemError caused by it
                try:
                    raise KeyboardInterrupt
                except KeyboardInterrupt as exc:
                    raise SystemError("CPUDispatcher(<function wos_dirichlet>) returned a result with an "
                                      "exception set") from exc

    return toy


def test_outputs_are_written_only_when_the_run_succeeds(fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out), "--fail"])
    assert res.exit_code == 2 and not out.exists() and list(tmp_path.iterdir()) == []
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out),
                                          "--check", "missing<1"])
    assert res.exit_code == 2 and not out.exists()
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out)])
    assert res.exit_code == 0 and load_mesh(out).vertex_fields["one"].sum() == 1152


def test_ctrl_c_inside_a_compiled_kernel_is_an_interruption(fixture_dir, tmp_path):
    # it was reported as "internal error: SystemError ..." with exit 3
    out = tmp_path / "o.ply"
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out), "--interrupt"])
    assert res.exit_code == 130 and res.stderr.strip() == "error: interrupted" and not out.exists()


def test_dash_output_is_binary_ply_on_stdout(fixture_dir):
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", "-"])
    assert res.exit_code == 0
    m = read_mesh_bytes(res.stdout_bytes, "ply")
    assert res.stdout_bytes.startswith(b"ply\nformat binary_little_endian")
    assert m.F.shape == (2304, 3) and "one" in m.vertex_fields


def test_missing_output_folder_is_a_usage_error(fixture_dir, tmp_path):
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(tmp_path / "x" / "o.ply")])
    assert res.exit_code == 2 and not Path(tmp_path / "x").exists()


def test_unwritable_report_leaves_no_output_and_files_get_the_umask_mode(fixture_dir, tmp_path):
    out, folder = tmp_path / "o.ply", tmp_path / "r.json"
    folder.mkdir()  # the report path is a folder: nothing may be written
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out),
                                          "--report", str(folder)])
    assert res.exit_code == 2 and "cannot write" in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"] and list(folder.iterdir()) == []
    as_ply = tmp_path / "d.ply"
    as_ply.mkdir()
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(as_ply)])
    assert res.exit_code == 2 and "is a folder" in res.output and list(as_ply.iterdir()) == []
    as_ply.rmdir()
    old = os.umask(0o022)
    try:
        res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out)])
    finally:
        os.umask(old)
    assert res.exit_code == 0 and stat.S_IMODE(out.stat().st_mode) == 0o644


def test_parser_errors_and_non_finite_options_are_one_line_usage_errors(cli, fixture_dir, tmp_path):
    mesh = str(fixture_dir / "cube.ply")
    for args in (["perturb", mesh, "--seed", "-1", "-o", tmp_path / "o.ply"],
                 ["perturb", mesh, "--seed", "1", "--bogus", "-o", tmp_path / "o.ply"],
                 ["perturb", mesh, "--seed", "1", "--noise", "inf", "-o", tmp_path / "o.ply"],
                 ["denoise", mesh, "--sigma-r", "nan", "-o", tmp_path / "o.ply"],
                 ["geodesic", mesh, "-s", "99999999999999999999", "-o", tmp_path / "o.ply"],
                 ["denoise", mesh, "--vertex-iterations", "99999999999999999999", "-o", tmp_path / "o.ply"],
                 ["wos-solve", mesh, "--grid", "100000", "--boundary", "x", "-o", tmp_path / "u.exr"]):
        p = cli(*args)
        lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), (args, p.stderr)
        if "--seed" in args[3:4] or "--bogus" in args:  # the parser's own errors carry the hint
            assert lines[0].endswith(f" {args[0]} --help')"), lines[0]
    # Python's digit separators: --noise 1_0 had been read as 10, while --check refuses 1_0
    for args in (["perturb", mesh, "--noise", "1_0", "--seed", "1"], ["perturb", mesh, "--noise=0_3", "--seed", "1"],
                 ["geodesic", mesh, "-s", "1_0"], ["geodesic", mesh, "-s1_0"]):
        p = cli(*args, "-o", tmp_path / "o.ply")
        assert p.returncode == 2 and "write the number without '_'" in p.stderr and p.stderr.count("\n") == 1, p.stderr
    # ... and only numbers: a positional file name, or a text option, may hold '_'
    for args in (["info", "--json", "1_0"], ["info", "--", "1_0"]):
        p = cli(*args)
        assert p.returncode == 2 and "1_0: no such file" in p.stderr, p.stderr
    # a file name where a number belongs gets the parser's own error, not the separator advice
    p = cli("perturb", "--seed", "my_mesh.ply", mesh, "-o", tmp_path / "o.ply")
    assert p.returncode == 2 and "Invalid value for '--seed'" in p.stderr and "without '_'" not in p.stderr
    # an option without its value comes with no parser context: the hint had been left out
    p = cli("geodesic", mesh, "-s", "0", "-o")
    assert p.stderr.strip() == "error: Option '-o' requires an argument. (see 'geoproc geodesic --help')"
    assert list(tmp_path.iterdir()) == []


def test_overflowing_coordinates_and_obj_index_zero_are_refused(cli, tmp_path):
    big = tmp_path / "big.obj"
    big.write_text("v 1e200 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n")
    p = cli("perturb", big, "--seed", "1", "-o", tmp_path / "o.ply")
    assert p.returncode == 2 and "overflow" in _one_error_line(p.stderr, str(big))
    zero = tmp_path / "zero.obj"
    zero.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    assert "references vertex 0" in _one_error_line(cli("info", zero).stderr, str(zero))
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    for cmd in (["perturb", flat, "--seed", "1"], ["geodesic", flat, "-s", "0"]):
        p = cli(*cmd, "-o", tmp_path / "o.ply")
        assert p.returncode == 2 and "zero area" in _one_error_line(p.stderr, str(flat))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.obj", "flat.obj", "zero.obj"]


def test_obj_comments_and_latin1_text_are_read(tmp_path):
    path = tmp_path / "c.obj"
    path.write_bytes(b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0 # corner\nv 1 1 0\nf 1 2 3 # first\nf 2 4 3\n")
    m = load_mesh(path)
    assert m.F.tolist() == [[0, 1, 2], [1, 3, 2]]


def test_out_of_memory_is_one_line_exit_2(fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    res = CliRunner().invoke(_toy_app(), [str(fixture_dir / "torus.ply"), "-o", str(out), "--huge"])
    assert res.exit_code == 2 and not out.exists()
    assert res.output.strip() == "error: out of memory: Unable to allocate 74.5 GiB for an array"


def test_report_dash_goes_to_stdout_alone(cli, fixture_dir, tmp_path):
    mesh, out = fixture_dir / "cube.ply", tmp_path / "o.ply"
    p = cli("perturb", mesh, "--seed", "1", "-o", out, "--report", "-")
    assert p.returncode == 0 and out.exists() and not (tmp_path / "-").exists()
    rep = json.loads(p.stdout)
    validate_report(rep)
    assert rep["command"] == "perturb" and rep["params"]["seed"] == 1
    out.unlink()
    for args in (["perturb", mesh, "--seed", "1", "-o", "-", "--report", "-"], ["info", mesh, "--report", "-"]):
        p = cli(*args, cwd=tmp_path)
        assert p.returncode == 2 and p.stdout == b"" and list(tmp_path.iterdir()) == []
        lines = p.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: --report -") and "standard output" in lines[0]
    # refused before the input is read, as for the other commands (info read it and did the work first)
    p = cli("info", tmp_path / "missing.ply", "--report", "-")
    assert p.returncode == 2 and p.stderr.strip().startswith("error: --report - and another output")


def test_stdout_failures_same_paths_and_early_stdout_leave_nothing(fixture_dir, tmp_path):
    import subprocess
    import sys

    mesh = tmp_path / "t.ply"
    mesh.write_bytes((fixture_dir / "torus.ply").read_bytes())
    domain = tmp_path / "d.json"
    domain.write_text('{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}')
    base = [sys.executable, "-m", "geoproc_cli.main"]
    with open("/dev/full", "wb") as full:
        p = subprocess.run(base + ["geodesic", mesh, "-s", "0", "-o", tmp_path / "o.ply", "--report", "-"],
                           stdout=full, stderr=subprocess.PIPE, text=True)
    assert p.returncode == 2 and p.stderr.strip() == "error: -: cannot write: No space left on device"
    for args, message in (
        (["morse-simplify", mesh, "-f", "z", "-p", "0.1", "-o", tmp_path / "m.ply", "--critical", tmp_path / "s.json",
          "--report", tmp_path / "s.json"], "two outputs"),
        (["wos-solve", domain, "--boundary", "x", "-o", tmp_path / "u.exr", "--report", domain], "is also an input"),
        (["perturb", fixture_dir / "points.ply", "--seed", "1", "-o", tmp_path / "p.obj"], "written as .ply only"),
        (["info", mesh, "--json", "--check", "nosuch<=1"], "reports no metric 'nosuch'"),
    ):
        p = subprocess.run(base + args, capture_output=True, text=True)
        assert p.returncode == 2 and p.stdout == "" and message in p.stderr, (args, p.stderr)
    assert sorted(f.name for f in tmp_path.iterdir()) == ["d.json", "t.ply"]


def test_output_paths_are_refused_before_any_input_is_read(cli, fixture_dir, tmp_path):
    # the paths are checked first: a mistyped -o fails at once, not after the work
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"not a mesh")
    domain = tmp_path / "garbage.json"
    domain.write_bytes(b"{")
    missing, nodir = tmp_path / "missing.ply", tmp_path / "nodir"
    commands = (
        ["denoise", missing, "-o", nodir / "o.ply"],
        ["geodesic", missing, "-s", "0", "-o", tmp_path / "o.ply", "--render", nodir / "r.png"],
        ["morse-simplify", missing, "-f", "z", "-p", "0.1", "-o", tmp_path / "o.ply", "--diagram", nodir / "d.png"],
        ["perturb", missing, "--seed", "1", "-o", nodir / "o.ply"],
        ["wos-solve", tmp_path / "missing.json", "--boundary", "x", "-o", tmp_path / "u.exr",
         "--image", nodir / "u.png"],
        ["info", missing, "--report", nodir / "r.json"],
    )
    for args in commands:
        p = cli(*args)
        assert p.returncode == 2 and "output folder" in p.stderr and "missing" not in p.stderr, (args, p.stderr)
    (tmp_path / "folder.ply").mkdir()
    (tmp_path / "dangling.ply").symlink_to(nodir / "target.ply")
    for output, message in (("folder.ply", "is a folder"), ("new.ply/", "names a folder (it ends with '/')"),
                            ("dangling.ply", f"output folder '{nodir}' does not exist")):
        p = cli("denoise", missing, "-o", f"{tmp_path}/{output}")
        assert p.returncode == 2 and message in p.stderr and "missing" not in p.stderr, (output, p.stderr)
    (tmp_path / "folder.ply").rmdir()
    (tmp_path / "dangling.ply").unlink()
    # an extension no mesh is written in: denoise and perturb had refused it after the work
    for args in (["denoise", garbage, "-o", tmp_path / "o.pyl"], ["denoise", garbage, "--outliers", "-o",
                                                                 tmp_path / "o.pyl"],
                 ["perturb", garbage, "--seed", "1", "-o", tmp_path / "o.pyl"]):
        p = cli(*args)
        assert p.returncode == 2 and "cannot write '.pyl'" in p.stderr and "not a mesh" not in p.stderr, p.stderr
    for args in (["denoise", garbage, "-o", garbage], ["perturb", garbage, "--seed", "1", "-o", garbage],
                 ["geodesic", garbage, "-s", "0", "-o", garbage],
                 ["denoise", fixture_dir / "torus.ply", "--reference", garbage, "-o", garbage],
                 ["wos-solve", domain, "--boundary", "x", "-o", tmp_path / "u.exr", "--report", domain]):
        p = cli(*args)
        assert p.returncode == 2, (args, p.stderr)
        line = _one_error_line(p.stderr, str(args[-1]))
        assert line.endswith("is also an input; write the result to another file"), line
    assert garbage.read_bytes() == b"not a mesh" and domain.read_bytes() == b"{"
    assert sorted(f.name for f in tmp_path.iterdir()) == ["garbage.json", "garbage.ply"]
    # a hard link is the same file under another name: refused as an input, and as a second output
    os.link(garbage, tmp_path / "linked.ply")
    p = cli("perturb", garbage, "--seed", "1", "-o", tmp_path / "linked.ply")
    assert p.returncode == 2 and _one_error_line(p.stderr, str(tmp_path / "linked.ply")).endswith(
        "is also an input; write the result to another file"), p.stderr
    os.link(garbage, tmp_path / "linked.json")
    p = cli("perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", tmp_path / "linked.ply",
            "--report", tmp_path / "linked.json")
    assert p.returncode == 2 and "linked.json: given for two outputs" in p.stderr, p.stderr
    assert garbage.read_bytes() == b"not a mesh"
    # standard input redirected from the output file: `perturb - -o r.ply < r.ply` replaced it
    import subprocess
    import sys

    r = tmp_path / "r.ply"
    r.write_bytes((fixture_dir / "torus.ply").read_bytes())
    with open(r, "rb") as stdin:
        p = subprocess.run([sys.executable, "-m", "geoproc_cli.main", "perturb", "-", "--seed", "1", "-o", str(r),
                            "-q"], stdin=stdin, capture_output=True, text=True)
    assert p.returncode == 2 and _one_error_line(p.stderr, str(r)).endswith(
        "is also an input; write the result to another file"), p.stderr
    assert r.read_bytes() == (fixture_dir / "torus.ply").read_bytes()
    # standard output appended to an input: `perturb r.ply -o - >> r.ply` added a second PLY to it
    # (refused as /dev/stdout was); --report - the same
    for out in (["-o", "-"], ["-o", str(tmp_path / "s.ply"), "--report", "-"]):
        with open(r, "ab") as stdout:
            p = subprocess.run([sys.executable, "-m", "geoproc_cli.main", "perturb", str(r), "--seed", "1", *out],
                               stdout=stdout, stderr=subprocess.PIPE, text=True)
        assert p.returncode == 2 and p.stderr.strip().endswith(
            "standard output (-) is also an input; write the result to another file"), p.stderr
        assert r.read_bytes() == (fixture_dir / "torus.ply").read_bytes()


def test_inputs_from_pipes_are_hashed_as_read(fixture_dir, tmp_path):
    # a pipe (here bash's process substitution) can be read once: the report
    # hashes the bytes parsed, not a second, empty read
    import shlex
    import subprocess
    import sys

    geo = f"{shlex.quote(sys.executable)} -m geoproc_cli.main"
    torus, out = shlex.quote(str(fixture_dir / "torus.ply")), shlex.quote(str(tmp_path / "o"))
    domain = '{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}'
    for command, content in (
        (f"{geo} geodesic {torus} --sources-file <(printf '0 5\\n') -o {out}.ply --report -", b"0 5\n"),
        (f"{geo} wos-solve <(printf '%s' '{domain}') --boundary x --walks 4 --grid 8 -o {out}.exr --report -",
         domain.encode()),
    ):
        p = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stderr
        piped = json.loads(p.stdout)["inputs"][-1]
        assert piped["path"].startswith("/dev/fd/") and piped["sha256"] == hashlib.sha256(content).hexdigest()


def test_coordinates_beyond_the_safe_range_are_refused(cli, fixture_dir, tmp_path):
    torus = load_mesh(fixture_dir / "torus.ply")
    # (1e-200: the extent was measured as a norm whose squares underflowed to 0, so the points
    # read as all coinciding and were accepted; info reported a diagonal of 0)
    for scale, fragment in ((1e80, "overflow products of squared lengths"), (1e-60, "areas underflow"),
                            (1e-200, "areas underflow")):
        path = tmp_path / f"t{scale:g}.ply"
        from geoproc.mesh import save_mesh

        save_mesh(path, Mesh(torus.V * scale, torus.F))
        p = cli("morse-simplify", path, "-f", "z", "-p", "0.1", "-o", tmp_path / "m.ply")
        assert p.returncode == 2 and fragment in _one_error_line(p.stderr, str(path))


def test_checks_need_finite_ascii_numbers(cli, fixture_dir):
    for bad in ("genus<=nan", "genus<=inf", "genus<=1e999", "genus<=1_0", "genus<=\u0661"):
        p = cli("info", fixture_dir / "torus.ply", "--check", bad)
        assert p.returncode == 2 and "is not a finite decimal number" in p.stderr, (bad, p.stderr)
    p = cli("info", fixture_dir / "torus.ply", "--check", "genus==1.", "--check", "genus>=+.5e0")
    assert p.returncode == 0, p.stderr


def test_error_lines_escape_control_characters_and_bare_command_is_usage(cli, tmp_path):
    import subprocess
    import sys

    p = cli("info", tmp_path / "two\nlines.ply")
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "two\\nlines.ply: no such file" in p.stderr
    # notes too: a quad file's triangulation note had printed the name over two lines
    quads = tmp_path / "two\nlines.obj"
    quads.write_bytes(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    p = cli("info", quads)
    assert p.returncode == 0 and p.stderr.count("\n") == 1 and "two\\nlines.obj: triangulated" in p.stderr, p.stderr
    p = subprocess.run([sys.executable, "-m", "geoproc_cli.main"], capture_output=True, text=True)
    assert p.returncode == 2 and p.stdout == "" and p.stderr.startswith("error: missing command")


def test_stl_output_beyond_float32_is_refused(cli, fixture_dir, tmp_path):
    # STL stores float32: 1e40 used to become inf with a RuntimeWarning and exit 0
    from geoproc.mesh import save_mesh

    torus = load_mesh(fixture_dir / "torus.ply")
    path = tmp_path / "big.ply"
    save_mesh(path, Mesh(torus.V * 1e40, torus.F))
    out = tmp_path / "m.stl"
    p = cli("denoise", path, "--rounds", "0", "-o", out)
    assert p.returncode == 2 and not out.exists()
    assert "STL stores 32-bit floats" in _one_error_line(p.stderr, str(out))
    p = cli("denoise", path, "--rounds", "0", "-o", tmp_path / "m.off")
    assert p.returncode == 0, p.stderr


def test_report_params_are_the_options_that_applied(cli, fixture_dir, tmp_path):
    # geodesic recorded -c 1 under --time and steps 1 for heat; perturb, denoise and wos-solve left out -o
    rep = tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-t", "0.05", "-o", tmp_path / "d.ply", "--report", rep)
    assert p.returncode == 0, p.stderr
    params = json.loads(rep.read_text())["params"]
    assert params["time"] == 0.05 and params["time_factor"] is None and params["steps"] is None
    out = tmp_path / "n.ply"
    p = cli("perturb", fixture_dir / "cube.ply", "--seed", "1", "-o", out, "--report", rep)
    assert p.returncode == 0 and json.loads(rep.read_text())["params"]["output"] == str(out)
    p = cli("denoise", out, "-o", tmp_path / "c.ply", "--report", rep)
    assert p.returncode == 0 and json.loads(rep.read_text())["params"]["output"] == str(tmp_path / "c.ply")


@pytest.mark.parametrize("sink", ["closed pipe", "/dev/full"])
def test_an_unwritable_stderr_keeps_the_exit_code(sink, fixture_dir, tmp_path):
    # rich exited 1 on a closed pipe, and a full device raised from the error
    # printer: a bad input read as a failed --check, and a finished run as one
    import subprocess
    import sys

    if sink == "/dev/full" and not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")

    def status(*args):
        if sink == "closed pipe":
            r, w = os.pipe()
            os.close(r)
        else:
            w = os.open("/dev/full", os.O_WRONLY)
        try:
            return subprocess.run([sys.executable, "-m", "geoproc_cli.main", *map(str, args)],
                                  stdout=subprocess.DEVNULL, stderr=w, timeout=300).returncode
        finally:
            os.close(w)

    assert status("info", tmp_path / "missing.ply") == 2
    assert status("info", "--bogus") == 2
    assert status("info", fixture_dir / "torus.ply", "--check", "genus==5") == 1
    out = tmp_path / "p.ply"
    # a run with a note for stderr (the quad's polygons are split into triangles)
    assert status("perturb", fixture_dir / "quad.obj", "--seed", "1", "-o", out) == 0 and out.exists()


def test_termination_while_writing_leaves_nothing_staged(fixture_dir, tmp_path):
    # SIGTERM (timeout, job schedulers) killed the run with its outputs still staged as
    # temporary files beside their destinations; it is now an error line and status 143
    import signal
    import subprocess
    import sys
    import time

    report = tmp_path / "r.json"
    os.mkfifo(report)  # written to directly, after the mesh is staged: opening it waits for a reader
    proc = subprocess.Popen([sys.executable, "-c", "from geoproc_cli.entry import main; main()", "perturb",
                             str(fixture_dir / "torus.ply"), "--seed", "1", "-o", str(tmp_path / "o.ply"),
                             "--report", str(report)], stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not any(p.name.endswith(".tmp") for p in tmp_path.iterdir()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert any(p.name.endswith(".tmp") for p in tmp_path.iterdir())  # staged, waiting on the FIFO
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and err.decode().strip() == "error: terminated (SIGTERM)"
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]


def _perturb_under(script: str, fixture_dir, out, *extra: str):
    """``perturb torus.ply --seed 1 -o out [extra]`` run by ``python -c script``
    (:func:`tests.conftest.run_cli_under`)."""
    return run_cli_under(script, "perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", out, *extra)


@pytest.mark.parametrize("sig, status, line", [("SIGTERM", 143, "error: terminated (SIGTERM)"),
                                               ("SIGINT", 130, "error: interrupted")])
def test_a_signal_while_libigl_loads_is_an_interruption(fixture_dir, tmp_path, sig, status, line):
    # libigl's nanobind extension turned the exception the handler raised while it created its
    # enumerations into a C++ exception: abort, exit 134, a 31-line traceback. The signal is
    # sent here at that moment (the first enumeration made while igl loads)

    script = (
        "import enum, os, signal, sys\n"
        "call = enum.EnumType.__call__\n"
        "armed = [True]\n"
        "def inject(cls, *a, **k):\n"
        "    if armed[0] and 'igl' in sys.modules and 'igl.pyigl_core' not in sys.modules:\n"
        f"        armed[0] = False; os.kill(os.getpid(), signal.{sig})\n"
        "    return call(cls, *a, **k)\n"
        "enum.EnumType.__call__ = inject\n"
        "from geoproc_cli.entry import main\n"
        "main()\n"
    )
    out = tmp_path / "o.ply"
    p = _perturb_under(script, fixture_dir, out)
    assert p.returncode == status and p.stderr.strip() == line, p.stderr[-3000:]
    assert list(tmp_path.iterdir()) == []


def test_an_output_folder_that_cannot_take_a_file_is_refused_before_the_work(fixture_dir, tmp_path, monkeypatch,
                                                                            capsys):
    # a read-only file system (or a folder without write permission) was found only when the
    # output was staged, after the work: 17 s of exact geodesics on the armadillo, then exit 2
    import geoproc.geodesic
    from geoproc_cli import main as cli_main

    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if os.fspath(p) == str(ro) else real_access(
        p, mode, **kw))
    monkeypatch.setattr(geoproc.geodesic, "geodesic_distance", lambda *a, **k: pytest.fail("the work ran"))
    monkeypatch.setattr("sys.argv", ["geoproc", "geodesic", str(fixture_dir / "torus.ply"), "-s", "0", "-o",
                                     str(ro / "d.ply")])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    err = capsys.readouterr().err.strip()
    assert stop.value.code == 2 and err == f"error: {ro / 'd.ply'}: cannot write: output folder '{ro}' is not writable"
    assert list(ro.iterdir()) == []


def test_a_signal_once_the_outputs_are_in_place_is_ignored(fixture_dir, tmp_path):
    # a SIGTERM in the last tens of milliseconds (notes, exit) made a finished run exit 143,
    # most often without an error line, its outputs complete

    script = (
        "import os, signal\n"
        "from geoproc_cli import common\n"
        "flush = common.Run._flush_notes\n"
        "def late(self):\n"
        "    os.kill(os.getpid(), signal.SIGTERM)\n"
        "    flush(self)\n"
        "common.Run._flush_notes = late\n"
        "from geoproc_cli.entry import main\n"
        "main()\n"
    )
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = _perturb_under(script, fixture_dir, out, "--report", str(rep))
    assert p.returncode == 0 and p.stderr == "", (p.returncode, p.stderr[-2000:])
    assert out.stat().st_size > 0 and json.loads(rep.read_text())["command"] == "perturb"


def test_a_signal_while_python_exits_after_the_outputs_are_in_place_is_ignored(fixture_dir, tmp_path):
    # Python's exit puts its signal handlers back to the default action: a SIGTERM in the
    # fraction of a second the exit takes killed a finished run (exit 143, no error line).
    # It is sent here from an object that the interpreter's exit destroys

    script = (
        "import os, signal, time\n"
        "class Late:\n"
        "    def __del__(self):\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        time.sleep(0.05)\n"
        "late = Late()\n"
        "from geoproc_cli.entry import main\n"
        "main()\n"
    )
    out = tmp_path / "o.ply"
    p = _perturb_under(script, fixture_dir, out)
    assert p.returncode == 0 and p.stderr == "", (p.returncode, p.stderr[-2000:])
    assert out.stat().st_size > 0


def test_a_signal_that_an_import_wraps_is_an_interruption(fixture_dir, tmp_path):
    # Python 3.11 wraps an exception raised inside a descriptor's __set_name__ in a
    # RuntimeError: a SIGHUP while typer's imports (platform's cached_property) ran gave a
    # 62-line traceback and exit 1, the status of a failed --check

    script = (
        "import functools, os, signal\n"
        "orig = functools.cached_property.__set_name__\n"
        "armed = [True]\n"
        "def hook(self, owner, name):\n"
        "    if armed[0] and signal.getsignal(signal.SIGHUP) is not signal.SIG_DFL:\n"
        "        armed[0] = False\n"
        "        os.kill(os.getpid(), signal.SIGHUP)\n"
        "    return orig(self, owner, name)\n"
        "functools.cached_property.__set_name__ = hook\n"
        "from geoproc_cli.entry import main\n"
        "main()\n"
    )
    out = tmp_path / "o.ply"
    p = _perturb_under(script, fixture_dir, out)
    assert p.returncode == 129 and p.stderr == "error: terminated (SIGHUP)\n", (p.returncode, p.stderr[-2000:])
    assert not out.exists()


def test_a_second_command_in_the_process_is_interruptible_again(fixture_dir, tmp_path, capsys):
    # once a command's outputs were in place the terminating signals were set to be ignored
    # for good: a second command in the same process ran through a Ctrl-C
    import signal

    from geoproc_cli import entry
    from geoproc_cli.common import Run

    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    flush = Run._flush_notes
    try:
        for sig in saved:
            signal.signal(sig, signal.SIG_DFL if sig != signal.SIGINT else signal.default_int_handler)
        entry.install_signal_handlers()
        entry.outputs_committed()  # as the first command leaves it
        os.kill(os.getpid(), signal.SIGTERM)  # dropped: that command is done
        Run._flush_notes = lambda self: os.kill(os.getpid(), signal.SIGINT)  # inside the second command
        import sys

        sys.argv = ["geoproc", "perturb", str(fixture_dir / "torus.ply"), "--seed", "1", "-o", str(tmp_path / "o.ply")]
        with pytest.raises(SystemExit) as stop:
            entry.main()
        assert stop.value.code == 0  # the outputs were in place when it came
        Run._flush_notes = flush
        with pytest.raises(SystemExit) as stop:  # a signal while it works interrupts it
            sys.argv[-1] = str(tmp_path / "p.ply")
            from geoproc_cli import main as cli_main

            real_load = Run.load_mesh
            Run.load_mesh = lambda self, *a, **k: os.kill(os.getpid(), signal.SIGINT) or real_load(self, *a, **k)
            try:
                cli_main.main()
            finally:
                Run.load_mesh = real_load
        assert stop.value.code == 130 and not (tmp_path / "p.ply").exists()
        assert "error: interrupted" in capsys.readouterr().err
    finally:
        Run._flush_notes = flush
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def test_interruption_typer_swallows_is_reported(monkeypatch, capsys):
    # typer turns a Ctrl-C outside a command's body (while it parses the options) into a
    # silent exit status 130; the handlers remember the signal and main() reports it
    import signal

    from geoproc_cli import entry
    from geoproc_cli import main as cli_main

    monkeypatch.setattr(entry, "_pending", None)

    def swallowing_app(standalone_mode=False):
        try:
            entry._raise_interruption(signal.SIGTERM, None)
        except KeyboardInterrupt:
            return 130  # as typer.core does: raise Exit(130) from the interrupt

    monkeypatch.setattr(cli_main, "command", lambda: swallowing_app)
    monkeypatch.setattr("sys.argv", ["geoproc", "info", "x.ply"])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    assert stop.value.code == 143 and capsys.readouterr().err.strip() == "error: terminated (SIGTERM)"
    assert entry.unreported_interruption() is None


def test_output_linked_to_standard_output_that_is_a_pipe(cli, fixture_dir, tmp_path):
    # realpath of /dev/stdout on a pipe names no file (/proc/PID/fd/pipe:[N]): the report was
    # refused with "cannot write: No such file or directory" instead of written through the link
    link = tmp_path / "so.json"
    link.symlink_to("/dev/stdout")
    out = tmp_path / "p.ply"
    p = cli("perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", out, "--report", link, "-q")  # a pipe here
    assert p.returncode == 0, p.stderr
    report = json.loads(p.stdout.decode())
    assert report["command"] == "perturb" and report["metrics"]["vertices"] == 1152
    assert sorted(f.name for f in tmp_path.iterdir()) == ["p.ply", "so.json"]


def test_two_outputs_on_standard_output_by_any_name_are_refused(cli, fixture_dir, tmp_path):
    # a link to /dev/stdout was not counted as standard output: the PLY and the report went
    # to the pipe one after the other (and info's summary after its report)
    so_ply, so_json = tmp_path / "so.ply", tmp_path / "so.json"
    so_ply.symlink_to("/dev/stdout")
    so_json.symlink_to("/dev/stdout")
    torus = fixture_dir / "torus.ply"
    for args in (["perturb", torus, "--seed", "1", "-o", so_ply, "--report", "-"],
                 ["perturb", torus, "--seed", "1", "-o", "-", "--report", so_json],
                 ["info", torus, "--report", so_json]):
        p = cli(*args)
        assert p.returncode == 2 and p.stdout == b"", args
        assert "both write to standard output; give all but one a file name" in p.stderr, args


def test_signals_started_ignored_stay_ignored():
    # nohup starts a run with SIGHUP ignored, a shell's background job with SIGINT ignored:
    # the handlers must not make those signals end the run
    import subprocess
    import sys

    code = ("import signal; signal.signal(signal.SIGHUP, signal.SIG_IGN); "
            "from geoproc_cli.entry import install_signal_handlers as h; h(); "
            "print(signal.getsignal(signal.SIGHUP) is signal.SIG_IGN, "
            "signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True", "True"]


def test_a_bug_in_the_body_is_an_internal_error_with_exit_3(capsys):
    with pytest.raises(typer.Exit) as stop:
        with command_run("info", {}):
            raise ValueError("boom\nsecond line")
    assert stop.value.exit_code == 3
    assert capsys.readouterr().err.strip() == \
        "error: internal error: ValueError: boom (rerun with --debug for the traceback)"


def test_a_timer_adds_up_its_intervals(monkeypatch):
    from geoproc_cli import common

    run = common.Run("info", {}, True)
    clock = iter([0.0, 1.0, 10.0, 12.0])
    monkeypatch.setattr(common.time, "perf_counter", lambda: next(clock))
    for _ in range(2):
        with run.timer("load"):
            pass
    assert run.timings == {"load": 3.0}


def test_clean_up_counts_are_reported_under_their_names(cli, tmp_path):
    # one copy of vertex 0 (merged) and two vertices no face uses (dropped), counted by hand
    src = tmp_path / "m.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 0\nv 5 5 5\nv 6 6 6\nf 1 2 3\nf 4 3 2\n")
    rep = tmp_path / "r.json"
    p = cli("info", src, "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    m = json.loads(rep.read_text())["metrics"]
    assert (m["input_vertices"], m["merged_vertices"], m["removed_unreferenced_vertices"]) == (6, 1, 2)
    assert m["vertices"] == 3


STRAY_PRINT_APP = """
import ctypes, sys
import typer
from geoproc.mesh import load_mesh
from geoproc_cli.common import command_run

app = typer.Typer()

@app.command()
def copy(mesh: str, output: str = typer.Option(..., "-o")) -> None:
    with command_run("copy", {}, outputs=[output]) as run:
        ctypes.CDLL(None).printf(b"a compiled library's own line\\n")  # as HiGHS's MIP solver printed
        print("a Python line", flush=True)
        run.write_mesh(output, run.load_mesh(mesh))

app()
"""


@pytest.mark.skipif(os.name != "posix", reason="libc printf through ctypes")
def test_with_its_result_on_stdout_a_run_lets_no_other_print_reach_it(fixture_dir, tmp_path):
    import subprocess
    import sys

    src = fixture_dir / "torus.ply"
    piped = subprocess.run([sys.executable, "-c", STRAY_PRINT_APP, str(src), "-o", "-"], capture_output=True,
                           timeout=120)
    assert piped.returncode == 0, piped.stderr
    assert read_mesh_bytes(piped.stdout, "ply").V.shape == load_mesh(src).V.shape
    assert b"a compiled library's own line" not in piped.stderr + piped.stdout
    # written to a file, the run leaves standard output as it is
    to_file = subprocess.run([sys.executable, "-c", STRAY_PRINT_APP, str(src), "-o", str(tmp_path / "o.ply")],
                             capture_output=True, timeout=120)
    assert to_file.returncode == 0 and b"a compiled library's own line" in to_file.stdout


def test_report_params_hold_the_options_used_and_none_for_those_not(cli, fixture_dir, tmp_path):
    # the report's params named options that a mode refuses when given (k and threshold of
    # --outliers for a mesh, --exact-windows with --barycentric), called an animation's frames
    # cleaned; a default chosen from the input (the outlier threshold) is null there
    import numpy as np

    from geoproc.animation import Animation, animation_to_bytes

    def params(*args):
        rep = tmp_path / "r.json"
        p = cli(*args, "--report", rep, "-q")
        assert p.returncode == 0, p.stderr
        return json.loads(rep.read_text())["params"]

    mesh = params("denoise", fixture_dir / "cube.ply", "-o", tmp_path / "d.ply")
    assert mesh["k"] is mesh["threshold"] is mesh["coherence"] is mesh["feature_tau"] is None
    assert mesh["feature_angle"] is not None and mesh["clean"] is True and mesh["method"] == "guided"
    cloud = params("denoise", fixture_dir / "points.ply", "--outliers", "-o", tmp_path / "c.ply")
    assert cloud["threshold"] is None and cloud["k"] == 16  # chosen from the scores: the metric gives it
    assert cloud["method"] is cloud["rounds"] is cloud["features"] is cloud["reference"] is None
    V, F = load_mesh(fixture_dir / "cube.ply").V, load_mesh(fixture_dir / "cube.ply").F
    anim = tmp_path / "a.npz"
    anim.write_bytes(animation_to_bytes(Animation(np.stack([V, 1.01 * V, 1.02 * V]), F)))
    moved = params("perturb", anim, "--seed", "1", "-o", tmp_path / "p.npz")
    assert moved["clean"] is None and moved["outlier_range"] is None and moved["direction"] == "normal"
    dynamic = params("denoise", tmp_path / "p.npz", "--dynamic", "-o", tmp_path / "q.npz")
    assert dynamic["clean"] is dynamic["features"] is dynamic["k"] is None and dynamic["coherence"] == "heights"
    exact = params("morse-simplify", fixture_dir / "icosphere.ply", "-f", "z", "-p", "0.1", "--barycentric",
                   "-o", tmp_path / "m.ply")
    assert exact["exact_windows"] is None and exact["barycentric"] is True


def test_outputs_to_a_device_and_a_mesh_there_as_binary_ply(cli, fixture_dir, tmp_path):
    # -o /dev/null (a run kept for its report and gates) had been refused: no extension to choose the format by
    rep = tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", "/dev/null", "--report", rep,
            "--check", "vertices>=1")
    assert p.returncode == 0 and json.loads(rep.read_text())["metrics"]["vertices"] == 1152, p.stderr
    link = tmp_path / "out"
    link.symlink_to("/dev/stdout")
    p = cli("perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", link, "-q")
    assert p.returncode == 0 and p.stdout.startswith(b"ply\nformat binary_little_endian"), p.stderr
    p = cli("perturb", fixture_dir / "torus.ply", "--seed", "1", "-o", tmp_path / "noext")
    assert p.returncode == 2 and "no file extension to choose the format by" in p.stderr
    # outputs whose names must end in .exr, .png or .json may be devices too, several at /dev/null
    # (they had been refused: '-o /dev/null: must end in .exr', 'given for two outputs')
    dom = tmp_path / "sq.json"
    dom.write_text('{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}')
    p = cli("wos-solve", dom, "--boundary", "x", "--grid", "8", "--walks", "4", "-o", "/dev/null", "--image",
            "/dev/null", "--report", rep, "--check", "walks>=4")
    assert p.returncode == 0 and json.loads(rep.read_text())["command"] == "wos-solve", p.stderr
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", "z", "-p", "0.1", "-o", "/dev/null",
            "--diagram", "/dev/null", "--critical", "/dev/null", "--report", "/dev/null")
    assert p.returncode == 0, p.stderr
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", "z", "-p", "0.1", "-o", tmp_path / "m.ply",
            "--critical", tmp_path / "m.ply")  # any other file given twice is still refused
    assert p.returncode == 2 and "given for two outputs" in p.stderr


def test_info_summarizes_an_animation(cli, fixture_dir, tmp_path):
    # an animation, which perturb and denoise write, had been 'unknown mesh format'
    torus = load_mesh(fixture_dir / "torus.ply")
    frames = np.stack([torus.V * (1 + 0.1 * t) for t in range(4)])
    np.savez(tmp_path / "a.npz", vertices=frames, faces=torus.F, tag=np.ones((4, len(torus.V))))
    rep = tmp_path / "r.json"
    p = cli("info", tmp_path / "a.npz", "--json", "--report", rep, "--check", "frames==4", "--check", "genus==1")
    assert p.returncode == 0, p.stderr
    s = json.loads(p.stdout)
    assert (s["frames"], s["vertices"], s["faces"], s["genus"]) == (4, len(torus.V), len(torus.F), 1)
    assert s["bbox_diagonal"] == pytest.approx(np.linalg.norm(np.ptp(torus.V, axis=0)))  # the first frame's
    assert s["vertex_properties"] == ["tag"] and json.loads(rep.read_text())["metrics"]["frames"] == 4
    assert s["worst_frame"] == -1 and s["degenerate_faces"] == 0
    # a face collapsed in one later frame: counted, with that frame (frame 0's summary had read 0)
    frames[2][torus.F[5, 1]] = frames[2][torus.F[5, 0]]
    np.savez(tmp_path / "b.npz", vertices=frames, faces=torus.F)
    p = cli("info", tmp_path / "b.npz", "--json", "-q", "--check", "degenerate_faces==0")
    assert p.returncode == 1 and f"check failed: {tmp_path / 'b.npz'}: degenerate_faces==0" in p.stderr, p.stderr
    s = json.loads(p.stdout)  # the collapsed edge's two faces, one vertex on another, frame 2
    assert (s["degenerate_faces"], s["duplicate_vertices"], s["worst_frame"]) == (2, 1, 2)
    # each count is the most of any frame: three vertices on others in frame 3 (1 had been read, frame 2's)
    frames[3][torus.F[10:13, 0]] = frames[3][torus.F[20:23, 0]]
    np.savez(tmp_path / "c.npz", vertices=frames, faces=torus.F)
    s = json.loads(cli("info", tmp_path / "c.npz", "--json", "-q", "--report", rep).stdout)
    assert (s["degenerate_faces"], s["duplicate_vertices"], s["worst_frame"]) == (2, 3, 2)
    assert json.loads(rep.read_text())["params"]["clean"] is None  # frames are read as stored (had been true)
    # a moving point cloud: its duplicate points counted over the frames too (frame 0's had been read)
    np.savez(tmp_path / "d.npz", vertices=frames, faces=np.zeros((0, 3), int))
    s = json.loads(cli("info", tmp_path / "d.npz", "--json", "-q").stdout)
    assert (s["degenerate_faces"], s["duplicate_vertices"], s["worst_frame"]) == (None, 3, 3)  # null as one cloud's
    p = cli("info", tmp_path / "a.npz", "--no-clean")
    assert p.returncode == 2 and "--no-clean: not used for an animation" in p.stderr
    # a check on what only the other kind of input reports: refused before the input is read, with why
    p = cli("info", tmp_path / "a.npz", "--check", "merged_vertices==0")
    assert p.returncode == 2 and "info reports 'merged_vertices' only with a mesh or point cloud" in p.stderr
    p = cli("info", fixture_dir / "torus.ply", "--check", "frames==1")
    assert p.returncode == 2 and "info reports 'frames' only with an animation (.npz or a folder" in p.stderr
    p = cli("info", fixture_dir / "torus.ply", "--report", rep)
    assert p.returncode == 0 and "frames" not in json.loads(rep.read_text())["metrics"]


def test_an_output_folder_is_the_one_the_file_system_resolves(cli, fixture_dir, tmp_path):
    # '..' after a symbolic link leads to the link target's parent; the path's text had been
    # normalised instead, refusing a folder that exists and passing one that does not
    (tmp_path / "sub" / "deep").mkdir(parents=True)
    (tmp_path / "sub" / "only").mkdir()
    (tmp_path / "lnk").symlink_to(tmp_path / "sub" / "deep")
    src = fixture_dir / "torus.ply"
    p = cli("perturb", src, "--seed", "1", "-o", f"{tmp_path}/lnk/../only/x.ply", "--report",
            f"{tmp_path}/lnk/../only/r.json")
    assert p.returncode == 0, p.stderr
    assert sorted(q.name for q in (tmp_path / "sub" / "only").iterdir()) == ["r.json", "x.ply"]
    for option, name in (("-o", "x.ply"), ("--report", "r.json")):
        args = ["-o", str(tmp_path / "y.ply")] if option == "--report" else []
        p = cli("perturb", src, "--seed", "1", *args, option, f"{tmp_path}/lnk/../sub/{name}")
        assert p.returncode == 2 and f"output folder '{tmp_path}/lnk/../sub' does not exist" in p.stderr, p.stderr
    assert not (tmp_path / "y.ply").exists() and not (tmp_path / "sub" / "sub").exists()


@pytest.mark.parametrize("args, named", [
    # a file named like an option after '--' had been taken for the option's text
    (["-s", "0", "-c", "1e400", "-o", "x.ply", "--", "--time-factor=7.ply"], "-c 1e400 (which reads as inf)"),
    (["-s", "0", "--time-factor=1e400", "-o", "x.ply", "grid.ply"], "--time-factor 1e400 (which reads as inf)"),
    (["grid.ply", "-s", "0", "-o", "x.ply", "--time-factor", "-1E999"], "--time-factor -1E999 (which reads as -inf)"),
    # an option cluster, and another option's value that starts like the option (had been
    # '--time-factor inf' and '-c 5.ply (which reads as inf)')
    (["grid.ply", "-s", "0", "-qc1e400", "-o", "x.ply"], "-c 1e400 (which reads as inf)"),
    (["grid.ply", "-s", "0", "-c", "1e400", "-o", "-c5.ply"], "-c 1e400 (which reads as inf)"),
])
def test_an_option_is_named_as_typed(fixture_dir, tmp_path, args, named):
    import shutil

    from tests.conftest import run_cli

    shutil.copy(fixture_dir / "grid.ply", tmp_path / "grid.ply")
    shutil.copy(fixture_dir / "grid.ply", tmp_path / "--time-factor=7.ply")
    p = run_cli("geodesic", *args, cwd=tmp_path)
    assert p.returncode == 2 and p.stderr == f"error: {named}: must be a finite number\n", p.stderr
