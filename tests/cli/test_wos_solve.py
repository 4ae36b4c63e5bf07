"""``geoproc wos-solve`` through the real command line."""

import json

import numpy as np
import pytest

from geoproc.wos.images import read_exr
from tests.conftest import load_fixture_module


def _load_wos_fixtures():
    """fixtures/wos_fixtures.py, loaded the way conftest loads make_fixtures."""
    return load_fixture_module("wos_fixtures")


wf = _load_wos_fixtures()


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("wos")
    files = {
        "disk": wf.disk(128), "annulus": wf.annulus(128), "rect": wf.rectangle_neumann(), "glyph": wf.glyph("B", 128),
        "bowtie": {"loops": [[[0, 0], [1, 1], [1, 0], [0, 1]]]},
        "open": {"loops": [[[0, 0], [1, 0]]]},
        "flat": {"loops": [[[0, 0], [1, 0], [2, 0]]]},
        "huge": {"loops": [[[0, 0], [1e20, 0], [1e20, 1e20], [0, 1e20]]]},
        "neu_int": {"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "neumann": 1},
        "neu_zero": {"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "neumann": 0},
        "square": {"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]},
        "big_values": {"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "values": [[1e308] * 4]},
        "typo": {"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "Neumann": [[0, 1]]},
    }
    for name, doc in files.items():
        (d / f"{name}.json").write_text(json.dumps(doc))
    # json.dumps cannot repeat a key: the last copy was used without a word
    # past Python's 4300 digits for reading an integer: an internal error, exit 3
    (d / "longint.json").write_text('{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "neumann": [' + "9" * 5000 + "]}")
    (d / "twice.json").write_text('{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "neumann": [0], "neumann": null}')
    wf.write_mask(d / "mask.png", wf.disk_mask(64, 24.0, 8.0))
    wf.write_mask(d / "blank.png", np.zeros((32, 32), bool))
    whole = (d / "mask.png").read_bytes()
    (d / "trunc.png").write_bytes(whole[: len(whole) // 2])
    (d / "folder.json").mkdir()
    return d


def test_solve_writes_exr_report_and_images(cli, inputs, tmp_path):
    out, rep, img, err = (tmp_path / n for n in ("u.exr", "r.json", "u.png", "e.png"))
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x**3 - 3*x*y**2", "--method",
            "cv-green", "--walks", "32", "--grid", "40", "--kernels", "40", "--exact", "-o", out,
            "--report", rep, "--image", img, "--error-image", err, "--seed", "3", "--quiet")
    assert p.returncode == 0, p.stderr
    U = read_exr(str(out))
    assert U.shape == (40, 40) and U.dtype == np.float32
    yy, xx = np.mgrid[0:40, 0:40]
    X, Y = -1 + (xx + 0.5) / 20, 1 - (yy + 0.5) / 20
    inside = X**2 + Y**2 < 0.99**2
    outside = X**2 + Y**2 > 1.0
    assert np.isfinite(U[inside]).all() and np.isnan(U[outside]).all()
    exact = X**3 - 3 * X * Y**2
    m = json.loads(rep.read_text())["metrics"]
    assert np.sqrt(np.mean((U[inside] - exact[inside]) ** 2)) < 0.02
    for key in ("rmse", "max_abs_error", "bias", "walks", "total_steps", "steps_per_second",
                "fit_seconds", "residual_seconds"):
        assert key in m, key
    assert m["rmse"] < 0.02 and m["walks"] == 32 and m["total_steps"] > 0
    assert img.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and err.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the PNGs go to standard output with -, as geodesic's --render and morse-simplify's --diagram do
    for option, written in (("--image", img), ("--error-image", err)):
        p = cli("wos-solve", inputs / "disk.json", "--boundary", "x**3 - 3*x*y**2", "--method",
                "cv-green", "--walks", "32", "--grid", "40", "--kernels", "40", "--exact", "-o", tmp_path / "v.exr",
                option, "-", "--seed", "3", "--quiet")
        assert p.returncode == 0, p.stderr
        assert p.stdout == written.read_bytes()


def test_same_seed_same_bytes(cli, inputs, tmp_path):
    args = ["wos-solve", inputs / "glyph.json", "--boundary", "exp(x)*cos(y)", "--walks", "8",
            "--grid", "32", "--quiet"]
    outs = []
    for k, seed in enumerate(("5", "5", "6")):
        o, i = tmp_path / f"u{k}.exr", tmp_path / f"u{k}.png"
        p = cli(*args, "--seed", seed, "-o", o, "--image", i)
        assert p.returncode == 0, p.stderr
        outs.append((o.read_bytes(), i.read_bytes()))
    assert outs[0] == outs[1]
    assert outs[0][0] != outs[2][0]


@pytest.mark.slow  # about 30 s of CLI runs: kept out of make test's ten minutes (make test-all runs it)
def test_a_solution_float32_cannot_resolve_is_noted(cli, inputs, tmp_path):
    # u = 1e9 + x on the unit square: the EXR (float32, steps of 64 there) showed a constant
    args = ["wos-solve", inputs / "square.json", "--walks", "4", "--grid", "8", "-o", tmp_path / "u.exr"]
    p = cli(*args, "--boundary", "1e9 + x")
    assert p.returncode == 0, p.stderr
    assert ("note: the solution varies by 1 around 1e+09, which the float32 EXR resolves in less than one step; "
            "subtract a constant from the boundary data") in " ".join(p.stderr.split())
    assert np.ptp(read_exr(str(tmp_path / "u.exr"))[np.isfinite(read_exr(str(tmp_path / "u.exr")))]) == 0
    p = cli(*args, "--boundary", "x")
    assert p.returncode == 0 and "float32" not in p.stderr
    # constant data: a control variate leaves rounding (1e-14 around 1 on the disk), no variation
    for method in ("cv-green", "cv-angle", "npass"):
        p = cli("wos-solve", inputs / "disk.json", "--boundary", "1", "-m", method, "--grid", "64", "--walks", "16",
                "-o", tmp_path / "u.exr")
        assert p.returncode == 0 and "float32" not in p.stderr, (method, p.stderr)
    # constant as the domain's own values, or as an expression that reads x
    dom = dict(wf.disk(128))
    dom["values"] = [[1.0] * len(loop) for loop in dom["loops"]]
    (tmp_path / "ones.json").write_text(json.dumps(dom))
    for extra in ([], ["--boundary", "2 - 1"]):
        p = cli("wos-solve", tmp_path / "ones.json", *extra, "-m", "cv-green", "--grid", "32", "--walks", "16",
                "-o", tmp_path / "u.exr")
        assert p.returncode == 0 and "float32 EXR" not in p.stderr, (extra, p.stderr)
    # data equal at every checked point but not constant are still noted
    sq = {"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}
    (tmp_path / "sq.json").write_text(json.dumps(sq))
    p = cli("wos-solve", tmp_path / "sq.json", "--boundary", "1e6 + sin(8*pi*x)", "--grid", "16", "--walks", "16",
            "-o", tmp_path / "u.exr")
    assert p.returncode == 0 and "which the float32 EXR resolves in only" in p.stderr
    # a small variation of its own is still noted (a cut at 1e-12 of the size had hidden 2e-13 around 1)
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "1 + 1e-13*x", "-m", "cv-green", "--grid", "16",
            "--walks", "16", "-o", tmp_path / "u.exr")
    assert p.returncode == 0 and "which the float32 EXR resolves in less than one step" in p.stderr


def test_mask_domain(cli, inputs, tmp_path):
    out, rep = tmp_path / "m.exr", tmp_path / "m.json"
    p = cli("wos-solve", inputs / "mask.png", "--boundary", "(x-32)/24", "--walks", "16", "--grid",
            "32", "--exact", "-o", out, "--report", rep, "--epsilon", "0.01")
    assert p.returncode == 0, p.stderr
    assert "traced 2 loop(s)" in p.stderr
    m = json.loads(rep.read_text())["metrics"]
    assert m["loops"] == 2
    assert m["domain_area"] == pytest.approx(np.pi * (24**2 - 8**2), rel=0.03)
    assert m["rmse"] < 0.1


def test_neumann_rectangle(cli, inputs, tmp_path):
    out, rep = tmp_path / "n.exr", tmp_path / "n.json"
    p = cli("wos-solve", inputs / "rect.json", "--boundary", "y", "--neumann", "2*y - 1", "--walks",
            "32", "--grid", "24", "--exact", "--method", "cv-green", "--kernels", "40", "-o", out,
            "--report", rep, "--quiet")
    assert p.returncode == 0, p.stderr
    m = json.loads(rep.read_text())["metrics"]
    assert m["neumann_segments"] == 2 and m["rmse"] < 0.03


@pytest.mark.parametrize("domain,extra,message", [
    ("bowtie.json", [], "loop 0 intersects itself"),
    ("open.json", [], "loop 0 is open"),
    ("flat.json", [], "zero area"),
    ("blank.png", [], "no foreground"),
    # libpng printed a line of its own before the error
    ("trunc.png", [], "trunc.png: cannot read image"),
    ("missing.json", [], "no such file"),
    ("folder.json", [], "folder.json: is a directory, not a domain file"),
    ("huge.json", [], "loop 0 has coordinates as large as 1e+20; they must stay within +-1e+15"),
    ("neu_int.json", [], "'neumann' must be a list of loop indices or [loop, segment] pairs, not 1"),
    # a falsy non-list ("neumann": 0) was read as no Neumann loop: a Dirichlet problem without a word
    ("neu_zero.json", [], "'neumann' must be a list of loop indices or [loop, segment] pairs, not 0"),
    # a misspelt key gave a Dirichlet problem without a word
    ("typo.json", [], "unknown key 'Neumann' (the keys are 'loops', 'neumann' and 'values')"),
    ("twice.json", [], "twice.json: the key 'neumann' is given twice"),
    ("longint.json", [], "longint.json: a number in it is too long to read (Exceeds the limit (4300 digits)"),
    ("disk.json", ["--boundary", "0x" + "f" * 4000], "a 16000-bit integer is beyond the floating-point range"),
    ("disk.json", ["--boundary", "+".join(["x"] * 20000)], "expression nested too deeply"),
    ("disk.json", ["--boundary", "x + foo(y) + bar"], "unknown names 'bar', 'foo'"),
    ("disk.json", ["--boundary", "x", "--error-image", "e.png"], "--error-image needs --exact"),
    # NaN inside the domain had given null error metrics without a word
    ("disk.json", ["--boundary", "sqrt(x*x + y*y - 0.5)", "--exact"],
     "--exact: --boundary is not finite at 24 grid points inside"),
    # the problem is in the domain file, which the message had not named
    ("rect.json", ["--boundary", "x", "--method", "cv-angle"], "rect.json: has Neumann segments, and cv-angle"),
    # boundary data must be finite on the boundary, and the solution fit EXR's float32
    ("disk.json", ["--boundary", "log(x - 5)"], "--boundary is not finite on the boundary of"),
    ("disk.json", ["--boundary", "1/(x*x + y*y - 1)"], "--boundary is not finite on the boundary"),
    ("rect.json", ["--neumann", "0/0"], "--neumann is not finite on the boundary"),
    ("disk.json", ["--boundary", "exp(700*x)"], "disk.json: --boundary reaches 1.01e+304 on the Dirichlet boundary"),
    ("disk.json", ["--boundary", "x", "--kernels", "5", "--ridge", "3"], "--kernels, --ridge: only with a control"),
    ("disk.json", ["--boundary", "x", "--image", "u.tif"], "--image u.tif: must end in .png"),
])
def test_bad_input_exits_2_with_one_line_and_no_output(cli, inputs, tmp_path, domain, extra, message):
    out = tmp_path / "u.exr"
    args = list(extra)
    if "--boundary" not in args and domain != "disk.json":
        args += ["--boundary", "x"]
    args = [a if a != "e.png" else str(tmp_path / "e.png") for a in args]
    p = cli("wos-solve", inputs / domain, *args, "--grid", "8", "--walks", "2", "-o", out,
            "--report", tmp_path / "r.json")
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), p.stderr
    assert message in lines[0], lines[0]
    assert p.stdout == b""  # (OpenImageIO printed a truncated PNG's pending error there)
    assert not out.exists() and not (tmp_path / "r.json").exists() and not (tmp_path / "e.png").exists()


def test_exact_with_no_point_beyond_two_epsilon_is_refused_before_the_walks(tmp_path, monkeypatch, capsys):
    # a 3 mm square at the default epsilon: the refusal had come after every walk (86 s at
    # --grid 512 --walks 2000), without the file, the epsilon or what to change
    import geoproc.wos.solve as solve
    from geoproc_cli import main as cli_main

    domain = tmp_path / "sq.json"
    domain.write_text('{"loops": [[[0, 0], [0.003, 0], [0.003, 0.003], [0, 0.003]]]}')
    monkeypatch.setattr(solve.WalkProblem, "estimate_chunked", lambda *a, **k: pytest.fail("walked"))
    monkeypatch.setattr("sys.argv", ["geoproc", "wos-solve", str(domain), "--boundary", "x", "--exact", "--grid",
                                     "64", "-o", str(tmp_path / "u.exr")])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err == (
        f"error: {domain}: --exact: no grid point lies farther than 2 x epsilon (0.002) from the boundary "
        "(the farthest is 0.00148 from it); --epsilon is in domain units (try 3e-06, as 0.001 is to a unit "
        "square), or use a finer --grid\n")
    assert not (tmp_path / "u.exr").exists()


@pytest.mark.slow  # about 30 s of CLI runs: kept out of make test's ten minutes (make test-all runs it)
def test_a_declared_solution_that_is_not_harmonic_gets_a_note(cli, inputs, tmp_path):
    # --exact compares with the function given; one that is not harmonic is not what the walks
    # estimate, and it had passed without a word
    rep = tmp_path / "r.json"
    for boundary, harmonic in (("x*x + y*y", False), ("x**3 - 3*x*y**2", True), ("exp(x)*cos(y)", True)):
        p = cli("wos-solve", inputs / "disk.json", "--boundary", boundary, "--exact", "--grid", "24", "--walks",
                "2", "-o", tmp_path / "u.exr", "--report", rep)
        assert p.returncode == 0, p.stderr
        m = json.loads(rep.read_text())["metrics"]
        defect, gap = m["declared_laplacian"], m["declared_mean_value_gap"]
        assert (defect < 1e-6) if harmonic else (defect > 1.0), (boundary, defect)
        assert (gap < 1e-12) if harmonic else (gap > 0.1), (boundary, gap)  # x^2 + y^2: rho^2 / range
        assert ("--boundary is not harmonic" in p.stderr) != harmonic
    # harmonic but for a point inside (log r with r = 0 at the disk's centre), or across a cut
    # (atan2 in the annulus): the stencils, at grid points away from the point, read harmonic
    for domain, boundary in (("disk.json", "log(sqrt(x*x + y*y))"), ("annulus.json", "atan2(y, x)")):
        p = cli("wos-solve", inputs / domain, "--boundary", boundary, "--exact", "--grid", "16", "--walks", "2",
                "-o", tmp_path / "u.exr", "--report", rep)
        assert p.returncode == 0, p.stderr
        m = json.loads(rep.read_text())["metrics"]
        assert m["declared_laplacian"] < 1e-4 < 0.1 < m["declared_mean_value_gap"], (domain, m)
        assert "its mean over circles inside the domain differs from its value at their centre" in p.stderr
    # far from the origin rounding of the values had read as a Laplacian of 67 (x*x - y*y, 1e12 away),
    # and the note called it not harmonic; now what rounding hides is null, and said
    loops = json.loads((inputs / "disk.json").read_text())["loops"]
    for offset, lap_null, gap_null in ((1e8, True, False), (1e12, True, True)):
        far = tmp_path / "far.json"
        far.write_text(json.dumps({"loops": [[[x + offset, y] for x, y in loop] for loop in loops]}))
        p = cli("wos-solve", far, "--boundary", "x*x - y*y", "--exact", "--grid", "16", "--walks", "2",
                "-o", tmp_path / "u.exr", "--report", rep)
        assert p.returncode == 0 and "not harmonic" not in p.stderr, p.stderr
        m = json.loads(rep.read_text())["metrics"]
        assert (m["declared_laplacian"] is None) == lap_null and (m["declared_mean_value_gap"] is None) == gap_null
        assert ("cannot check that --boundary is harmonic" in p.stderr) == gap_null
    # what a check finds beyond rounding stands: x*x + y*y 1e4 away had read null and passed
    far.write_text(json.dumps({"loops": [[[x + 1e4, y] for x, y in loop] for loop in loops]}))
    p = cli("wos-solve", far, "--boundary", "x*x + y*y", "--exact", "--grid", "16", "--walks", "2",
            "-o", tmp_path / "u.exr", "--report", rep)
    assert p.returncode == 0 and "--boundary is not harmonic (its Laplacian reaches" in p.stderr, p.stderr
    assert json.loads(rep.read_text())["metrics"]["declared_laplacian"] > 1e-4


def test_a_declared_solution_whose_flux_is_not_the_neumann_data_gets_a_note(cli, inputs, tmp_path):
    # y with flux 5 on the rectangle's top and bottom read rmse 3.7 without a word
    rep = tmp_path / "r.json"
    sector = tmp_path / "sector.json"
    sector.write_text(json.dumps(wf.reflex_sector()))
    for domain, boundary, flux, noted in (
            ("rect.json", "y", "5", True), ("rect.json", "x*y", None, True),
            ("rect.json", "y", "2*y - 1", False),  # d/dn y is -1 at the bottom, 1 at the top
            (sector, "(x*x+y*y)**(1/3)*cos(2/3*(atan2(y,x)+0.75*pi))", None, False)):  # zero flux, r^(2/3) apex
        args = ["--boundary", boundary] + (["--neumann", flux] if flux else [])
        p = cli("wos-solve", inputs / domain, *args, "--exact", "--grid", "16", "--walks", "2",
                "-o", tmp_path / "u.exr", "--report", rep)
        assert p.returncode == 0, p.stderr
        gap = json.loads(rep.read_text())["metrics"]["declared_flux_gap"]
        assert (gap > 1) if noted else (gap < 1e-4), (domain, boundary, gap)
        assert ("the normal derivative of --boundary on the Neumann segments differs" in p.stderr) == noted
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--exact", "--grid", "8", "--walks", "2",
            "-o", tmp_path / "u.exr", "--report", rep)
    assert json.loads(rep.read_text())["metrics"]["declared_flux_gap"] is None  # no Neumann segment


def test_output_to_standard_output_is_refused_in_words(cli, inputs, tmp_path):
    # it had read "-o -: must end in .exr", as if "-" were a file name
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--grid", "8", "--walks", "2", "-o", "-")
    assert p.returncode == 2 and p.stdout == b""
    assert p.stderr.strip().splitlines() == [
        "error: -o -: this file is not written to standard output; give a file name ending in .exr"]


@pytest.mark.parametrize("domain,extra,message", [
    # (values past float32's range are refused before the walks, naming the domain)
    ("big_values.json", [], ("error: ", "big_values.json: the domain's values reach 1e+308")),
    # (--boundary past float32's range is refused before the walks, naming the domain)
    ("big_values.json", ["--boundary", "1.7e308 + 0*x"], ("big_values.json: --boundary reaches 1.7e+308",
                                                          "beyond the float32 range of the EXR")),
    # (a flux that large is refused before the walks too, naming it: the walks' sums had overflowed)
    ("rect.json", ["--boundary", "y", "--neumann", "1.7e308"], ("rect.json: --neumann reaches 1.7e+308",
                                                                "far beyond the float32 range")),
    # (a flux finite at the checked points, 1e200 at most, and beyond the doubles within 0.03 of x = 0.1)
    ("rect.json", ["--boundary", "y", "--neumann", "1/(x-0.1)**200", "--grid", "16", "--walks", "16"],
     ("rect.json: the walk estimates at", "(data from --boundary and --neumann)")),
])
def test_walk_estimates_too_large_to_average_name_the_domain(cli, inputs, tmp_path, domain, extra, message):
    # the error line named no file, then named --boundary where the flux was too large
    out = tmp_path / "u.exr"
    size = [] if "--grid" in extra else ["--grid", "4", "--walks", "2"]
    p = cli("wos-solve", inputs / domain, *size, *extra, "-o", out)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and all(m in lines[0] for m in message), p.stderr
    assert not out.exists()


@pytest.mark.parametrize("args,gate,option", [
    ([], "fit_seconds<100", "a control variate"),
    (["--method", "cv-green"], "refine_steps<100", "--method npass"),
    ([], "bias<1", "--exact"),
])
def test_a_check_that_the_method_cannot_report_is_refused_at_once(cli, tmp_path, args, gate, option):
    missing = tmp_path / "missing.json"  # never read when the check is refused first
    p = cli("wos-solve", missing, "--boundary", "x", *args, "-o", tmp_path / "u.exr", "--check", gate)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert f"only with {option}" in p.stderr and "missing.json" not in p.stderr


def test_json_domain_from_stdin(cli, inputs, tmp_path):
    out, rep = tmp_path / "u.exr", tmp_path / "r.json"
    p = cli("wos-solve", "-", "--boundary", "x", "--grid", "16", "--walks", "4", "-o", out, "--report", rep,
            stdin=(inputs / "disk.json").read_bytes())
    assert p.returncode == 0 and p.stderr == "", p.stderr  # no 'traced' note: it is JSON, not a mask
    assert json.loads(rep.read_text())["metrics"]["segments"] == 128
    p = cli("wos-solve", "-", "--boundary", "x", "-o", out, stdin=(inputs / "mask.png").read_bytes())
    assert p.returncode == 2 and "a mask image must be given as a file" in p.stderr


def test_one_walk_has_no_standard_error(cli, inputs, tmp_path):
    # the spread of one walk cannot be measured: null, and a check on it fails
    rep = tmp_path / "r.json"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "1", "--grid", "8", "-o",
            tmp_path / "u.exr", "--report", rep, "--check", "mean_standard_error<=1")
    assert p.returncode == 1 and "mean_standard_error<=1 (not measured in this run" in p.stderr
    assert json.loads(rep.read_text())["metrics"]["mean_standard_error"] is None


def test_a_mask_without_boundary_expression_is_told_that_a_mask_has_no_values(cli, tmp_path):
    mask = np.zeros((32, 32), bool)
    mask[8:24, 8:24] = True
    wf.write_mask(tmp_path / "square.png", mask)
    p = cli("wos-solve", tmp_path / "square.png", "--grid", "8", "--walks", "2", "-o", tmp_path / "u.exr")
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and not (tmp_path / "u.exr").exists()
    assert "square.png: give --boundary 'EXPR' (a mask carries no boundary values)" in lines[0]
    # a JSON domain without values, from standard input or under another name, had been told the same
    square = '{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}'
    (tmp_path / "square.txt").write_text(square)
    for args, kw, name in ((["-"], {"stdin": square.encode()}, "-"), ([tmp_path / "square.txt"], {}, "square.txt")):
        p = cli("wos-solve", *args, "--grid", "8", "--walks", "2", "-o", tmp_path / "u.exr", **kw)
        assert p.returncode == 2 and not (tmp_path / "u.exr").exists(), p.stderr
        assert f"{name}: give --boundary 'EXPR' or per-vertex 'values' in the domain JSON" in p.stderr, p.stderr


def test_naive_reports_no_fit_parameters(cli, inputs, tmp_path):
    rep = tmp_path / "r.json"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--grid", "8", "--walks", "2",
            "-o", tmp_path / "u.exr", "--report", rep)
    assert p.returncode == 0, p.stderr
    params = json.loads(rep.read_text())["params"]
    assert params["method"] == "naive"
    assert all(params[k] is None for k in ("kernels", "fit_walks", "fit_points", "ridge"))


def test_a_mask_is_read_with_standard_error_closed(inputs, tmp_path):
    # the libpng guard redirected descriptor 2 and failed (exit 3) when there was none
    import subprocess
    import sys

    out = tmp_path / "u.exr"
    cmd = [sys.executable, "-m", "geoproc_cli.main", "wos-solve", str(inputs / "mask.png"), "--boundary",
           "(x-32)/24", "--walks", "2", "--grid", "8", "-o", str(out)]
    p = subprocess.run(["bash", "-c", '"$@" 2>&-', "run", *cmd], capture_output=False, stdout=subprocess.DEVNULL)
    assert p.returncode == 0 and out.exists()


def test_an_epsilon_large_for_the_domain_is_noted(cli, tmp_path):
    # a 2 mm square at the default 1e-3: every walk stopped where it started (0 steps)
    dom = tmp_path / "mm.json"
    dom.write_text(json.dumps({"loops": [[[0, 0], [0.002, 0], [0.002, 0.002], [0, 0.002]]]}))
    p = cli("wos-solve", dom, "--boundary", "x", "--grid", "8", "--walks", "4", "-o", tmp_path / "u.exr")
    assert p.returncode == 0
    assert "note: --epsilon 0.001 is 0.35 of the domain's bounding-box diagonal (0.00283)" in p.stderr
    assert "(try 2e-06, as 0.001 is to a unit square)" in p.stderr  # as the --exact refusal suggests
    p = cli("wos-solve", dom, "--boundary", "x", "--grid", "8", "--walks", "4", "--epsilon", "1e-6",
            "-o", tmp_path / "u.exr")
    assert p.returncode == 0 and "--epsilon" not in p.stderr


def test_capped_kernels_and_fit_points_are_noted(cli, inputs, tmp_path):
    rep = tmp_path / "r.json"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "2", "--grid", "8", "--fit-walks", "2",
            "--method", "cv-angle", "--kernels", "500", "--fit-points", "5000", "-o", tmp_path / "u.exr",
            "--report", rep)
    assert p.returncode == 0, p.stderr
    m = json.loads(rep.read_text())["metrics"]
    assert json.loads(rep.read_text())["params"]["ridge"] == 0.1  # cv-angle's default, as used
    assert m["kernels_used"] == 128 and m["fit_points"] < 5000
    assert "note: 128 kernels used, not 500: cv-angle puts at most one on each boundary segment" in p.stderr
    assert f"note: {m['fit_points']} fit points used, not 5000" in p.stderr
    # the default, 8 x the kernels used, is capped with the same note (it had been silent)
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "2", "--grid", "8", "--fit-walks", "2",
            "--method", "cv-green", "-o", tmp_path / "u.exr", "--report", rep)
    m = json.loads(rep.read_text())["metrics"]
    assert p.returncode == 0 and m["fit_points"] < 8 * m["kernels_used"]
    assert (f"note: {m['fit_points']} fit points used, not {8 * m['kernels_used']} (8 x the kernels used)"
            in " ".join(p.stderr.split()))


