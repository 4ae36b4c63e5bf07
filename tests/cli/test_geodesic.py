"""``geoproc geodesic`` through the real command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from geoproc.mesh import Mesh, load_mesh, save_mesh


def _report(path):
    return json.loads(path.read_text())


def test_exact_on_grid_writes_euclidean_distance(cli, fixture_dir, tmp_path):
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "-m", "exact", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    m = load_mesh(out)
    ref = np.linalg.norm(m.V - m.V[0], axis=1)
    assert np.abs(m.vertex_fields["distance"] - ref).max() < 1e-12
    r = _report(rep)
    assert r["metrics"]["max_distance"] == pytest.approx(np.sqrt(2), rel=1e-12)
    assert r["metrics"]["unreachable_vertices"] == 0


def test_reference_file_gives_the_same_metrics_as_the_exact_reference(cli, fixture_dir, tmp_path, make_fixtures):
    # a stored run (a mesh with a 'distance' property, or a .npy) as the reference: the metrics are
    # those of --reference exact when the file holds the exact distances; +inf marks unreached vertices
    V, F = make_fixtures.icosphere(2)
    two = Mesh(np.concatenate([V, V + [3.0, 0, 0]]), np.concatenate([F, F + len(V)]))  # source on one sphere
    src, golden, npy = tmp_path / "two.ply", tmp_path / "golden.ply", tmp_path / "golden.npy"
    save_mesh(src, two)
    p = cli("geodesic", src, "-s", "3", "-m", "exact", "-o", golden, "--quiet")
    assert p.returncode == 0, p.stderr
    d = load_mesh(golden).vertex_fields["distance"]
    assert np.isinf(d[len(V):]).all()
    np.save(npy, d)
    got = {}
    for ref in ("exact", golden, npy):
        rep = tmp_path / "r.json"
        p = cli("geodesic", src, "-s", "3", "-m", "heat", "--reference", ref, "-o", tmp_path / "h.ply",
                "--report", rep, "--quiet")
        assert p.returncode == 0, p.stderr
        r = _report(rep)
        got[str(ref)] = r["metrics"]
        assert r["params"]["reference"] == str(ref)
        if ref != "exact":
            assert [i["path"] for i in r["inputs"]] == [str(src), str(ref)]
    ref_metrics = ("pearson_r", "rmse", "mae", "mean_relative_error", "max_relative_error", "compared_vertices")
    for ref in (golden, npy):
        assert {k: got[str(ref)][k] for k in ref_metrics} == {k: got["exact"][k] for k in ref_metrics}
    assert got["exact"]["compared_vertices"] == len(V) and 0 < got["exact"]["mean_relative_error"] < 0.05
    # from standard input too
    p = cli("geodesic", src, "-s", "3", "-m", "heat", "--reference", "-", "-o", tmp_path / "h.ply", "--report",
            tmp_path / "r.json", "--quiet", stdin=golden.read_bytes())
    assert p.returncode == 0 and _report(tmp_path / "r.json")["metrics"]["rmse"] == got["exact"]["rmse"]


def test_reference_files_from_stdin_float32_and_on_non_manifold_meshes(cli, tmp_path, make_fixtures):
    # a stored reference needs none of the exact reference's checks (two spheres touching at a
    # vertex: exact refuses them); a .npy comes through standard input too; a float32 copy of a
    # mesh far from the origin is the same mesh
    from plyfile import PlyData, PlyElement

    V, F = make_fixtures.icosphere(2)
    mirrored = V - 2 * (V @ V[0] - 1)[:, None] * V[0]
    two = Mesh(np.concatenate([V, mirrored]) + 100.0, np.concatenate([F, np.where(F == 0, 0, F + len(V))[:, ::-1]]))
    src, d_ply, d_npy = tmp_path / "two.ply", tmp_path / "d.ply", tmp_path / "d.npy"
    save_mesh(src, two)
    p = cli("geodesic", src, "-s", "5", "-m", "exact", "-o", tmp_path / "x.ply")
    assert p.returncode == 2 and "--reference exact needs" not in p.stderr and "non-manifold" in p.stderr
    p = cli("geodesic", src, "-s", "5", "-o", d_ply, "--quiet")
    assert p.returncode == 0, p.stderr
    m = load_mesh(d_ply)
    np.save(d_npy, m.vertex_fields["distance"])
    vertex = np.empty(len(m.V), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("distance", "f8")])
    for k, c in enumerate("xyz"):
        vertex[c] = m.V[:, k]
    vertex["distance"] = m.vertex_fields["distance"]
    face = np.empty(len(m.F), dtype=[("vertex_indices", "i4", (3,))])
    face["vertex_indices"] = m.F
    f32 = tmp_path / "f32.ply"
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(face, "face")]).write(str(f32))
    for ref, stdin in ((d_ply, None), ("-", d_npy.read_bytes()), (f32, None)):
        rep = tmp_path / "r.json"
        p = cli("geodesic", src, "-s", "5", "-m", "varadhan", "--reference", ref, "-o", tmp_path / "v.ply",
                "--report", rep, "--quiet", stdin=stdin)
        assert p.returncode == 0, (ref, p.stderr)
        met = _report(rep)["metrics"]
        assert met["compared_vertices"] == len(m.V) and 0 < met["mean_relative_error"] < 0.5


def test_bad_reference_files_are_one_line_errors(cli, fixture_dir, tmp_path):
    src = fixture_dir / "icosphere.ply"
    n = len(load_mesh(src).V)
    nan, short = tmp_path / "nan.npy", tmp_path / "short.npy"
    v = np.ones(n)
    v[4] = np.nan
    np.save(nan, v)
    np.save(short, np.ones(n - 1))
    negative = tmp_path / "negative.npy"
    np.save(negative, -np.arange(n, dtype=float))  # no positive distance: every error would be null
    for ref, needle in ((tmp_path / "exakt", "--reference " + str(tmp_path / "exakt") + ": no such file (give exact"),
                        (fixture_dir / "torus.ply", "the reference mesh has"),
                        (src, "no vertex property 'distance' (--field-name; --reference-field names another)"),
                        (nan, "1 reference distance is NaN or -inf (first: vertex 4)"),
                        (short, f"{n - 1} reference distances for {n} vertices"),
                        (negative, "no reference distance is finite and above 0")):
        out = tmp_path / "o.ply"
        p = cli("geodesic", src, "-s", "0", "--reference", ref, "-o", out)
        lines = p.stderr.strip().splitlines()
        assert p.returncode == 2 and len(lines) == 1 and needle in lines[0], (ref, p.stderr)
        assert not out.exists()
    moved = tmp_path / "moved.ply"
    m = load_mesh(src)
    save_mesh(moved, Mesh(m.V * 1.001, m.F, vertex_fields={"distance": np.ones(n)}))
    p = cli("geodesic", src, "-s", "0", "--reference", moved, "-o", tmp_path / "o.ply")
    assert p.returncode == 2 and "it must be the same mesh, with its vertices in the same order" in p.stderr


def test_heat_with_reference_on_sphere(cli, fixture_dir, tmp_path):
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "icosphere.ply", "-s", "3", "-m", "heat", "--reference", "exact",
            "-o", out, "--report", rep, "--check", "mean_relative_error<=0.02")
    assert p.returncode == 0, p.stderr
    met = _report(rep)["metrics"]
    assert met["pearson_r"] > 0.999
    assert met["mae"] == met["mean_relative_error"] < 0.02
    assert 0 <= met["rmse"] and met["max_relative_error"] < 0.1
    timings = _report(rep)["timings_s"]
    assert {"setup", "solve", "reference"} <= set(timings)
    # independent check of the written field: great-circle distance on the unit sphere
    m = load_mesh(out)
    arc = np.arccos(np.clip(m.V @ m.V[3], -1, 1))
    assert np.abs(m.vertex_fields["distance"] - arc).mean() / np.pi < 0.02


def test_input_properties_are_kept_and_field_renamed(cli, make_fixtures, tmp_path):
    V, F = make_fixtures.grid(11)
    src = tmp_path / "in.ply"
    save_mesh(src, Mesh(V, F, vertex_fields={"quality": np.arange(len(V), dtype=float)}))
    out = tmp_path / "d.ply"
    p = cli("geodesic", src, "-s", "5", "-m", "log-heat", "--field-name", "geo", "-o", out)
    assert p.returncode == 0, p.stderr
    m = load_mesh(out)
    assert np.array_equal(m.vertex_fields["quality"], np.arange(len(V), dtype=float))
    assert "distance" not in m.vertex_fields
    ref = np.linalg.norm(V - V[5], axis=1)
    assert np.abs(m.vertex_fields["geo"] - ref).mean() / ref.max() < 0.03


def test_sources_file_and_stdout(cli, fixture_dir, tmp_path):
    sf = tmp_path / "s.txt"
    sf.write_text("\ufeff# two corners\n0, 0000000000000000000000000440\n", encoding="utf-8")  # a BOM, leading zeros
    p = cli("geodesic", fixture_dir / "grid.ply", "--sources-file", sf, "-m", "exact", "-o", "-")
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith(b"ply")
    out = tmp_path / "o.ply"
    out.write_bytes(p.stdout)
    m = load_mesh(out)
    ref = np.minimum(np.linalg.norm(m.V - m.V[0], axis=1), np.linalg.norm(m.V - m.V[440], axis=1))
    assert np.abs(m.vertex_fields["distance"] - ref).max() < 1e-12


@pytest.mark.parametrize("content,shown", [
    (b"0\n1x\n", "line 2: '1x' is not a vertex index"),
    (b"\xff\xfe1\n", "line 1: '\\xff\\xfe1' is not a vertex index"),  # bytes that are not UTF-8
    ("0 \u0661\n".encode(), "line 1: '\\u0661' is not a vertex index"),  # an Arabic-Indic digit
    # int() refuses past 4300 digits: the run ended as an internal error, exit 3
    (b"0\n" + b"9" * 5000 + b"\n", "line 2: a 5000-digit number is beyond any vertex index"),
    (b"0\n" + b"0" * 30 + b"9" * 21 + b"\n", "line 2: a 21-digit number is beyond any vertex index"),
])
def test_a_bad_token_in_the_sources_file_is_shown_in_ascii(cli, fixture_dir, tmp_path, content, shown):
    sf = tmp_path / "s.txt"
    sf.write_bytes(content)
    p = cli("geodesic", fixture_dir / "grid.ply", "--sources-file", sf, "-o", tmp_path / "o.ply")
    assert p.returncode == 2 and p.stderr.strip().endswith(shown), p.stderr
    assert p.stderr.isascii() or "s.txt" not in p.stderr


def test_leading_zeros_in_the_sources_file_are_read_past_pythons_digit_limit(cli, fixture_dir, tmp_path):
    # int() counts leading zeros towards its 4300 digits: an internal error, exit 3
    sf, out = tmp_path / "s.txt", tmp_path / "o.ply"
    sf.write_text("0\n+" + "0" * 5000 + "440\n")
    p = cli("geodesic", fixture_dir / "grid.ply", "--sources-file", sf, "-m", "exact", "-o", out,
            "--report", tmp_path / "r.json")
    assert p.returncode == 0, p.stderr
    assert json.loads((tmp_path / "r.json").read_text())["metrics"]["sources"] == 2


def test_a_source_out_of_range_in_the_sources_file_names_its_line(cli, fixture_dir, tmp_path):
    # it had been reported against the mesh, with no line
    sf = tmp_path / "s.txt"
    sf.write_text("0 1\n# far\n5, 441\n")
    p = cli("geodesic", fixture_dir / "grid.ply", "--sources-file", sf, "-o", tmp_path / "o.ply")
    assert p.returncode == 2 and not (tmp_path / "o.ply").exists()
    assert p.stderr.strip() == (f"error: {sf}: line 3: source vertex 441 is out of range (the mesh "
                                f"{fixture_dir / 'grid.ply'} has 441 vertices)")


def test_a_source_given_twice_counts_once(cli, fixture_dir, tmp_path):
    rep = tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "-s", "0", "-s", "440", "-m", "exact",
            "-o", tmp_path / "o.ply", "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    assert json.loads(rep.read_text())["metrics"]["sources"] == 2
    out = load_mesh(tmp_path / "o.ply")
    ref = np.minimum(np.linalg.norm(out.V - out.V[0], axis=1), np.linalg.norm(out.V - out.V[440], axis=1))
    assert np.abs(out.vertex_fields["distance"] - ref).max() < 1e-12


def test_sources_from_stdin_and_all_sources_against_exact(cli, fixture_dir, tmp_path):
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "grid.ply", "--sources-file", "-", "-m", "exact", "-o", out,
            stdin=b"0 440\n")
    assert p.returncode == 0, p.stderr
    d = load_mesh(out).vertex_fields["distance"]
    assert d[0] == 0 and d[440] == 0 and d.max() > 0
    # every vertex a source: the relative errors are undefined (null), with no warning on stderr
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    tri = tmp_path / "tri.ply"
    save_mesh(tri, Mesh(V, np.array([[0, 1, 2]])))
    args = ("geodesic", tri, "-s", "0", "-s", "1", "-s", "2", "--reference", "exact", "-o", out)
    p = cli(*args, "--report", rep)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert _report(rep)["metrics"]["mean_relative_error"] is None
    p = cli(*args, "--check", "mean_relative_error<=0.1")  # not measured: the gate fails
    assert p.returncode == 1 and "not measured in this run" in p.stderr
    p = cli(*args, "--check", "method==1")  # a text metric cannot be gated: usage error, before the run
    assert p.returncode == 2 and "geodesic's metric 'method' is text, not a number" in p.stderr


def test_render_to_standard_output(cli, fixture_dir, tmp_path):
    # as morse-simplify's --diagram: --render - had been refused as not ending in .png
    out = tmp_path / "d.ply"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", out, "--render", "-", "-q")
    assert p.returncode == 0 and p.stdout[:8] == b"\x89PNG\r\n\x1a\n" and out.exists(), p.stderr
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", "-", "--render", "-")
    assert p.returncode == 2 and p.stdout == b""


def test_render_writes_a_png(cli, fixture_dir, tmp_path):
    out, png = tmp_path / "d.ply", tmp_path / "d.png"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", out, "--render", png)
    assert p.returncode == 0, p.stderr
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10000
    # the picture is that of the written distances with the source marked (red dots)
    import io

    import matplotlib.image

    from geoproc.geodesic.render import render_distance_png

    m = load_mesh(out)
    assert data == render_distance_png(m.V, m.F, m.vertex_fields["distance"], [0], title="torus.ply: heat")
    img = matplotlib.image.imread(io.BytesIO(data))[..., :3]
    assert ((img[..., 0] > 0.8) & (img[..., 1] < 0.3) & (img[..., 2] < 0.3)).sum() > 20


def test_unreachable_component_is_inf_and_counted(cli, make_fixtures, tmp_path):
    V1, F1 = make_fixtures.grid(11)
    src = tmp_path / "two.ply"
    save_mesh(src, Mesh(np.vstack([V1, V1 + [3.0, 0, 0]]), np.vstack([F1, F1 + len(V1)])))
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("geodesic", src, "-s", "0", "-m", "log-ode", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    assert _report(rep)["metrics"]["unreachable_vertices"] == len(V1)
    d = load_mesh(out).vertex_fields["distance"]
    assert np.isinf(d[len(V1):]).all() and np.isfinite(d[: len(V1)]).all()
    # the note names the mesh, as an error line does (batch jobs interleave their stderr)
    assert f"note: {src}: {len(V1)} vertices are not connected to a source" in " ".join(p.stderr.split())


def test_log_ode_cvxpy_solver_matches_default(cli, make_fixtures, tmp_path):
    pytest.importorskip("cvxpy")
    small = tmp_path / "ico2.ply"
    save_mesh(small, Mesh(*make_fixtures.icosphere(2)))
    outs = []
    for solver in ("lu", "cvxpy"):
        out = tmp_path / f"{solver}.ply"
        p = cli("geodesic", small, "-s", "0", "-m", "log-ode", "--steps", "2",
                "--solver", solver, "-o", out)
        assert p.returncode == 0, p.stderr
        outs.append(load_mesh(out).vertex_fields["distance"])
    assert np.abs(outs[0] - outs[1]).max() < 1e-6


def test_cvxpy_inaccurate_steps_are_a_note_not_a_warning(cli, fixture_dir, tmp_path):
    # on the torus Clarabel ends a step as "optimal_inaccurate"; CVXPY's
    # UserWarning used to reach stderr even with --quiet
    pytest.importorskip("cvxpy")
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    args = ("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", "log-ode", "--solver", "cvxpy", "-n", "3",
            "-o", out, "--report", rep)
    p = cli(*args, "--quiet")
    assert p.returncode == 0 and p.stderr == ""
    inaccurate = json.loads(rep.read_text())["metrics"]["solver_inaccurate_steps"]
    p = cli(*args)
    assert "UserWarning" not in p.stderr
    assert ("short of its tolerances" in p.stderr) == (inaccurate > 0)


def test_cvxpy_step_that_clarabel_cannot_solve_is_refused(cli, fixture_dir, tmp_path):
    # a time factor of 1e6 (within the allowed range): Clarabel fails, which was an internal error (exit 3)
    pytest.importorskip("cvxpy")
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", "log-ode", "--solver", "cvxpy", "-c", "1e6",
            "-o", out, "--report", rep)
    assert p.returncode == 2, p.stderr
    assert p.stderr.count("\n") == 1 and "torus.ply" in p.stderr and "--solver lu" in p.stderr
    assert not out.exists() and not rep.exists()


@pytest.mark.parametrize("args,tail", [
    (["-m", "exact"], "libigl's exact geodesic (MMP) does not return on some such meshes"),
    (["-m", "heat", "--reference", "exact"],
     "libigl's exact geodesic (MMP, --reference exact) does not return on some such meshes"),
])
def test_exact_needle_refusal_names_what_needs_it(cli, make_fixtures, tmp_path, args, tail):
    # the plain -m exact message had come to read "(MMP, method 'exact')" once the
    # checks also served --reference exact
    V, F = make_fixtures.grid(8)
    src = tmp_path / "needles.ply"
    save_mesh(src, Mesh(V * [3e-6, 1, 1], F))
    p = cli("geodesic", src, "-s", "0", *args, "-o", tmp_path / "d.ply")
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and lines[0].endswith(tail), p.stderr


@pytest.mark.parametrize("squash,args,fragment", [
    # libigl's exact geodesic ran for minutes on this 8 x 8 grid (angles 3e-6 rad)
    (3e-6, ["-m", "exact"], "below 0.0001 rad"),
    (3e-6, ["--reference", "exact"], "below 0.0001 rad"),
    # the heat method's Poisson step gave errors of 80 % of the grid's length at 1e-7 rad
    (1e-7, ["--operators", "extrinsic"], "below 1e-06 rad"),
    # its default (auto) goes intrinsic there, where libigl's flips did not return
    (1e-7, [], "below 1e-07 rad"),
    (1e-7, ["-m", "log-heat", "--operators", "extrinsic"], "below 1e-06 rad"),
    # varadhan's cotan solve returned inf at 1e-9 rad
    (1e-9, ["-m", "varadhan"], "below 1e-07 rad"),
    (1e-9, ["-m", "log-ode", "--laplacian", "cotan"], "below 1e-07 rad"),
    # a surface made of needles: libigl's intrinsic Delaunay flips did not return on one
    (1e-9, ["-m", "log-ode"], "below 1e-07 rad"),
    (1e-9, ["-m", "log-heat"], "below 1e-07 rad"),
])
def test_needles_are_refused_where_the_method_fails(cli, make_fixtures, tmp_path, squash, args, fragment):
    V, F = make_fixtures.grid(8)
    src = tmp_path / "needles.ply"
    save_mesh(src, Mesh(V * [squash, 1, 1], F))
    out = tmp_path / "d.ply"
    p = cli("geodesic", src, "-s", "0", *args, "-o", out)
    assert p.returncode == 2 and not out.exists()
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "needles.ply: 98 of 98 faces have an angle " + fragment in lines[0]
    # a grid squashed to 1e-5 passes the varadhan limit and runs
    save_mesh(src, Mesh(V * [1e-5, 1, 1], F))
    assert cli("geodesic", src, "-s", "0", "-m", "varadhan", "-o", out).returncode == 0


@pytest.mark.parametrize("args", [["-m", "log-heat"], ["-m", "varadhan", "--laplacian", "intrinsic-delaunay"]])
def test_faces_degenerate_within_rounding_are_refused_on_the_intrinsic_paths(cli, make_fixtures, tmp_path, args):
    # a sphere squashed to 1e-20: its 16 equator faces are needles of 1e-20 rad, and
    # libigl's intrinsic Delaunay flips did not return (memory grew past 15 GB)
    V, F = make_fixtures.icosphere(2)
    src, out = tmp_path / "flat.ply", tmp_path / "d.ply"
    save_mesh(src, Mesh(V * [1, 1, 1e-20], F))
    p = cli("geodesic", src, "-s", "0", *args, "-o", out)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and not out.exists()
    assert "flat.ply: 16 of 320 faces have an angle below 1e-14 rad" in lines[0]
    save_mesh(src, Mesh(V * [1, 1, 1e-12], F))  # needles of 1e-12 rad: the flips remove them
    assert cli("geodesic", src, "-s", "0", *args, "-o", out).returncode == 0


def _isolated_vertex_mesh(make_fixtures, tmp_path):
    V, F = make_fixtures.grid(5)
    path = tmp_path / "iso.ply"
    save_mesh(path, Mesh(np.vstack([V, [[5.0, 5.0, 0.0]]]), F))
    return path, len(V)


BAD = [
    (["-s", "441"], "grid.ply", "source vertex 441 is out of range"),
    (["-s", "0", "--time", "0"], "grid.ply", "--time must be a positive finite number"),
    (["-s", "0", "--time", "nan"], "grid.ply", "--time nan: must be a finite number"),
    # named as typed: 1e400 had been named inf
    (["-s", "0", "--time=1e400"], "grid.ply", "--time 1e400 (which reads as inf): must be a finite number"),
    (["-s", "0", "--time-factor", "-1E999"], "grid.ply", "--time-factor -1E999 (which reads as -inf): must be a"),
    # names the other commands read as normals or outlier flags (a distance written as nx had been lost)
    (["-s", "0", "--field-name", "nx"], "grid.ply", "--field-name 'nx': a PLY property of that name holds vertex"),
    (["-s", "0", "--field-name", "outlier"], "grid.ply", "holds outlier flags, which denoise --outliers scores"),
    (["-s", "0", "--field-name", "end_header"], "grid.ply", "take a property of that name for the header's end"),
    # a short form is named as typed too (it had been '--time-factor inf')
    (["-s", "0", "-c", "1e400"], "grid.ply", "error: -c 1e400 (which reads as inf): must be a finite number"),
    (["-s", "0", "-t-1e999"], "grid.ply", "error: -t -1e999 (which reads as -inf): must be a finite number"),
    (["-s", "0", "--time-factor", "-2"], "grid.ply", "--time-factor must be a positive"),
    (["-s", "0", "-m", "varadhan", "--steps", "0"], "grid.ply", "'-n': Input should be greater than or equal to 1"),
    (["-s", "0", "-m", "log-ode", "-n", "100001"], "grid.ply", "'-n': Input should be less than or equal to 100000"),
    (["--sources-file", "."], "grid.ply", "error: .: is a directory, not a file of source indices"),
    (["-s", "0"], "fin.obj", "non-manifold"),
    (["-s", "0", "-m", "exact"], "bowtie.obj", "non-manifold"),
    # the exact reference's needs are checked before the chosen method runs, and named as its own
    (["-s", "0", "-m", "heat", "--reference", "exact"], "bowtie.obj", "; --reference exact needs a manifold mesh"),
    # ... after the checks every method makes (the sources, a mesh of no area)
    (["-s", "9", "-m", "log-ode", "--reference", "exact"], "bowtie.obj", "source vertex 9 is out of range"),
    (["-s", "0"], "points.ply", "point cloud"),
    (["-s", "0"], "zero_area.off", "zero area"),
    ([], "grid.ply", "at least one source"),
    # refused, not ignored: options the method does not use
    (["-s", "0", "-m", "exact", "-c", "-1"], "grid.ply", "--time-factor: not used by -m exact"),
    (["-s", "0", "-m", "heat", "--solver", "newton"], "grid.ply", "--solver: only with -m log-ode"),
    (["-s", "0", "-m", "heat", "-n", "3"], "grid.ply", "--steps: not used by -m heat"),
    (["-s", "0", "-m", "varadhan", "--operators", "intrinsic"], "grid.ply", "--operators: only with -m heat"),
    # diffusion times double precision cannot carry
    (["-s", "0", "-m", "log-ode", "-t", "5e-324"], "grid.ply", "grid.ply: time step 4.94066e-324 is too small"),
    (["-s", "0", "-m", "log-heat", "-c", "1e4", "-n", "20"], "grid.ply", "grid.ply: the heat at t = "),
    (["-s", "0", "-m", "log-heat", "-c", "1e13"], "grid.ply", "--time-factor 10000000000000 is more than 1e+12"),
    (["-s", "0", "-m", "heat", "-t", "1e300"], "grid.ply", "is more than 1e+12 h^2"),
    (["-s", "0", "-m", "heat", "-c", "1.0000001e12"], "grid.ply", "--time-factor 1000000100000 is more than 1e+12"),
    (["--sources-file", "-", "-s", "0"], "-", "standard input can feed only one input"),
    (["-s", "0", "-c", "2", "-t", "0.01"], "grid.ply", "--time-factor and --time: give one"),
    (["-s", "0", "--operators", "intrinsic", "--laplacian", "cotan"], "grid.ply", "not used with --operators intr"),
    (["-s", "0", "--render", "d.jpg"], "grid.ply", "--render d.jpg: must end in .png (or be -)"),
]


@pytest.mark.parametrize("args,mesh,message", BAD)
def test_bad_input_exits_2_with_one_line(cli, fixture_dir, tmp_path, args, mesh, message):
    out = tmp_path / "d.ply"
    p = cli("geodesic", fixture_dir / mesh if mesh != "-" else "-", *args, "-o", out,
            stdin=(fixture_dir / "grid.ply").read_bytes())
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0]
    assert not out.exists()


def test_source_on_isolated_vertex_exits_2(cli, make_fixtures, tmp_path):
    path, iso = _isolated_vertex_mesh(make_fixtures, tmp_path)
    out = tmp_path / "d.ply"
    p = cli("geodesic", path, "--no-clean", "-s", str(iso), "-o", out)
    assert p.returncode == 2
    assert p.stderr.strip() == f"error: {path}: source vertex {iso} is isolated (no face uses it)"
    assert not out.exists()


def test_log_ode_with_negative_cotan_weights_exits_2(cli, make_fixtures, tmp_path):
    V, F = make_fixtures.icosphere(2)
    path = tmp_path / "flat.ply"
    save_mesh(path, Mesh(V * [1.0, 1.0, 0.05], F))
    out = tmp_path / "d.ply"
    p = cli("geodesic", path, "-s", "0", "-m", "log-ode", "--laplacian", "cotan", "-o", out)
    assert p.returncode == 2
    W = V * [1.0, 1.0, 0.05]
    weight: dict[tuple[int, int], float] = {}
    for f in F:  # cot of the angle at each corner, added to the opposite edge
        for k in range(3):
            a, b, c = f[k], f[(k + 1) % 3], f[(k + 2) % 3]
            u, v = W[b] - W[a], W[c] - W[a]
            key = (min(b, c), max(b, c))
            weight[key] = weight.get(key, 0.0) + u @ v / np.linalg.norm(np.cross(u, v))
    negative = sum(w < 0 for w in weight.values())
    assert negative > 0 and p.stderr.strip().splitlines() == [
        f"error: {path}: {negative} edges have negative cotangent weights, and the log-ODE needs "
        "non-negative ones; use --laplacian intrinsic-delaunay"]
    assert not out.exists()
    # log-heat's heat step is a log-ODE too: the same line, naming the file (it named none)
    p = cli("geodesic", path, "-s", "0", "-m", "log-heat", "--laplacian", "cotan", "--operators", "extrinsic",
            "-o", out)
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [
        f"error: {path}: {negative} edges have negative cotangent weights, and the log-ODE needs "
        "non-negative ones; use --laplacian intrinsic-delaunay"]
    assert not out.exists()


def test_non_ply_output_is_refused(cli, fixture_dir, tmp_path):
    out = tmp_path / "d.obj"
    p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "-o", out)
    assert p.returncode == 2 and "only PLY keeps" in p.stderr and not out.exists()


def test_varadhan_infinities_on_a_connected_mesh_are_noted(cli, fixture_dir, tmp_path):
    # t = 1e-20 h^2 on the (connected) torus: the heat underflows or goes negative on
    # most vertices and Varadhan's formula leaves them at +inf; only the metric said so
    out, rep = tmp_path / "v.ply", tmp_path / "v.json"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", "varadhan", "-c", "1e-20", "-o", out,
            "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _report(rep)["metrics"]
    d = load_mesh(out).vertex_fields["distance"]
    assert met["unreachable_vertices"] == 0 and met["nonfinite_distance_vertices"] == np.isinf(d).sum() > 100
    assert (f"note: {fixture_dir / 'torus.ply'}: {met['nonfinite_distance_vertices']} vertices connected to a "
            "source have no finite distance (the heat there is 0 or negative") in " ".join(p.stderr.split())
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", "varadhan", "-o", out)
    assert p.returncode == 0 and "no finite distance" not in p.stderr


def test_tiny_time_on_armadillo(cli, shared_data, tmp_path):
    """t = 1e-4 h^2: u underflows for heat and varadhan (the report counts it),
    while log-ode and log-heat stay finite everywhere; heat solves its step
    again in the log domain unless told to keep the plain one."""
    import geoproc.geodesic as gd

    mesh = shared_data / "meshes" / "armadillo.obj"
    out, rep = tmp_path / "heat.ply", tmp_path / "heat.json"
    p = cli("geodesic", mesh, "-s", "0", "-m", "heat", "--time-factor", "1e-4", "--heat-underflow", "keep",
            "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _report(rep)["metrics"]
    n = met["vertices"]
    assert met["zero_heat_vertices"] > n // 2 and met["heat_step_in_log_domain"] is False
    assert (f"note: {mesh}: {met['underflow_heat_vertices']} vertices where heat u underflowed below the smallest "
            f"normal double ({met['zero_heat_vertices']} to 0)") in " ".join(p.stderr.split())
    fixed = tmp_path / "fixed.ply"
    p = cli("geodesic", mesh, "-s", "0", "-m", "heat", "--time-factor", "1e-4", "-o", fixed, "--report", rep)
    assert p.returncode == 0, p.stderr
    assert _report(rep)["metrics"]["heat_step_in_log_domain"] is True
    assert "solved again in the log domain" in p.stderr
    m = load_mesh(mesh)
    run = {k: gd.geodesic_distance(m.V, m.F, [0], k, time_factor=1e-4)
           for k in ("varadhan", "log-ode", "log-heat")}
    assert run["varadhan"].stats["zero_heat_vertices"] > n // 2
    assert np.isinf(run["varadhan"].distance).sum() >= run["varadhan"].stats["zero_heat_vertices"]
    for k in ("log-ode", "log-heat"):
        assert np.isfinite(run[k].distance).all()
        assert run[k].stats["nonfinite_log_heat"] == 0
        # finite although exp(w) is below the smallest double on most vertices
        assert run[k].stats["log_heat_below_double"] > n // 2
    # log-heat stays meaningful: its distance grows away from the source
    # (the heat method's normalized gradient is 0/0 where u == 0)
    euclid = np.linalg.norm(m.V - m.V[0], axis=1)
    assert np.corrcoef(run["log-heat"].distance, euclid)[0, 1] > 0.9
    assert np.corrcoef(load_mesh(out).vertex_fields["distance"], euclid)[0, 1] < 0.75  # measured 0.67
    np.testing.assert_allclose(load_mesh(fixed).vertex_fields["distance"], run["log-heat"].distance,
                               rtol=0, atol=1e-9 * run["log-heat"].distance.max())


@pytest.mark.slow
def test_log_heat_at_tiny_time_against_exact_on_armadillo(shared_data):
    import geoproc.geodesic as gd

    m = load_mesh(shared_data / "meshes" / "armadillo.obj")
    ref = gd.exact_geodesic_distance(m.V, m.F, np.array([0]))
    d = gd.geodesic_distance(m.V, m.F, [0], "log-heat", time_factor=1e-4).distance
    c = gd.compare_to_reference(d, ref)
    # measured r = 0.9965, mean relative error 12 %; the heat method gives r = -0.56 here
    assert c["pearson_r"] > 0.99 and c["mean_relative_error"] < 0.2


def test_log_splitting_orders_vertices_like_exact_geodesics(cli, fixture_dir, tmp_path):
    # LogHeatBackward from the 1e-300 floor: the distances carry a large offset (the
    # floor diffuses in log space), but they rank the vertices like the true distance.
    pytest.importorskip("clarabel")
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "icosphere.ply", "-s", "3", "-m", "log-splitting", "--steps", "2",
            "--reference", "exact", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _report(rep)["metrics"]
    assert met["pearson_r"] > 0.99  # measured 0.9987
    assert met["nonfinite_log_heat"] == 0 and np.isfinite(load_mesh(out).vertex_fields["distance"]).all()


def test_log_heat_goes_intrinsic_on_a_mesh_of_slivers(cli, make_fixtures, tmp_path):
    V, F = make_fixtures.torus(r=0.4, nu=60, nv=20, twist=3)  # 40% of faces with an angle below 5 deg
    src = tmp_path / "slivers.ply"
    save_mesh(src, Mesh(V, F))
    errors = {}
    for method, ops in (("log-heat", None), ("heat", None), ("heat", "extrinsic")):
        rep = tmp_path / "r.json"
        p = cli("geodesic", src, "-s", "0", "-m", method, *(["--operators", ops] if ops else []),
                "--reference", "exact", "-o", tmp_path / "d.ply", "--report", rep)
        assert p.returncode == 0, p.stderr
        met = _report(rep)["metrics"]
        errors[method, ops] = (met["operators"], met["mean_relative_error"])
    assert errors["log-heat", None][0] == "intrinsic" and errors["log-heat", None][1] < 0.03
    assert errors["heat", None][0] == "intrinsic" and errors["heat", None][1] < 0.03
    assert errors["heat", "extrinsic"][1] > 0.1  # the paper's operators


def test_laplacian_unused_by_auto_intrinsic_is_noted(cli, make_fixtures, tmp_path):
    V, F = make_fixtures.torus(r=0.4, nu=60, nv=20, twist=3)  # auto goes intrinsic here
    src = tmp_path / "slivers.ply"
    save_mesh(src, Mesh(V, F))
    args = ("geodesic", src, "-s", "0", "-m", "log-heat", "-o", tmp_path / "d.ply")
    p = cli(*args, "--laplacian", "cotan")
    assert p.returncode == 0, p.stderr
    assert "--laplacian cotan not used: --operators auto chose the intrinsic operators" in p.stderr
    p = cli(*args, "--laplacian", "cotan", "--quiet")
    assert p.returncode == 0 and p.stderr == ""
    p = cli(*args)
    assert p.returncode == 0 and "--laplacian" not in p.stderr


def test_the_reported_operators_and_laplacian_given_back_run_again(cli, fixture_dir, tmp_path):
    # the report records laplacian intrinsic-delaunay with operators intrinsic; given back as
    # options the pair had been refused ('--laplacian: not used with --operators intrinsic')
    rep = tmp_path / "r.json"
    args = ("geodesic", fixture_dir / "torus.ply", "-s", "0", "--operators", "intrinsic")
    assert cli(*args, "-o", tmp_path / "a.ply", "--report", rep).returncode == 0
    params = json.loads(rep.read_text())["params"]
    assert (params["operators"], params["laplacian"]) == ("intrinsic", "intrinsic-delaunay")
    p = cli(*args, "--laplacian", params["laplacian"], "-o", tmp_path / "b.ply")
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()
    p = cli(*args, "--laplacian", "cotan", "-o", tmp_path / "c.ply")  # one it would not use is still refused
    assert p.returncode == 2 and "--laplacian: not used with --operators intrinsic" in p.stderr


def test_negative_heat_of_the_heat_method_is_noted(cli, make_fixtures, tmp_path):
    # cotan weights of obtuse triangles give negative heat at small times, where the normalized
    # gradient turns round: heat on a sliver torus ended with them and no word
    V, F = make_fixtures.torus(r=0.4, nu=60, nv=20, twist=3)
    src, rep = tmp_path / "slivers.ply", tmp_path / "r.json"
    save_mesh(src, Mesh(V, F))
    p = cli("geodesic", src, "-s", "0", "-c", "0.01", "--laplacian", "cotan", "--operators", "extrinsic",
            "-o", tmp_path / "d.ply", "--report", rep)
    n = json.loads(rep.read_text())["metrics"]["negative_heat_vertices"]
    assert p.returncode == 0 and n > 0
    assert (f"{n} vertices got negative heat (the cotan weights of obtuse triangles are negative): the normalized "
            "gradient points the wrong way there; the default --laplacian intrinsic-delaunay has no negative "
            "weight") in " ".join(p.stderr.split())


def test_faces_too_thin_for_cotan_weights_are_refused(cli, tmp_path):
    # face 0 has a positive cross-product area (5e-10) but its edge lengths give 0:
    # libigl's cotangents are infinite there, so the heat solve returned NaN (and a
    # surface squashed to 1e-31 made exact and log-ode run without end)
    src = tmp_path / "sliver.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0.5 1e-9 0\nv 0.5 1 0\nf 1 2 3\nf 1 3 4\nf 3 2 4\n")
    out = tmp_path / "d.ply"
    # log-ode's intrinsic flips took this one away, but on a bunny with 20 such faces they
    # allocated without end: every method refuses them
    for method in ("heat", "varadhan", "log-heat", "log-splitting", "exact", "log-ode"):
        p = cli("geodesic", src, "-s", "0", "-m", method, "-o", out)
        assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert "1 faces are too thin (first: face 0): their edge lengths give zero area" in p.stderr
        assert not out.exists()


def test_report_params_of_options_the_method_does_not_use_are_null(cli, fixture_dir, tmp_path):
    rep = tmp_path / "r.json"
    for method, solver in (("heat", None), ("log-ode", "lu")):
        p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "-m", method, "-o", tmp_path / "o.ply",
                "--report", rep)
        assert p.returncode == 0, p.stderr
        assert json.loads(rep.read_text())["params"]["solver"] == solver


def test_report_names_the_laplacian_the_intrinsic_operators_used(cli, fixture_dir, tmp_path):
    rep = tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", "heat", "--operators", "intrinsic",
            "-o", tmp_path / "d.ply", "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    report = _report(rep)
    assert report["metrics"]["operators"] == "intrinsic" and report["params"]["laplacian"] == "intrinsic-delaunay"


@pytest.mark.parametrize("method,metric", [("heat", "steps"), ("exact", "steps"), ("exact", "t"),
                                           ("exact", "t_over_h2")])
def test_a_check_on_a_metric_the_method_has_not_is_refused_before_the_work(cli, fixture_dir, tmp_path, method,
                                                                           metric):
    # heat has no time steps and exact no diffusion time: they were reported as
    # null, so the check "failed" with exit 1 after the run, as if measured
    out = tmp_path / "d.ply"
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", method, "-o", out, "--check", f"{metric}<=5")
    assert p.returncode == 2 and f"reports '{metric}' only with" in p.stderr and not out.exists()
    rep = tmp_path / "r.json"
    assert cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-m", method, "-o", out, "--report", rep,
               "-q").returncode == 0
    assert metric not in json.loads(rep.read_text())["metrics"]


def test_steps_reach_the_backward_euler_loop(cli, fixture_dir, tmp_path):
    # varadhan with -n 10 against ten backward-Euler steps built here with libigl and scipy:
    # (M - (T/10) L) u_k+1 = M u_k from u_0 = 1 at the source, d = sqrt(-4 T log u)
    import igl
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    m = load_mesh(fixture_dir / "grid.ply")
    E = igl.edges(m.F)
    T = 3 * np.linalg.norm(m.V[E[:, 0]] - m.V[E[:, 1]], axis=1).mean() ** 2
    L = sp.csc_matrix(igl.cotmatrix(m.V, m.F))
    M = sp.diags(igl.massmatrix(m.V, m.F, igl.MASSMATRIX_TYPE_VORONOI).diagonal())
    u = np.zeros(len(m.V))
    u[0] = 1.0
    for _ in range(10):
        u = spsolve(sp.csc_matrix(M - T / 10 * L), M @ u)
    ref = np.sqrt(np.maximum(0.0, -4 * T * np.log(u)))
    out = {}
    for n in ("1", "10"):
        out[n] = tmp_path / f"d{n}.ply"
        p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "-m", "varadhan", "-c", "3", "-n", n, "-o", out[n])
        assert p.returncode == 0, p.stderr
    d10, d1 = (load_mesh(out[n]).vertex_fields["distance"] for n in ("10", "1"))
    np.testing.assert_allclose(d10, ref, rtol=1e-10, atol=1e-12)
    assert np.abs(d1 - d10).max() > 0.01 * d10.max()


def test_sources_from_options_and_a_file_together(cli, fixture_dir, tmp_path):
    # -s 0 and a file naming 440: both are sources (the grid's opposite corners; exact is planar)
    f = tmp_path / "s.txt"
    f.write_text("440\n")
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "--sources-file", f, "-m", "exact", "-o", out,
            "--report", rep)
    assert p.returncode == 0, p.stderr
    m = load_mesh(out)
    ref = np.minimum(np.linalg.norm(m.V - m.V[0], axis=1), np.linalg.norm(m.V - m.V[440], axis=1))
    assert np.abs(m.vertex_fields["distance"] - ref).max() < 1e-12
    assert _report(rep)["metrics"]["sources"] == 2


@pytest.mark.parametrize("method", ["heat", "varadhan", "log-splitting", "log-ode", "log-heat"])
def test_default_laplacian_of_each_method(cli, fixture_dir, tmp_path, method):
    # the defaults the README states: cotan for varadhan and log-splitting,
    # intrinsic-delaunay for heat, log-ode and log-heat; the same bytes as naming them (a Delaunay
    # mesh, which every method takes with either Laplacian: they differ in the lumped mass)
    if method == "log-splitting":
        pytest.importorskip("clarabel")
    default = "intrinsic-delaunay" if method in ("heat", "log-ode", "log-heat") else "cotan"
    other = "cotan" if default != "cotan" else "intrinsic-delaunay"
    outs = {}
    for name, extra in (("none", []), ("same", ["--laplacian", default]), ("other", ["--laplacian", other])):
        outs[name], rep = tmp_path / f"{name}.ply", tmp_path / f"{name}.json"
        p = cli("geodesic", fixture_dir / "icosphere.ply", "-s", "0", "-m", method, *extra, "-o", outs[name],
                "--report", rep, "--operators" if method in ("heat", "log-heat") else "--quiet",
                *(["extrinsic"] if method in ("heat", "log-heat") else []))
        assert p.returncode == 0, p.stderr
        if name == "none":
            assert _report(rep)["params"]["laplacian"] == default
    d = {k: load_mesh(v).vertex_fields["distance"] for k, v in outs.items()}
    assert np.array_equal(d["none"], d["same"]) and not np.array_equal(d["none"], d["other"])


def test_sources_read_from_a_file_are_in_the_report_and_renumbering_is_explained(cli, fixture_dir, tmp_path):
    # a pipe of sources left only its hash in the report; an index past a merged mesh said nothing of the merge
    rep = tmp_path / "r.json"
    p = cli("geodesic", fixture_dir / "grid.ply", "--sources-file", "-", "-o", tmp_path / "o.ply", "--report", rep,
            stdin=b"0\n440\n0\n")
    assert p.returncode == 0, p.stderr
    params = json.loads(rep.read_text())["params"]
    assert params["sources_from_file"] == [0, 440, 0] and params["sources"] == []
    p = cli("geodesic", fixture_dir / "grid.ply", "-s", "0", "-o", tmp_path / "o.ply", "--report", rep)
    assert json.loads(rep.read_text())["params"]["sources_from_file"] is None
    g = load_mesh(fixture_dir / "grid.ply")
    split = Mesh(g.V[g.F].reshape(-1, 3), np.arange(3 * len(g.F)).reshape(-1, 3))  # every corner its own vertex
    save_mesh(tmp_path / "split.ply", split)
    p = cli("geodesic", tmp_path / "split.ply", "-s", "500", "-o", tmp_path / "o.ply")
    assert p.returncode == 2, p.stderr
    assert (f"source vertex 500 is out of range (the mesh has 441 vertices, numbered from 0; the mesh file stores "
            f"{3 * len(g.F)}, and loading merged {3 * len(g.F) - 441} coincident") in p.stderr, p.stderr
    p = cli("geodesic", tmp_path / "split.ply", "--sources-file", "-", "-o", tmp_path / "o.ply", stdin=b"500\n")
    assert p.returncode == 2 and "(--no-clean keeps the stored numbering)" in p.stderr, p.stderr


def test_a_bad_reference_file_is_refused_before_the_work(fixture_dir, tmp_path, monkeypatch, capsys):
    import geoproc.geodesic.distance
    from geoproc_cli import main as cli_main

    short = tmp_path / "short.npy"
    np.save(short, np.ones(3))
    monkeypatch.setattr(geoproc.geodesic.distance, "geodesic_distance", lambda *a, **k: pytest.fail("the work ran"))
    monkeypatch.setattr("sys.argv", ["geoproc", "geodesic", str(fixture_dir / "torus.ply"), "-s", "0", "--reference",
                                     str(short), "-o", str(tmp_path / "d.ply")])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    assert stop.value.code == 2 and "3 reference distances for" in capsys.readouterr().err


def test_exact_is_its_own_reference(fixture_dir, tmp_path, monkeypatch, capsys):
    # -m exact --reference exact had computed the exact distances twice
    import geoproc.geodesic.exact as exact
    from geoproc_cli import main as cli_main

    calls = []
    real = exact.exact_geodesic_distance
    monkeypatch.setattr(exact, "exact_geodesic_distance", lambda *a, **k: calls.append(1) or real(*a, **k))
    rep = tmp_path / "r.json"
    monkeypatch.setattr("sys.argv", ["geoproc", "geodesic", str(fixture_dir / "torus.ply"), "-s", "0", "-m", "exact",
                                     "--reference", "exact", "-o", str(tmp_path / "d.ply"), "--report", str(rep)])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    assert stop.value.code == 0 and len(calls) == 1
    assert _report(rep)["metrics"]["max_relative_error"] == 0.0


def test_a_flat_mesh_seen_edge_on_is_noted(cli, fixture_dir, tmp_path):
    # the grid lies in the xy plane: from x the picture is empty (it had been written without a word)
    args = ("geodesic", fixture_dir / "grid.ply", "-s", "220", "-o", tmp_path / "g.ply", "--render", tmp_path / "g.png")
    p = cli(*args, "--render-view", "x")
    assert p.returncode == 0 and "every face is seen edge-on from --render-view x" in p.stderr
    p = cli(*args)
    assert p.returncode == 0 and "edge-on" not in p.stderr, p.stderr
    # also flat as a file stores it (rounded to 6 decimals), in a plane along no axis: seen from z
    from geoproc.mesh import load_mesh

    g = load_mesh(fixture_dir / "grid.ply")
    u, v = g.V[:, 0] / np.ptp(g.V[:, 0]), g.V[:, 1] / np.ptp(g.V[:, 1])
    tilted = tmp_path / "tilted.obj"
    tilted.write_text("".join(f"v {0.8 * a:.6f} {0.6 * a:.6f} {b:.6f}\n" for a, b in zip(u, v, strict=True))
                      + "".join(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in g.F))
    p = cli("geodesic", tilted, "-s", "220", "-o", tmp_path / "t.ply", "--render", tmp_path / "t.png")
    assert p.returncode == 0 and "every face is seen edge-on from --render-view z" in p.stderr, p.stderr
    p = cli("geodesic", tilted, "-s", "220", "-o", tmp_path / "t.ply", "--render", tmp_path / "t.png",
            "--render-view", "x")
    assert p.returncode == 0 and "edge-on" not in p.stderr, p.stderr


def test_render_view_chooses_the_side_the_mesh_is_seen_from(cli, fixture_dir, tmp_path):
    # the torus lies in the xy plane: from z its hole shows the white background
    # at the picture's centre; from x its side covers the centre and is flat
    import io

    import matplotlib.image

    from geoproc.geodesic.render import render_distance_png

    pictures = {}
    for view in ("z", "x", "-y"):
        out, png, rep = tmp_path / f"{view}.ply", tmp_path / f"{view}.png", tmp_path / f"{view}.json"
        p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", out, "--render", png, "--render-view", view,
                "--report", rep)
        assert p.returncode == 0, p.stderr
        assert json.loads(rep.read_text())["params"]["render_view"] == view
        m = load_mesh(out)
        data = png.read_bytes()
        assert data == render_distance_png(m.V, m.F, m.vertex_fields["distance"], [0], view=view,
                                           title="torus.ply: heat")
        pictures[view] = matplotlib.image.imread(io.BytesIO(data))[..., :3]
    white = {v: img.min(axis=2) > 0.99 for v, img in pictures.items()}
    h, w = white["z"].shape
    assert white["z"][h // 2, w // 2] and not white["x"][h // 2, w // 2] and not white["-y"][h // 2, w // 2]
    rows = (~white["x"]).any(axis=1).sum()  # seen from the side: 0.7 tall for 2.7 wide
    assert rows < 0.45 * (~white["z"]).any(axis=1).sum()
    p = cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", tmp_path / "d.ply", "--render-view", "x")
    assert p.returncode == 2 and "--render-view: only with --render" in p.stderr


def test_reference_field_names_the_property_read_from_a_reference_mesh(cli, fixture_dir, tmp_path):
    # the exact run stored as 'exact'; the heat run writes 'distance' and reads 'exact'
    # (the one --field-name had named both, so two runs could not be compared as stored)
    torus, golden = fixture_dir / "torus.ply", tmp_path / "golden.ply"
    p = cli("geodesic", torus, "-s", "0", "-m", "exact", "--field-name", "exact", "-o", golden, "-q")
    assert p.returncode == 0, p.stderr
    got = {}
    for ref, extra in (("exact", []), (golden, ["--reference-field", "exact"])):
        rep = tmp_path / "r.json"
        p = cli("geodesic", torus, "-s", "0", "--reference", ref, *extra, "-o", tmp_path / "h.ply", "--report", rep,
                "-q")
        assert p.returncode == 0, p.stderr
        r = _report(rep)
        got[str(ref)] = r["metrics"]["rmse"]
        assert r["params"]["reference_field"] == (None if ref == "exact" else "exact")
        assert r["params"]["field_name"] == "distance" and "distance" in load_mesh(tmp_path / "h.ply").vertex_fields
    assert got[str(golden)] == got["exact"] > 0
    p = cli("geodesic", torus, "-s", "0", "--reference", golden, "-o", tmp_path / "h.ply")
    assert p.returncode == 2 and "no vertex property 'distance' (--field-name; --reference-field names another)" \
        in p.stderr
    npy = tmp_path / "d.npy"
    np.save(npy, load_mesh(golden).vertex_fields["exact"])
    for ref in ("exact", npy):
        p = cli("geodesic", torus, "-s", "0", "--reference", ref, "--reference-field", "exact", "-o",
                tmp_path / "x.ply")
        assert p.returncode == 2 and "--reference-field: only with --reference MESH" in p.stderr
    p = cli("geodesic", torus, "-s", "0", "--reference", "-", "--reference-field", "exact", "-o", tmp_path / "x.ply",
            stdin=npy.read_bytes())
    assert p.returncode == 2 and "--reference-field: the reference on standard input is a .npy" in p.stderr
    assert not (tmp_path / "x.ply").exists()
    p = cli("geodesic", torus, "-s", "0", "--reference", golden, "--reference-field", "", "-o", tmp_path / "x.ply")
    assert p.returncode == 2 and "--reference-field '': give the name of a vertex property" in p.stderr


@pytest.mark.parametrize("method", ["heat", "exact"])
def test_faces_collapsed_by_merging_are_named_with_the_way_out(cli, tmp_path, method):
    import trimesh

    ico = trimesh.creation.icosphere(2)
    V = ico.vertices.copy()
    V[ico.faces[0, 1]] = V[ico.faces[0, 0]]
    path, out = tmp_path / "collapse.ply", tmp_path / "o.ply"
    save_mesh(path, Mesh(V, ico.faces))
    p = cli("geodesic", path, "-s", "5", "-m", method, "-o", out)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and not out.exists()
    need = "a manifold" if method == "exact" else "an edge-manifold"
    assert p.stderr.startswith(f"error: {path}: 2 faces repeat a vertex (first: face 0, vertices ")
    # (not --no-clean: every method refuses the zero-area faces those then are)
    assert (f"; merging coincident positions on loading made all of them (an edge of length zero); "
            f"method '{method}' needs {need} mesh") in p.stderr
    p = cli("geodesic", path, "-s", "5", "-m", method, "-o", out, "--no-clean")
    assert p.returncode == 2 and "2 faces have zero area" in p.stderr


def test_vertices_the_reference_does_not_reach_are_counted(cli, tmp_path, make_fixtures):
    # a reference from one source on two disjoint spheres leaves the second at +inf; a run
    # from a source on each reaches it: those vertices are not compared, and are counted
    V, F = make_fixtures.icosphere(2)
    two = Mesh(np.concatenate([V, V + [3.0, 0, 0]]), np.concatenate([F, F + len(V)]))
    src, golden, rep = tmp_path / "two.ply", tmp_path / "golden.ply", tmp_path / "r.json"
    save_mesh(src, two)
    assert cli("geodesic", src, "-s", "0", "-m", "exact", "-o", golden, "-q").returncode == 0
    p = cli("geodesic", src, "-s", "0", "-s", str(len(V)), "--reference", golden, "-o", tmp_path / "h.ply",
            "--report", rep, "--check", "reference_nonfinite_vertices==0")
    assert p.returncode == 1
    m = _report(rep)["metrics"]
    assert (m["compared_vertices"], m["nonfinite_vertices"], m["reference_nonfinite_vertices"]) == (len(V), 0, len(V))
    assert f"{len(V)} vertices with a finite distance have none in the reference" in p.stderr
    p = cli("geodesic", src, "-s", "0", "--reference", golden, "-o", tmp_path / "h.ply", "--report", rep)
    assert p.returncode == 0 and _report(rep)["metrics"]["reference_nonfinite_vertices"] == 0
    assert "none in the reference" not in p.stderr