def test_walks_stalled_at_the_step_cap_are_noted(cli, inputs, tmp_path):
    # a stopping distance below what rounding resolves near the unit disk's boundary: walks stall
    # there and run to the 10,000-step cap (96 s instead of 3 s on a 128 grid), without a word
    rep = tmp_path / "r.json"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "4", "--grid", "4",
            "--epsilon", "1e-20", "-o", tmp_path / "u.exr", "--report", rep)
    assert p.returncode == 0, p.stderr
    steps = json.loads(rep.read_text())["metrics"]["mean_steps_per_walk"]
    assert steps > 5000 and "a walk that reaches 10000 steps stops" in p.stderr and "(1e-20 here)" in p.stderr
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "4", "--grid", "4",
            "--epsilon", "1e-12", "-o", tmp_path / "u.exr")
    assert p.returncode == 0 and "10000 steps" not in p.stderr, p.stderr


def test_fit_options_reach_the_solver(cli, inputs, tmp_path):
    # the EXR is the solver's grid in float32, the same numbers for the same seed: options that
    # the command left out of the call would change them (the report named them all the same)
    from geoproc.wos.expression import parse_expression
    from geoproc.wos.load import load_domain
    from geoproc.wos.solve import solve_laplace

    opts = {"walks": 4, "grid": 24, "kernels": 20, "fit_walks": 64, "ridge": 100.0, "fit_points_n": 90,
            "eps": 0.01}
    out = tmp_path / "u.exr"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--method", "cv-green", "--walks", "4",
            "--grid", "24", "--kernels", "20", "--fit-walks", "64", "--ridge", "100", "--fit-points", "90",
            "--epsilon", "0.01", "--seed", "3", "-o", out, "--quiet")
    assert p.returncode == 0, p.stderr
    domain = load_domain(str(inputs / "disk.json"))
    U = solve_laplace(domain, parse_expression("x"), method="cv-green", seed=3, **opts).U
    np.testing.assert_array_equal(read_exr(str(out)), U.astype(np.float32))
    for key, other in (("fit_walks", 128), ("ridge", None), ("fit_points_n", None), ("kernels", 80),
                       ("eps", 1e-3)):
        V = solve_laplace(domain, parse_expression("x"), method="cv-green", seed=3, **{**opts, key: other}).U
        assert not np.array_equal(V.astype(np.float32), U.astype(np.float32)), key


def test_error_image_shows_only_the_scored_pixels(cli, inputs, tmp_path):
    # |u - exact| on the pixels the metrics use; the band within 2 epsilon of the boundary blank
    from geoproc.wos.expression import parse_expression
    from geoproc.wos.images import png_bytes
    from geoproc.wos.load import load_domain
    from geoproc.wos.solve import solve_laplace

    err_png = tmp_path / "e.png"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "4", "--grid", "24", "--epsilon",
            "0.05", "--exact", "--seed", "3", "-o", tmp_path / "u.exr", "--error-image", err_png, "--quiet")
    assert p.returncode == 0, p.stderr
    res = solve_laplace(load_domain(str(inputs / "disk.json")), parse_expression("x"), walks=4, grid=24,
                        eps=0.05, exact=True, seed=3)
    err = np.abs(res.U - res.exact)
    assert (np.isfinite(err) & ~res.scored).sum() > 10  # the band is there to leave out
    extent = (res.grid.x0, res.grid.x0 + res.grid.nx * res.grid.h, res.grid.y1 - res.grid.ny * res.grid.h, res.grid.y1)
    title = f"disk.json: |error|, naive, rmse {res.metrics['rmse']:.3g}"
    kw = {"cmap": "magma", "contours": 0, "label": "|u - exact|"}
    assert err_png.read_bytes() == png_bytes(np.where(res.scored, err, np.nan), extent, title, **kw)
    assert err_png.read_bytes() != png_bytes(err, extent, title, **kw)


def test_data_the_exr_cannot_hold_and_other_input_edges(cli, tmp_path):
    square = tmp_path / "sq.json"
    square.write_text('{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}')
    out, rep = tmp_path / "u.exr", tmp_path / "r.json"
    # a solution below float32's range had been written as an EXR of zeros, exit 0
    p = cli("wos-solve", square, "--boundary", "1e-50*x", "--grid", "8", "--walks", "8", "-o", out)
    assert p.returncode == 2 and "below the float32 range of EXR" in p.stderr and not out.exists(), p.stderr
    # data beyond it is refused before the walks, in one line (npass had printed six lines of
    # overflow warnings and blamed data past 1e307)
    for method in ("npass", "cv-green"):
        p = cli("wos-solve", square, "--boundary", "1e200*x", "--method", method, "--grid", "8", "--walks", "8",
                "-o", out)
        assert p.returncode == 2 and p.stderr.count("\n") == 1 and "reaches 1e+200" in p.stderr, p.stderr
    # only the Dirichlet data counts: huge --boundary on Neumann sides, where it is not used, runs
    neu = tmp_path / "neu.json"
    neu.write_text('{"loops": [[[0, 0], [2, 0], [2, 1], [0, 1]]], "neumann": [[0, 0], [0, 1], [0, 2]]}')
    p = cli("wos-solve", neu, "--boundary", "1e39*x", "--grid", "8", "--walks", "8", "-q", "-o", out)
    assert p.returncode == 0, p.stderr
    # and so is data large only inside a segment, or in the domain's own values
    p = cli("wos-solve", square, "--boundary", "1e200*x*(1-x)", "--method", "npass", "--grid", "8", "--walks", "8",
            "-o", out)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "reaches 2.5e+199 on the Dirichlet" in p.stderr
    # an error past 1e154 no longer squares to an rmse of inf (reported as null)
    p = cli("wos-solve", square, "--boundary", "1e200*x*(1-x)*y*(1-y)", "--exact", "--grid", "8", "--walks", "8",
            "-q", "-o", out, "--report", rep)
    assert p.returncode == 0 and json.loads(rep.read_text())["metrics"]["rmse"] > 1e198, p.stderr
    # a segment of 1e-30: no overflow warning from its float32 copy under --quiet
    tiny = tmp_path / "tiny.json"
    tiny.write_text('{"loops": [[[0, 0], [1, 0], [1, 1], [1e-30, 1], [0, 1]]]}')
    p = cli("wos-solve", tiny, "--boundary", "x", "--grid", "8", "--walks", "8", "-q", "-o", out)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    # JSON on standard input after more than 64 bytes of white space (had been "not a JSON domain")
    p = cli("wos-solve", "-", "--boundary", "x", "--grid", "8", "--walks", "8", "-q", "-o", out,
            stdin=b" " * 70 + square.read_bytes())
    assert p.returncode == 0, p.stderr
    # cv-angle puts a kernel on every loop: more than --kernels asks, with a note; the report's
    # params name the fit points the run used by default (they had been null)
    three = tmp_path / "three.json"
    three.write_text(json.dumps({"loops": [[[3 * k, 0], [3 * k + 1, 0], [3 * k + 1, 1], [3 * k, 1]]
                                           for k in range(3)]}))
    p = cli("wos-solve", three, "--boundary", "x", "--method", "cv-angle", "--kernels", "2", "--grid", "24",
            "--walks", "8", "-o", out, "--report", rep)
    assert p.returncode == 0 and "3 kernels used, not 2: cv-angle shares them among the 3" in p.stderr, p.stderr
    r = json.loads(rep.read_text())
    assert r["params"]["fit_points"] == r["metrics"]["fit_points"] > 0


def test_stderr_image_is_the_spread_of_the_estimates_over_seeds(cli, inputs, tmp_path):
    # the written standard errors against the spread of the estimate over 48 other seeds
    from geoproc.wos.expression import parse_expression
    from geoproc.wos.load import load_domain
    from geoproc.wos.solve import solve_laplace

    se_exr = tmp_path / "se.exr"
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "16", "--grid", "8", "--seed", "3",
            "-o", tmp_path / "u.exr", "--stderr-image", se_exr, "--quiet")
    assert p.returncode == 0, p.stderr
    SE = read_exr(str(se_exr))
    assert SE.shape == (8, 8) and SE.dtype == np.float32
    U = read_exr(str(tmp_path / "u.exr"))
    assert np.array_equal(np.isnan(SE), np.isnan(U)) and np.isfinite(SE).sum() > 30
    dom = load_domain(str(inputs / "disk.json"))
    runs = np.stack([solve_laplace(dom, parse_expression("x"), walks=16, grid=8, seed=s).U for s in range(100, 148)])
    inside = np.isfinite(SE) & (SE > 0)
    spread = np.mean(runs[:, inside].var(axis=0, ddof=1))
    assert abs(spread / np.mean(SE[inside].astype(float) ** 2) - 1) < 0.15
    # one walk per point has no spread: refused before the walks
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "x", "--walks", "1", "--grid", "8",
            "-o", tmp_path / "v.exr", "--stderr-image", tmp_path / "s1.exr")
    assert p.returncode == 2 and "--stderr-image needs --walks 2 or more" in p.stderr
    assert not (tmp_path / "v.exr").exists() and not (tmp_path / "s1.exr").exists()
    # standard errors below float32's range (a solution of 1e-43) are written, not refused as the solution
    p = cli("wos-solve", inputs / "disk.json", "--boundary", "1e-43*x", "--walks", "8", "--grid", "8",
            "-o", tmp_path / "w.exr", "--stderr-image", tmp_path / "s2.exr", "--quiet")
    assert p.returncode == 0, p.stderr
    SE = read_exr(str(tmp_path / "s2.exr"))
    assert np.nanmax(SE) < 1e-43 and np.array_equal(np.isnan(SE), np.isnan(read_exr(str(tmp_path / "w.exr"))))


def test_the_exr_says_where_it_lies(cli, inputs, tmp_path):
    # the grid's origin and pixel size had been in the report only: now in each EXR's header too,
    # every digit kept (a float attribute rounds 1e12 + 0.5 to 1e12)
    from geoproc.wos.images import exr_attributes

    far = tmp_path / "far.json"
    far.write_text(json.dumps({"loops": [[[1e12 + 0.5, 3], [1e12 + 2.5, 3], [1e12 + 2.5, 4], [1e12 + 0.5, 4]]]}))
    out, se, rep = tmp_path / "u.exr", tmp_path / "se.exr", tmp_path / "r.json"
    p = cli("wos-solve", far, "--boundary", "y", "--grid", "8", "--walks", "4", "-o", out, "--stderr-image", se,
            "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    m = json.loads(rep.read_text())["metrics"]
    expected = {f"geoproc:{k}": m[k] for k in ("grid_left", "grid_top", "pixel_size")}
    assert exr_attributes(str(out)) == expected == exr_attributes(str(se))
    assert expected["geoproc:grid_left"] == 1e12 + 0.5 and expected["geoproc:grid_top"] == 4.0


def test_boundary_given_with_domain_values_says_it_replaces_them(cli, tmp_path):
    dom = tmp_path / "v.json"
    dom.write_text(json.dumps({"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]], "values": [[0, 1, 2, 3]]}))
    p = cli("wos-solve", dom, "--boundary", "x", "--grid", "8", "--walks", "2", "-o", tmp_path / "u.exr")
    assert p.returncode == 0 and f"{dom}: --boundary replaces the domain's own 'values'" in p.stderr
    p = cli("wos-solve", dom, "--grid", "8", "--walks", "2", "-o", tmp_path / "u.exr")
    assert p.returncode == 0 and "replaces" not in p.stderr


def test_a_neumann_flux_from_the_outward_normal(cli, tmp_path):
    # a turned square, Neumann on two opposite sides, u = x y: --neumann 'y*nx + x*ny'
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    P = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) @ np.array([[c, -s], [s, c]]).T
    dom = tmp_path / "turned.json"
    dom.write_text(json.dumps({"loops": [P.tolist()], "neumann": [[0, 0], [0, 2]]}))
    rep = tmp_path / "r.json"
    p = cli("wos-solve", dom, "--boundary", "x*y", "--neumann", "y*nx + x*ny", "--walks", "64", "--grid", "16",
            "--exact", "-m", "cv-green", "--kernels", "40", "-o", tmp_path / "u.exr", "--report", rep, "--quiet")
    assert p.returncode == 0, p.stderr
    m = json.loads(rep.read_text())["metrics"]
    assert m["neumann_segments"] == 2 and m["declared_flux_gap"] < 1e-4 and m["rmse"] < 0.03, m
    p = cli("wos-solve", dom, "--boundary", "x*nx", "--grid", "8", "--walks", "2", "-o", tmp_path / "v.exr")
    assert p.returncode == 2 and p.stderr.count("\n") == 1
    assert "--boundary 'x*nx': nx, the boundary's outward normal, is for a flux (--neumann) only" in p.stderr


def test_ridge_zero_with_fewer_fit_points_than_kernels_falls_back_to_plain_walks(cli, inputs, tmp_path):
    # the minimum-norm fit goes through the fit walks' noise: on the disk with 80 kernels and the
    # few fit points of an 8 x 8 grid its coefficients are huge, and the control variate added them
    # back (the star at grid 12 had an rmse of 3.7e7 against 0.08 for naive, without a word); its
    # variance at the fit points is checked first, and plain walks run instead, with a note
    rep = tmp_path / "r.json"
    base = ("wos-solve", inputs / "disk.json", "--boundary", "exp(x)*cos(y)", "--walks", "8", "--grid", "8",
            "--exact", "-o", tmp_path / "u.exr")
    args = (*base, "--fit-walks", "8", "-m", "cv-green", "--report", rep)
    p = cli(*args, "--ridge", "0")
    m = json.loads(rep.read_text())["metrics"]
    assert p.returncode == 0 and m["fit_points"] <= m["kernels_used"]
    assert m["control_variate_used"] is False and m["control_variate_variance_ratio"] > 1
    assert (f"the control variate fitted at {m['fit_points']} points gave the walks "
            f"{m['control_variate_variance_ratio']:.3g} times the variance of plain walks there: the residual pass "
            "ran plain walks") in " ".join(p.stderr.split()) and "and so does a --ridge above 0)" in p.stderr
    assert "note: --ridge 0 with" not in p.stderr  # (no control variate added anything back)
    naive = tmp_path / "n.json"
    assert cli(*base, "-m", "naive", "--report", naive).returncode == 0
    assert m["rmse"] == json.loads(naive.read_text())["metrics"]["rmse"]  # the same walks as naive
    p = cli(*args)
    m1 = json.loads(rep.read_text())["metrics"]
    assert p.returncode == 0 and "--ridge" not in p.stderr and m1["control_variate_used"] is True
    assert m1["rmse"] < 0.5 * m["rmse"]  # a ridge keeps the fit out of the noise


@pytest.mark.parametrize("method", ["naive", "cv-green", "npass"])
def test_neumann_data_too_large_are_named_for_what_they_are(cli, inputs, tmp_path, method):
    # npass had squared its gradients past 1e154 and blamed data beyond 1e307 for a flux of
    # 1e160; cv-green's fit had warned on 1e308: each now says what is too large, in one line
    out = tmp_path / "u.exr"
    p = cli("wos-solve", inputs / "rect.json", "--boundary", "y", "--neumann", "1e160", "-m", method,
            "--grid", "8", "--walks", "8", "-o", out)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and not out.exists()
    assert "the solution reaches 1." in p.stderr and "e+160, beyond the float32 range of EXR" in p.stderr
    p = cli("wos-solve", inputs / "rect.json", "--boundary", "y", "--neumann", "1e308", "-m", method,
            "--grid", "8", "--walks", "8", "-o", out)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and not out.exists()
    assert ("--neumann reaches 1e+308 on the Neumann boundary, over a domain 2.24 across: the solution would be "
            "far beyond the float32 range of the EXR output") in p.stderr
