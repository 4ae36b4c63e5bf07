"""``geoproc denoise`` through the real command line: outputs, report metrics
against ground truth, and one-line exit-2 refusals that leave no output."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from geoproc.animation import Animation, animation_to_bytes, load_animation
from geoproc.denoise import denoise_errors
from geoproc.denoise.metrics import flipped_faces, new_flipped_faces
from geoproc.mesh import Mesh, load_mesh, save_mesh
from tests.conftest import load_fixture_module


@pytest.fixture(scope="module")
def dfx():
    return load_fixture_module("denoise_fixtures")


@pytest.fixture(scope="module")
def cube_pair(dfx, tmp_path_factory):
    d = tmp_path_factory.mktemp("cube")
    Vn, F, V = dfx.noisy_cube(n=12, sigma=0.3, seed=2)
    save_mesh(d / "noisy.ply", Mesh(Vn, F))
    save_mesh(d / "clean.ply", Mesh(V, F))
    return d / "noisy.ply", d / "clean.ply"


def _metrics(path):
    return json.loads(Path(path).read_text())["metrics"]


def _one_line_error(p):
    return p.returncode == 2 and p.stderr.startswith("error:") and len(p.stderr.strip().splitlines()) == 1


def test_denoise_with_reference_report(cli, cube_pair, tmp_path):
    noisy, clean = cube_pair
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("denoise", noisy, "--reference", clean, "-o", out, "--report", rep,
            "--check", "mean_normal_angle_deg<=3")
    assert p.returncode == 0, p.stderr
    met = _metrics(rep)
    m = load_mesh(out)
    ref = load_mesh(clean)
    # the report's numbers are those of the written mesh
    independent = denoise_errors(m.V, m.F, ref.V)
    assert met["mean_normal_angle_deg"] == pytest.approx(independent["mean_normal_angle_deg"], rel=1e-6)
    assert met["mean_normal_angle_deg"] < 0.15 * met["input_mean_normal_angle_deg"]
    assert met["new_flipped_faces"] == 0
    assert {"max_normal_angle_deg", "flipped_faces", "hausdorff", "vertex_rmse"} <= set(met)
    assert set(np.unique(m.face_fields["feature"])) <= {0.0, 1.0} and m.face_fields["feature"].sum() > 0


@pytest.mark.slow
@pytest.mark.parametrize("method", ["bilateral", "rpca"])
def test_methods(cli, cube_pair, tmp_path, method):
    noisy, clean = cube_pair
    rep = tmp_path / "r.json"
    p = cli("denoise", noisy, "--method", method, "--reference", clean, "-o", tmp_path / "d.ply",
            "--report", rep)
    assert p.returncode == 0, p.stderr
    assert _metrics(rep)["mean_normal_angle_deg"] < 4.0


def test_stdout_pipe_is_binary_ply(cli, cube_pair):
    noisy, _ = cube_pair
    p = cli("denoise", noisy, "-o", "-", "--quiet")
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith(b"ply\nformat binary_little_endian")


def test_replacing_an_input_property_is_noted(cli, cube_pair, dfx, tmp_path):
    noisy, _ = cube_pair
    first, second = tmp_path / "a.ply", tmp_path / "b.ply"
    p = cli("denoise", noisy, "-o", first)
    assert p.returncode == 0 and "replacing" not in p.stderr, p.stderr
    p = cli("denoise", first, "-o", second)
    assert p.returncode == 0 and "note: replacing the input's face property 'feature'" in p.stderr, p.stderr
    P, _ = dfx.cloud_with_outliers(2000, 0.2, 0.05)
    save_mesh(tmp_path / "c.ply", Mesh(P, np.zeros((0, 3), int), {"outlier_score": np.zeros(len(P))}))
    p = cli("denoise", tmp_path / "c.ply", "--outliers", "--keep-all", "-o", tmp_path / "s.ply")
    assert p.returncode == 0 and "note: replacing the input's vertex property 'outlier_score'" in p.stderr, p.stderr


def test_shape_statistics_are_reported_whenever_measured(cli, cube_pair, tmp_path):
    # with --rounds, --normal-iterations and --sigma-r all given, coarseness_deg read 0 and
    # dihedral_tail_ratio was left out although both had been measured; on a clean mesh,
    # where neither is measured, coarseness_deg read 0
    noisy, clean = cube_pair
    reports = []
    for name, mesh, args in (("a", noisy, []), ("b", noisy, ["--rounds", "1", "--normal-iterations", "2",
                                                              "--sigma-r", "0.4"]), ("c", clean, [])):
        rep = tmp_path / f"{name}.json"
        p = cli("denoise", mesh, *args, "-o", tmp_path / f"{name}.ply", "--report", rep)
        assert p.returncode == 0, p.stderr
        reports.append(_metrics(rep))
    a, b, c = reports
    assert a["coarseness_deg"] > 0 and a["dihedral_tail_ratio"] > 1
    assert b["coarseness_deg"] == a["coarseness_deg"] and b["dihedral_tail_ratio"] == a["dihedral_tail_ratio"]
    assert c["coarseness_deg"] is None and c["dihedral_tail_ratio"] is None and c["outer_iterations"] == 0


def test_a_clean_mesh_is_said_to_be_written_unchanged_with_no_filter_values(cli, cube_pair, tmp_path):
    # nothing was filtered, without a word, and the report gave sigma_r 0.1 and guidance_mix 1 that did not act
    _, clean = cube_pair
    rep, out = tmp_path / "r.json", tmp_path / "o.ply"
    p = cli("denoise", clean, "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    assert "the mesh reads as clean (roughness" in p.stderr and "positions are written unchanged" in p.stderr
    assert np.array_equal(load_mesh(out).V, load_mesh(clean).V)
    m = _metrics(rep)
    assert m["outer_iterations"] == 0
    for key in ("sigma_r", "sigma_s", "sigma_s_length", "guidance_mix", "vertex_iterations", "fidelity",
                "unfold_rounds"):
        assert m[key] is None, key
    p = cli("denoise", clean, "-o", out, "--report", rep, "--check", "sigma_r<=1")
    assert p.returncode == 1 and "sigma_r<=1 (not measured in this run" in p.stderr, p.stderr
    # --rounds alone: the passes default to none on a clean mesh, which had not been said
    p = cli("denoise", clean, "-o", out, "--rounds", "2")
    assert p.returncode == 0 and "no filter pass ran: the mesh reads as clean" in p.stderr, p.stderr
    # two clean parts at scales 1000 apart: the groups' note says none was filtered
    cube = load_mesh(clean)
    both = Mesh(np.vstack([cube.V, cube.V / 1000 + 5]), np.vstack([cube.F, cube.F + len(cube.V)]))
    save_mesh(tmp_path / "two.ply", both)
    p = cli("denoise", tmp_path / "two.ply", "-o", out)
    assert p.returncode == 0 and "none was filtered, each reads as clean" in p.stderr, p.stderr
    # a clean animation: no frame's static step fitted, so its fit's values are null too
    frames = np.stack([cube.V + [t, 0, 0] for t in range(3)])
    np.savez(tmp_path / "a.npz", vertices=frames, faces=cube.F)
    p = cli("denoise", tmp_path / "a.npz", "--dynamic", "-o", tmp_path / "b.npz", "--report", rep)
    assert p.returncode == 0, p.stderr
    m = _metrics(rep)
    assert m["outer_iterations"] == 0 and m["vertex_iterations"] is None and m["fidelity"] is None
    assert m["normal_iterations"] is None and "every frame reads as clean" in p.stderr, p.stderr
    # --rounds 0 on a noisy mesh: the schedule's passes did not act either (it had reported 3)
    noisy, _ = cube_pair
    p = cli("denoise", noisy, "-o", out, "--rounds", "0", "--report", rep)
    assert p.returncode == 0 and _metrics(rep)["normal_iterations"] is None, p.stderr
    # groups of which none was filtered because --rounds 0 says so: not "each reads as clean"
    noisy_mesh = load_mesh(noisy)
    mixed = Mesh(np.vstack([noisy_mesh.V, cube.V / 1000 + 5]), np.vstack([noisy_mesh.F, cube.F + len(noisy_mesh.V)]))
    save_mesh(tmp_path / "mixed.ply", mixed)
    p = cli("denoise", tmp_path / "mixed.ply", "-o", out, "--rounds", "0")
    assert p.returncode == 0 and "the largest group; no filter pass ran" in p.stderr, p.stderr


def test_the_reported_schedule_given_back_reproduces_the_run(cli, cube_pair, tmp_path):
    # with --rounds, --normal-iterations and --sigma-r all given the guided method had dropped
    # its guidance mix and crease repair: the values a report recorded gave another result
    # (a noisy cube's largest face error 2.06 -> 54.3 degrees at noise 0.1)
    noisy, clean = cube_pair
    a, rep = tmp_path / "a.ply", tmp_path / "a.json"
    p = cli("denoise", noisy, "-o", a, "--report", rep)
    assert p.returncode == 0, p.stderr
    m = _metrics(rep)
    assert m["outer_iterations"] > 0 and m["guidance_mix"] < 1
    schedule = ["--rounds", m["outer_iterations"], "--normal-iterations", m["normal_iterations"],
                "--sigma-r", repr(m["sigma_r"]), "--sigma-s", repr(m["sigma_s"])]
    for extra in ([], ["--guidance-mix", repr(m["guidance_mix"])]):
        b = tmp_path / "b.ply"
        p = cli("denoise", noisy, *map(str, schedule), *extra, "-o", b)
        assert p.returncode == 0, p.stderr
        assert a.read_bytes() == b.read_bytes(), extra
    # another mix is another run (1: the normals themselves); the option is the guided method's
    p = cli("denoise", noisy, "--guidance-mix", "1", "-o", tmp_path / "z.ply")
    assert p.returncode == 0 and (tmp_path / "z.ply").read_bytes() != a.read_bytes()
    p = cli("denoise", noisy, "--method", "bilateral", "--guidance-mix", "0.5", "-o", tmp_path / "x.ply")
    assert p.returncode == 2 and "--guidance-mix" in p.stderr and "only with --method guided" in p.stderr
    p = cli("denoise", noisy, "--guidance-mix", "1.5", "-o", tmp_path / "x.ply")
    assert p.returncode == 2 and "must be within [0, 1]" in p.stderr and not (tmp_path / "x.ply").exists()
    # at strong noise the crease repair runs whatever the schedule; --no-crease-repair with the
    # patch guidance alone is the published filter, as the library's parameters give it
    from geoproc.denoise import denoise_mesh
    from geoproc.denoise.params import DenoiseParams

    assert m["crease_repair"] is True and m["crease_bisected_faces"] > 0
    z, rep_z = tmp_path / "zhang.ply", tmp_path / "zhang.json"
    p = cli("denoise", noisy, "--guidance-mix", "0", "--no-crease-repair", "-o", z, "--report", rep_z)
    assert p.returncode == 0 and _metrics(rep_z)["crease_repair"] is False
    mesh = load_mesh(noisy)
    want = denoise_mesh(mesh.V, mesh.F, "guided", DenoiseParams(guidance_mix=0.0, crease_repair=False)).V
    np.testing.assert_array_equal(load_mesh(z).V, want)
    # bilateral blends nothing: no guidance_mix (it had read 0, the patch guidance alone), and a
    # check on it is refused before the work
    p = cli("denoise", noisy, "--method", "bilateral", "-o", tmp_path / "b.ply", "--report", rep)
    assert p.returncode == 0 and "guidance_mix" not in _metrics(rep)
    p = cli("denoise", tmp_path / "missing.ply", "--method", "bilateral", "--check", "guidance_mix<=1", "-o",
            tmp_path / "b.ply")
    assert p.returncode == 2 and "only with --method guided" in p.stderr and "missing.ply" not in p.stderr


def test_inliers_drop_an_earlier_runs_scores(cli, dfx, tmp_path):
    # an earlier --keep-all run's flags were carried into the inliers: points flagged 1
    # among those this run kept, without a word
    P, _ = dfx.cloud_with_outliers(2000, 0.2, 0.05)
    old = {"outlier_score": np.full(len(P), 9.0), "outlier_detected": np.ones(len(P)), "w": np.arange(len(P))}
    save_mesh(tmp_path / "c.ply", Mesh(P, np.zeros((0, 3), int), old))
    p = cli("denoise", tmp_path / "c.ply", "--outliers", "-o", tmp_path / "i.ply")
    assert p.returncode == 0 and ("note: dropping the input's vertex properties 'outlier_score', "
                                  "'outlier_detected'") in p.stderr, p.stderr
    kept = load_mesh(tmp_path / "i.ply")
    assert set(kept.vertex_fields) == {"w"} and 0 < len(kept.V) < len(P)


def test_outliers_f1_and_outputs(cli, dfx, tmp_path):
    P, flag = dfx.cloud_with_outliers(8000, 0.2, 0.05)
    src = tmp_path / "cloud.ply"
    save_mesh(src, Mesh(P, np.zeros((0, 3), int), {"outlier": flag}))
    out, rep = tmp_path / "in.ply", tmp_path / "r.json"
    p = cli("denoise", src, "--outliers", "--k", "16", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _metrics(rep)
    from geoproc_cli.denoise import CLOUD, Choices, _metric_needs
    from tests.cli.test_metric_names import _gated

    gated = _gated(_metric_needs(Choices(CLOUD, "guided", "dihedral", False, None)))
    assert set(met) & gated == set()  # no metric this mode reports is refused as a --check
    kept = load_mesh(out)
    assert len(kept.V) == met["points"] - met["detected_outliers"]
    # precision and recall recomputed from the written inliers and perturb's flags
    removed_true = flag.sum() - kept.vertex_fields["outlier"].sum()
    assert met["recall"] == pytest.approx(removed_true / flag.sum())
    assert met["f1"] > 0.85
    # flags interpolated by an earlier command are noted, as perturb notes them (they had been read silently)
    soft = flag.astype(float)
    soft[:3] = [0.3, 0.7, 0.5]
    save_mesh(tmp_path / "soft.ply", Mesh(P, np.zeros((0, 3), int), {"outlier": soft}))
    p = cli("denoise", tmp_path / "soft.ply", "--outliers", "-o", tmp_path / "s.ply")
    assert p.returncode == 0 and (f"note: {tmp_path / 'soft.ply'}: the 'outlier' property has 3 values other than "
                                  "0 and 1: read as outlier flags where above 0.5") in " ".join(p.stderr.split())
    p = cli("denoise", src, "--outliers", "--keep-all", "-o", out)
    assert p.returncode == 0 and "note" not in p.stderr, p.stderr
    allp = load_mesh(out)
    assert len(allp.V) == len(P) and {"outlier_score", "outlier_detected"} <= set(allp.vertex_fields)
    # nothing detected: precision is not defined (null), recall and F1 are 0
    p = cli("denoise", src, "--outliers", "--threshold", "1e300", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _metrics(rep)
    assert met["precision"] is None and met["recall"] == 0.0 and met["f1"] == 0.0
    # everything detected: no inlier to write, exit 2 and nothing written
    out.unlink()
    p = cli("denoise", src, "--outliers", "--threshold", "0", "-o", out)
    assert _one_line_error(p) and "every point scores above the threshold 0" in p.stderr and not out.exists()
    bad = tmp_path / "nan.ply"
    save_mesh(bad, Mesh(P, np.zeros((0, 3), int), {"outlier": np.where(flag > 0, np.nan, 0.0)}))
    p = cli("denoise", bad, "--outliers", "-o", out)
    assert _one_line_error(p) and "nan.ply: 'outlier' property has non-finite values" in p.stderr


@pytest.mark.parametrize("coherence", [None, "normals"])
def test_dynamic_npz(cli, dfx, tmp_path, coherence):
    Vn, F, V = dfx.noisy_wave(frames=3)
    src, ref = tmp_path / "noisy.npz", tmp_path / "clean.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn, F)))
    ref.write_bytes(animation_to_bytes(Animation(V, F)))
    out, rep = tmp_path / "d.npz", tmp_path / "r.json"
    extra = [] if coherence is None else ["--coherence", coherence]
    p = cli("denoise", src, "--dynamic", *extra, "--reference", ref, "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    report = json.loads(rep.read_text())
    assert report["params"]["coherence"] == (coherence or "heights")
    assert report["metrics"]["coherence"] == (coherence or "heights")
    a = load_animation(out)
    theta = np.mean([denoise_errors(a.V[t], F, V[t])["mean_normal_angle_deg"] for t in range(3)])
    met = _metrics(rep)
    assert met["mean_normal_angle_deg"] == pytest.approx(theta, rel=1e-9)
    # the largest angle is the largest of any frame, not a mean of the frames' largest
    worst = [denoise_errors(a.V[t], F, V[t])["max_normal_angle_deg"] for t in range(3)]
    assert met["max_normal_angle_deg"] == pytest.approx(max(worst), rel=1e-9) and max(worst) > np.mean(worst)
    assert theta < 0.5 * np.mean([denoise_errors(Vn[t], F, V[t])["mean_normal_angle_deg"] for t in range(3)])
    # the schedule chosen from each frame's noise, over the frames (params had null and the
    # metrics nothing: the README's contract for options chosen from the input)
    from geoproc.denoise import denoise_mesh

    infos = [denoise_mesh(Vn[t], F).info for t in range(3)]
    assert report["params"]["rounds"] is None and report["params"]["sigma_r"] is None
    for key in ("noise_roughness", "sigma_r", "sigma_s", "guidance_mix"):
        assert met[key] == pytest.approx(np.mean([i[key] for i in infos]), rel=1e-12), key
    for key in ("outer_iterations", "normal_iterations"):
        assert met[key] == max(i[key] for i in infos) > 0, key
    # face counts are summed over the frames
    before = [flipped_faces(Vn[t], F, V[t]) for t in range(3)]
    assert met["input_flipped_faces"] == sum(len(b) for b in before)
    assert met["new_flipped_faces"] == sum(new_flipped_faces(a.V[t], F, V[t], before[t]) for t in range(3))


@pytest.mark.parametrize("args,gate,option", [
    ([], "f1>=0.9", "--outliers"),
    ([], "frames==1", "--dynamic"),
    ([], "feature_tau>=0", "--features l1"),
    (["--features", "l1"], "feature_angle_deg>=0", "--features dihedral"),
    (["--outliers"], "low_rank>=1", "--dynamic"),
    (["--dynamic"], "precision>=0", "--outliers"),
    ([], "rpca_sparse_faces<=0", "--method rpca"),
    (["--outliers"], "sigma_r>=0", "a mesh (not --outliers)"),
    (["--outliers"], "mean_refinement_shift<=1", "--outliers --refined"),
    (["--dynamic"], "coarseness_deg<=1", "a single mesh"),
])
def test_a_check_that_the_mode_cannot_report_is_refused_before_reading(cli, tmp_path, args, gate, option):
    missing = tmp_path / "missing.ply"  # never read when the check is refused first
    p = cli("denoise", missing, *args, "-o", tmp_path / "o.ply", "--check", gate)
    assert _one_line_error(p)
    assert f"only with {option}" in p.stderr and "missing.ply" not in p.stderr


def test_outliers_of_a_triangle_mesh_keep_the_faces_among_inliers(cli, make_fixtures, tmp_path):
    V, F = make_fixtures.icosphere(3)
    rng = np.random.default_rng(1)
    far = rng.choice(len(V), 40, replace=False)
    V = V.copy()
    V[far] *= 1.5  # pushed off the sphere
    src = tmp_path / "m.ply"
    save_mesh(src, Mesh(V, F, {"outlier": np.isin(np.arange(len(V)), far).astype(float)},
                        {"label": np.arange(len(F), dtype=float)}))
    out = tmp_path / "o.ply"
    p = cli("denoise", src, "--outliers", "-o", out)
    assert p.returncode == 0, p.stderr
    o = load_mesh(out, clean=False)
    kept = {tuple(v) for v in np.round(o.V, 12)}
    inlier = np.array([tuple(v) in kept for v in np.round(V, 12)])
    expected = np.flatnonzero(inlier[F].all(axis=1))
    assert (~inlier).sum() > 0 and 0 < len(expected) < len(F)
    # the same triangles, by position, with their labels
    assert np.array_equal(np.sort(o.face_fields["label"]), expected.astype(float))
    order = np.argsort(o.face_fields["label"])
    assert np.allclose(o.V[o.F[order]], V[F[expected]])
    assert f"note: {src}: {len(F) - len(expected)} of {len(F)} faces use a removed point" in " ".join(p.stderr.split())
    p = cli("denoise", src, "--outliers", "--keep-all", "-o", out)
    assert p.returncode == 0 and np.array_equal(load_mesh(out, clean=False).F, F)


def test_dynamic_needs_three_frames(cli, dfx, tmp_path):
    Vn, F, _ = dfx.noisy_wave(frames=3)
    src, out = tmp_path / "two.npz", tmp_path / "d.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn[:2], F)))
    p = cli("denoise", src, "--dynamic", "-o", out)
    assert _one_line_error(p) and "two.npz: has 2 frames; --dynamic needs at least 3" in p.stderr
    assert not out.exists()
    p = cli("denoise", src, "-o", out)
    assert _one_line_error(p) and "two.npz: a .npz file is read as an animation; --dynamic denoises it" in p.stderr
    (tmp_path / "frames").mkdir()
    p = cli("denoise", tmp_path / "frames", "-o", tmp_path / "f.ply")
    assert _one_line_error(p) and "frames: a folder is read as an animation; --dynamic denoises it" in p.stderr


# ---- bad input: one line, exit 2, nothing written --------------------------------------------

def test_nonmanifold_edge_is_refused(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "fin.obj", "-o", out)
    assert _one_line_error(p) and "non-manifold" in p.stderr and not out.exists()


def test_face_repeating_a_vertex_is_left_out(cli, tmp_path):
    # f 1 1 2 puts edge 1-2 in three faces: denoise had refused the mesh (a collapsed
    # edge's faces, once coincident vertices merge); it now leaves that face out, and a
    # method that needs a manifold names the face, not the edge
    src = tmp_path / "rep.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 1 1 2\n")
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("denoise", src, "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    assert _metrics(rep)["repeated_corner_faces"] == 1
    m = load_mesh(out, clean=False)
    assert len(m.F) == 3 and m.face_fields["feature"].tolist()[2] == 0 and np.isfinite(m.V).all()
    p = cli("geodesic", src, "-s", "0", "-o", tmp_path / "g.ply")
    assert _one_line_error(p) and "rep.obj: 1 face repeats a vertex (first: face 2, vertices 0 0 1)" in p.stderr


def test_zero_area_faces_are_handled(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "zero_area.off", "--no-clean", "--rounds", "1", "--normal-iterations", "2",
            "-o", out)
    assert p.returncode == 0, p.stderr
    assert np.isfinite(load_mesh(out, clean=False).V).all()


def test_open_boundary_is_handled(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "grid.ply", "--rounds", "1", "--pin-boundary", "-o", out)
    assert p.returncode == 0, p.stderr
    assert np.allclose(load_mesh(out).V, load_mesh(fixture_dir / "grid.ply").V)  # flat stays flat


def _noisy_grid(fixture_dir, frames=None):
    """The grid fixture with noise in every direction (frames of it, each its own noise),
    and its boundary vertices."""
    from geoproc.mesh.topology import boundary_vertices

    g = load_mesh(fixture_dir / "grid.ply")
    rng = np.random.default_rng(4)
    shape = g.V.shape if frames is None else (frames, *g.V.shape)
    return g.V + 0.01 * rng.standard_normal(shape), g.F, boundary_vertices(g.F)


@pytest.mark.parametrize("pin", [True, False])
def test_pin_boundary_keeps_the_boundary_where_it_was(cli, fixture_dir, tmp_path, pin):
    # noise in every direction, so that the filter moves the boundary unless it is pinned
    V, F, b = _noisy_grid(fixture_dir)
    src, out = tmp_path / "g.ply", tmp_path / "o.ply"
    save_mesh(src, Mesh(V, F))
    p = cli("denoise", src, *(["--pin-boundary"] if pin else []), "-o", out)
    assert p.returncode == 0, p.stderr
    W = load_mesh(out).V
    inner = np.setdiff1d(np.arange(len(V)), b)
    assert np.abs(W[inner] - V[inner]).max() > 1e-3
    assert np.array_equal(W[b], V[b]) if pin else np.abs(W[b] - V[b]).max() > 1e-3


@pytest.mark.parametrize("pin", [True, False])
def test_pin_boundary_keeps_the_boundary_of_every_frame(cli, fixture_dir, tmp_path, pin):
    V, F, b = _noisy_grid(fixture_dir, frames=3)
    src, out = tmp_path / "g.npz", tmp_path / "o.npz"
    src.write_bytes(animation_to_bytes(Animation(V, F)))
    p = cli("denoise", src, "--dynamic", *(["--pin-boundary"] if pin else []), "-o", out)
    assert p.returncode == 0, p.stderr
    W = load_animation(out).V
    assert np.array_equal(W[:, b], V[:, b]) if pin else np.abs(W[:, b] - V[:, b]).max() > 1e-3


def test_k_reaches_the_outlier_scores(cli, dfx, tmp_path):
    from geoproc.denoise import rpca_outliers

    P, flag = dfx.cloud_with_outliers(3000, 0.1, 0.05)
    src, out = tmp_path / "c.ply", tmp_path / "o.ply"
    save_mesh(src, Mesh(P, np.zeros((0, 3), int)))
    p = cli("denoise", src, "--outliers", "--k", "7", "--keep-all", "-o", out)
    assert p.returncode == 0, p.stderr
    score = load_mesh(out).vertex_fields["outlier_score"]
    np.testing.assert_array_equal(score, rpca_outliers(P, k=7).score)
    assert not np.array_equal(score, rpca_outliers(P, k=16).score)


def test_k_beyond_the_memory_is_an_out_of_memory_error(dfx, tmp_path, monkeypatch, capsys):
    # a --k within its range (at most the points) but past the machine's memory was killed by
    # the kernel: exit 137, no error line (k = 20,000 on 20,000 points, about 56 GiB)
    from geoproc_cli import common
    from geoproc_cli import main as cli_main

    P, _ = dfx.cloud_with_outliers(3000, 0.1, 0.05)
    src, out = tmp_path / "c.ply", tmp_path / "o.ply"
    save_mesh(src, Mesh(P, np.zeros((0, 3), int)))
    monkeypatch.setattr(common, "available_memory", lambda: 2**30)  # 1 GiB
    monkeypatch.setattr("sys.argv", ["geoproc", "denoise", str(src), "--outliers", "--k", "2990", "-o", str(out)])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.startswith("error: out of memory: --k 2990 on 3000 points needs about")
    assert not out.exists()


def test_parts_at_very_different_scales_are_denoised_apart_with_a_note(cli, dfx, tmp_path):
    # a small noisy part had pulled the whole mesh's noise estimate to "clean": output = input
    Vn, F, V = dfx.noisy_cube(n=10, sigma=0.3, seed=2)
    Wn, G, W = dfx.noisy_cube(n=8, sigma=0.3, seed=3)
    src, clean = tmp_path / "two.ply", tmp_path / "two_clean.ply"
    save_mesh(src, Mesh(np.vstack([Vn, Wn * 1e-3]), np.vstack([F, G + len(Vn)])))
    save_mesh(clean, Mesh(np.vstack([V, W * 1e-3]), np.vstack([F, G + len(V)])))
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("denoise", src, "--reference", clean, "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    assert "two.ply: its parts are meshed at scales more than 4 times apart; denoised in 2 groups" in p.stderr
    met = _metrics(rep)
    assert met["scale_groups"] == 2 and met["mean_normal_angle_deg"] < 5.0 and met["new_flipped_faces"] == 0


def test_no_clean_notes_the_seams_it_keeps_open(cli, cube_pair, tmp_path):
    # the surface tore along the kept seams (teapot's by up to 1.67 edges) without a word
    noisy, _ = cube_pair
    m = load_mesh(noisy)
    f = m.F[0]
    V = np.vstack([m.V, m.V[f[:1]]])  # a copy of one corner, used by one face instead of it
    F = m.F.copy()
    F[0, 0] = len(m.V)
    src = tmp_path / "seam.ply"
    save_mesh(src, Mesh(V, F))
    p = cli("denoise", src, "--no-clean", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and "seam.ply: 1 vertex the faces use repeats the position of another" in p.stderr
    p = cli("denoise", noisy, "--no-clean", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and "the position of another" not in p.stderr


def test_a_moving_cloud_beyond_the_memory_is_an_out_of_memory_error(dfx, tmp_path, monkeypatch, capsys):
    # the animation matrix and RPCA's copies of it take about 100 bytes per coordinate
    # (1.24 GB for 20 frames of 200,000 points): past the memory the kernel killed the run
    from geoproc_cli import common
    from geoproc_cli import main as cli_main

    V = np.random.default_rng(1).random((5, 4000, 3))
    src, out = tmp_path / "c.npz", tmp_path / "o.npz"
    src.write_bytes(animation_to_bytes(Animation(V, np.zeros((0, 3), int))))
    monkeypatch.setattr(common, "available_memory", lambda: 2**20)  # 1 MiB
    monkeypatch.setattr("sys.argv", ["geoproc", "denoise", str(src), "--outliers", "-o", str(out)])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.startswith("error: out of memory: --outliers on 5 frames of 4000 points")
    assert not out.exists()


def test_a_npz_output_for_a_mesh_on_stdin_is_refused_before_the_work(cube_pair, tmp_path, monkeypatch, capsys):
    # .npz passes the check made before standard input is read (an animation piped in is
    # named as the problem); a mesh read from there had then been denoised before the refusal
    import io
    import sys

    import geoproc.denoise.mesh_denoise as mesh_denoise
    from geoproc_cli import main as cli_main

    noisy, _ = cube_pair
    monkeypatch.setattr(mesh_denoise, "denoise_mesh", lambda *a, **k: pytest.fail("the work ran"))
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(noisy.read_bytes())))
    monkeypatch.setattr("sys.argv", ["geoproc", "denoise", "-", "-o", str(tmp_path / "x.npz")])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    assert stop.value.code == 2 and "x.npz: cannot write '.npz'" in capsys.readouterr().err


def test_a_k_beyond_the_points_is_named_as_such_whatever_the_memory(dfx, tmp_path, capsys, monkeypatch):
    # the memory estimate had counted k neighbours for each of fewer than k points
    from geoproc_cli import main as cli_main

    P, _ = dfx.cloud_with_outliers(100, 0.1, 0.05)
    src = tmp_path / "c.ply"
    save_mesh(src, Mesh(P, np.zeros((0, 3), int)))
    monkeypatch.setattr("sys.argv", ["geoproc", "denoise", str(src), "--outliers", "--k", "100000000", "-o",
                                     str(tmp_path / "o.ply")])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "fewer than the neighbourhood size" in err and "out of memory" not in err
    # nor when the points alone, each with all the others as neighbours, would not fit the memory
    # (k 25,000 on 20,000 points had read "out of memory ... needs about 55.9 GiB")
    from geoproc_cli import common

    P, _ = dfx.cloud_with_outliers(3000, 0.1, 0.05)
    save_mesh(src, Mesh(P, np.zeros((0, 3), int)))
    monkeypatch.setattr(common, "available_memory", lambda: 2**30)  # 1 GiB: 3000 x 3000 neighbours need more
    monkeypatch.setattr("sys.argv", ["geoproc", "denoise", str(src), "--outliers", "--k", "5000", "-o",
                                     str(tmp_path / "o.ply")])
    with pytest.raises(SystemExit) as stop:
        cli_main.main()
    err = capsys.readouterr().err
    assert stop.value.code == 2
    assert err.strip() == f"error: {src}: has 3000 points, fewer than the neighbourhood size k=5000"


def test_feature_angle_sets_the_dihedral_threshold(cli, cube_pair, tmp_path):
    # the cube's edges are 90 degrees: a threshold above that finds no feature, below it many
    noisy, _ = cube_pair
    faces = {}
    for angle in (30, 100):
        rep = tmp_path / f"{angle}.json"
        p = cli("denoise", noisy, "--feature-angle", str(angle), "-o", tmp_path / f"{angle}.ply", "--report", rep)
        assert p.returncode == 0, p.stderr
        assert _metrics(rep)["feature_angle_deg"] == angle
        faces[angle] = _metrics(rep)["feature_faces"]
    assert faces[100] == 0 and faces[30] > 100


def test_cloud_with_fewer_than_k_points(cli, tmp_path):
    src, out = tmp_path / "tiny.ply", tmp_path / "o.ply"
    save_mesh(src, Mesh(np.random.default_rng(0).standard_normal((10, 3)), np.zeros((0, 3), int)))
    p = cli("denoise", src, "--outliers", "--k", "16", "-o", out)
    assert _one_line_error(p) and "fewer than" in p.stderr and not out.exists()


def test_point_cloud_without_outliers_flag(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "points.ply", "-o", out)
    assert _one_line_error(p) and "--outliers" in p.stderr and not out.exists()


@pytest.mark.parametrize("args", [["--coherence", "normals"], ["--dynamic", "--coherence", "frames"]])
def test_coherence_usage(cli, dfx, tmp_path, args):
    Vn, F, _ = dfx.noisy_wave(frames=3)
    src, out = tmp_path / "noisy.npz", tmp_path / "d.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn, F)))
    p = cli("denoise", src, *args, "-o", out)
    assert _one_line_error(p) and "--coherence" in p.stderr and not out.exists()


def test_animation_with_differing_connectivity(cli, make_fixtures, tmp_path):
    V, F = make_fixtures.icosphere(1)
    frames = tmp_path / "frames"
    frames.mkdir()
    save_mesh(frames / "f0.ply", Mesh(V, F))
    save_mesh(frames / "f1.ply", Mesh(V, F[:, [0, 2, 1]]))
    out = tmp_path / "o.npz"
    p = cli("denoise", frames, "--dynamic", "-o", out)
    assert _one_line_error(p) and "connectivity" in p.stderr and not out.exists()


def test_stl_input_is_matched_to_its_reference(cli, cube_pair, tmp_path):
    # STL keeps no shared vertices: merged on loading, they come in order of
    # first use, not in the reference's order; the face lists still match row by row
    import trimesh

    noisy, clean = cube_pair
    m = load_mesh(noisy)
    stl = tmp_path / "noisy.stl"
    trimesh.Trimesh(m.V, m.F, process=False).export(stl)
    assert not np.array_equal(load_mesh(stl).F, m.F)
    out, rep = tmp_path / "d.ply", tmp_path / "r.json"
    p = cli("denoise", stl, "--reference", clean, "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _metrics(rep)
    # the noisy positions against the clean ones, as numbered in the PLY files (STL stores float32)
    direct = denoise_errors(m.V, m.F, load_mesh(clean).V)["mean_normal_angle_deg"]
    assert met["input_mean_normal_angle_deg"] == pytest.approx(direct, rel=1e-4)
    assert met["mean_normal_angle_deg"] < 0.15 * met["input_mean_normal_angle_deg"]
    assert met["new_flipped_faces"] == 0


def test_reference_with_other_faces_at_equal_counts(cli, cube_pair, tmp_path):
    noisy, clean = cube_pair
    c = load_mesh(clean)
    F = c.F.copy()
    F[[0, 1]] = F[[1, 0]]
    other = tmp_path / "other.ply"
    save_mesh(other, Mesh(c.V, F))
    out = tmp_path / "o.ply"
    p = cli("denoise", noisy, "--reference", other, "-o", out)
    assert _one_line_error(p) and "other faces" in p.stderr and not out.exists()


def test_reference_with_other_connectivity(cli, cube_pair, fixture_dir, tmp_path):
    noisy, _ = cube_pair
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("denoise", noisy, "--reference", fixture_dir / "icosphere.ply", "-o", out, "--report", rep)
    assert _one_line_error(p) and "connectivity" in p.stderr and not out.exists() and not rep.exists()
    assert "(if it is, load both with the same --no-clean setting)" in p.stderr


def test_reference_whose_faces_all_have_zero_area_is_refused(cli, cube_pair, tmp_path):
    # distinct vertices on a line: no reference normal exists, so no metric against it means anything
    noisy, clean = cube_pair
    c = load_mesh(clean)
    L = np.zeros_like(c.V)
    L[:, 0] = np.arange(len(L)) * 1e-3
    flat = tmp_path / "line.ply"
    save_mesh(flat, Mesh(L, c.F))
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("denoise", noisy, "--reference", flat, "-o", out, "--report", rep)
    assert _one_line_error(p) and f"{flat}: the reference is degenerate: every face has zero area" in p.stderr
    assert not out.exists() and not rep.exists()


@pytest.mark.slow
def test_bad_method(cli, cube_pair, tmp_path):
    noisy, _ = cube_pair
    p = cli("denoise", noisy, "--method", "median", "-o", tmp_path / "o.ply")
    assert _one_line_error(p)


def _torus_distance(P, R=1.0, r=0.35):
    return np.abs(np.hypot(np.hypot(P[:, 0], P[:, 1]) - R, P[:, 2]) - r)


def test_readme_cloud_example_removes_outliers(cli, dfx, tmp_path):
    # the README's example: the fixture cloud, perturb's outliers (20 % within 1/50 of the
    # diagonal), then --outliers; F1 0.90 there, the sparser cloud's recall cap (README)
    dfx.make_all(tmp_path)
    dirty, rep = tmp_path / "dirty.ply", tmp_path / "r.json"
    p = cli("perturb", tmp_path / "torus_points.ply", "--noise", "0", "--outliers", "0.2", "--outlier-range",
            "0.02", "--seed", "4", "-o", dirty)
    assert p.returncode == 0, p.stderr
    p = cli("denoise", dirty, "--outliers", "--k", "16", "-o", tmp_path / "in.ply", "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _metrics(rep)
    assert met["true_outliers"] == 4000 and met["f1"] > 0.85


def test_outliers_refined_positions(cli, dfx, tmp_path):
    from geoproc.perturb import NoiseSpec, perturb_positions

    spec = NoiseSpec(sigma=0.3, outliers=0.2, outlier_range=0.02)
    P, flag = perturb_positions(dfx.torus_points(20000), np.zeros((0, 3), int), spec, np.random.default_rng(4))
    src = tmp_path / "cloud.ply"
    save_mesh(src, Mesh(P, np.zeros((0, 3), int), {"outlier": flag}))
    plain, ref = tmp_path / "plain.ply", tmp_path / "refined.ply"
    assert cli("denoise", src, "--outliers", "-o", plain).returncode == 0
    p = cli("denoise", src, "--outliers", "--refined", "-o", ref, "--report", tmp_path / "r.json")
    assert p.returncode == 0, p.stderr
    a, b = load_mesh(plain), load_mesh(ref)
    assert len(a.V) == len(b.V)  # the same inliers, other positions
    # against the exact torus (the clean source): the refined inliers are closer
    assert _torus_distance(b.V).mean() < 0.75 * _torus_distance(a.V).mean()
    assert _metrics(tmp_path / "r.json")["mean_refinement_shift"] > 0


def test_animation_outliers_npz(cli, dfx, tmp_path):
    V, flag, V_clean = dfx.animated_cloud_with_outliers(count=3000, frames=40, sigma=0.3)
    src = tmp_path / "cloud.npz"
    src.write_bytes(animation_to_bytes(Animation(V, np.zeros((0, 3), np.int64), {"outlier": flag})))
    out, rep = tmp_path / "o.npz", tmp_path / "r.json"
    p = cli("denoise", src, "--outliers", "--refined", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    met = _metrics(rep)
    a = load_animation(out)
    detected = a.fields["outlier_detected"] > 0.5
    assert a.V.shape == V.shape and detected.shape == flag.shape
    assert int(detected.sum()) == met["detected_outliers"]
    # F1 recomputed from the written flags and the input's truth
    tp = (detected & (flag > 0)).sum()
    f1 = 2 * tp / (detected.sum() + (flag > 0).sum())
    assert met["f1"] == pytest.approx(f1) and f1 > 0.9
    # the refined (low-rank) trajectories are closer to the clean motion
    assert np.abs(a.V - V_clean).mean() < 0.5 * np.abs(V - V_clean).mean()


def test_refined_animation_outliers_recompute_stored_normals(cli, dfx, tmp_path):
    # --refined moves every frame's vertices; per-frame nx, ny, nz had been written unchanged
    import igl

    Vn, F, _ = dfx.noisy_wave(frames=6)
    N = np.stack([igl.per_vertex_normals(v, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA) for v in Vn])
    src, out = tmp_path / "wave.npz", tmp_path / "o.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn, F, {"nx": N[..., 0], "ny": N[..., 1], "nz": N[..., 2]})))
    p = cli("denoise", src, "--outliers", "--refined", "-o", out)
    assert p.returncode == 0 and "note: recomputed the vertex normals (nx, ny, nz)" in p.stderr, p.stderr
    a = load_animation(out)
    assert np.abs(a.V - Vn).max() > 0  # moved
    for t in range(len(Vn)):
        own = igl.per_vertex_normals(a.V[t], F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
        stored = np.stack([a.fields[k][t] for k in ("nx", "ny", "nz")], axis=1)
        np.testing.assert_allclose(stored, own, atol=1e-12)


def test_animation_outliers_bad_usage(cli, dfx, tmp_path):
    V, flag, _ = dfx.animated_cloud_with_outliers(count=300, frames=10)
    src = tmp_path / "cloud.npz"
    src.write_bytes(animation_to_bytes(Animation(V, np.zeros((0, 3), np.int64))))
    out = tmp_path / "o.ply"
    p = cli("denoise", src, "--outliers", "-o", out)
    assert _one_line_error(p) and ".npz" in p.stderr and not out.exists()
    p = cli("denoise", src, "--refined", "-o", tmp_path / "o.npz")
    assert _one_line_error(p) and "--refined" in p.stderr
    np.savez(tmp_path / "flat.npz", vertices=V, faces=np.zeros((0, 3), np.int64), outlier=flag.max(axis=0))
    p = cli("denoise", tmp_path / "flat.npz", "--outliers", "-o", tmp_path / "o.npz")
    assert _one_line_error(p) and f"'outlier' has shape ({V.shape[1]},); expected (frames, n)" in p.stderr
    # every point of every frame at one place: refused as one cloud so is (had scored all 0 without a word)
    np.savez(tmp_path / "same.npz", vertices=np.ones((10, 50, 3)), faces=np.zeros((0, 3), np.int64))
    p = cli("denoise", tmp_path / "same.npz", "--outliers", "-o", tmp_path / "o.npz")
    assert _one_line_error(p) and "has no frame with a point spacing: in every frame most points share" in p.stderr
    assert not (tmp_path / "o.npz").exists()


def test_feature_options(cli, cube_pair, tmp_path):
    noisy, clean = cube_pair
    for how in ("l1", "dihedral"):
        out, rep = tmp_path / f"{how}.ply", tmp_path / f"{how}.json"
        p = cli("denoise", noisy, "--features", how, "-o", out, "--report", rep)
        assert p.returncode == 0, p.stderr
        assert _metrics(rep)["feature_method"] == how
        assert load_mesh(out).face_fields["feature"].sum() == _metrics(rep)["feature_faces"] > 0
    p = cli("denoise", noisy, "--features", "curvature", "-o", tmp_path / "x.ply")
    assert _one_line_error(p)


@pytest.mark.parametrize("args, message", [
    (["--k", "8", "--keep-all"], "--k, --keep-all: only with --outliers"),
    (["--outliers", "--sigma-r", "0.3"], "--sigma-r: not used by --outliers"),
    (["--feature-tau", "0.2"], "--feature-tau: only with --features l1"),
    (["--features", "l1", "--feature-angle", "20"], "--feature-angle: only with --features dihedral"),
])
def test_options_the_mode_would_ignore_are_refused(cli, cube_pair, tmp_path, args, message):
    noisy, _ = cube_pair
    out = tmp_path / "o.ply"
    p = cli("denoise", noisy, *args, "-o", out)
    assert _one_line_error(p) and message in p.stderr and not out.exists()


def test_reference_from_stdin(cli, cube_pair, tmp_path):
    noisy, clean = cube_pair
    rep = tmp_path / "r.json"
    p = cli("denoise", noisy, "--reference", "-", "-o", tmp_path / "o.ply", "--report", rep,
            stdin=clean.read_bytes())
    assert p.returncode == 0, p.stderr
    assert _metrics(rep)["mean_normal_angle_deg"] < _metrics(rep)["input_mean_normal_angle_deg"]
    for data in (noisy.read_bytes(), b"0 5\n"):  # refused before reading, whatever stdin holds
        p = cli("denoise", "-", "--reference", "-", "-o", tmp_path / "o.ply", stdin=data)
        assert _one_line_error(p) and "standard input can feed only one input" in p.stderr


def test_coincident_faces_error_names_the_file(cli, tmp_path):
    src = tmp_path / "pillow.obj"  # two faces on the same three vertices: centroid spacing 0
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n")
    p = cli("denoise", src, "-o", tmp_path / "o.ply")
    assert _one_line_error(p) and f"error: {src}: edge-adjacent faces have coincident centroids" in p.stderr


def test_filter_options_unused_on_a_clean_mesh_are_noted(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "torus.ply", "--sigma-r", "0.3", "-o", out)
    assert p.returncode == 0 and "note: --sigma-r not used: the mesh reads as clean" in p.stderr
    p = cli("denoise", fixture_dir / "torus.ply", "--rounds", "0", "--sigma-s", "2", "-o", out)
    assert p.returncode == 0 and "note: --sigma-s not used: no filter pass ran (--rounds 0)" in p.stderr
    # --method too: it had been dropped without a word
    p = cli("denoise", fixture_dir / "torus.ply", "--method", "rpca", "--rounds", "0", "-o", out)
    assert p.returncode == 0 and "note: --method not used: no filter pass ran (--rounds 0)" in p.stderr
    p = cli("denoise", fixture_dir / "torus.ply", "--method", "rpca", "-o", out)
    assert p.returncode == 0 and "note: --method not used: the mesh reads as clean" in p.stderr
    rep = tmp_path / "r.json"
    p = cli("denoise", fixture_dir / "torus.ply", "--crease-repair", "--rounds", "0", "-o", out, "--report", rep)
    assert p.returncode == 0 and "note: --crease-repair not used: no filter pass ran (--rounds 0)" in p.stderr
    assert _metrics(rep)["crease_repair"] is False  # it had read true with no round run


def test_guided_blended_away_by_the_schedule_is_noted(cli, dfx, tmp_path):
    # weak noise on a creased mesh gets the plain bilateral filter (guidance_mix 1): an
    # explicit --method guided gave bilateral's bytes without a word
    Vn, F, _ = dfx.noisy_cube(n=12, sigma=0.1, seed=2)
    src, rep = tmp_path / "weak.ply", tmp_path / "r.json"
    save_mesh(src, Mesh(Vn, F))
    p = cli("denoise", src, "--method", "guided", "-o", tmp_path / "g.ply", "--report", rep)
    assert p.returncode == 0 and _metrics(rep)["guidance_mix"] == 1.0
    assert "note: --method guided: at this noise level on this mesh the guidance is blended away" in p.stderr
    p = cli("denoise", src, "--method", "guided", "--guidance-mix", "0", "-o", tmp_path / "z.ply")
    assert p.returncode == 0 and "blended away" not in p.stderr
    p = cli("denoise", src, "--method", "guided", "--crease-repair", "-o", tmp_path / "r.ply")  # guided passes ran
    assert p.returncode == 0 and "blended away" not in p.stderr
    assert (tmp_path / "z.ply").read_bytes() != (tmp_path / "g.ply").read_bytes()


@pytest.mark.parametrize(("args", "message"), [
    (["--sigma-r", "0"], "error: --sigma-r 0: must be > 0\n"),
    (["--sigma-s", "-2"], "error: --sigma-s -2: must be > 0\n"),
    (["--feature-angle", "400"], "error: --feature-angle 400: must be within [0, 180] degrees\n"),
    # %g showed a value just past the bound as the bound itself
    (["--feature-angle", "180.0000001"], "error: --feature-angle 180.0000001: must be within [0, 180] degrees\n"),
    (["--features", "l1", "--feature-tau", "-1"], "error: --feature-tau -1: must be >= 0\n"),
])
def test_a_parameter_out_of_range_is_named_alone(cli, fixture_dir, tmp_path, args, message):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "torus.ply", *args, "-o", out)
    assert p.returncode == 2 and p.stderr == message and not out.exists()


def test_sigma_r_whose_square_underflows_is_refused(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "torus.ply", "--sigma-r", "1e-300", "--rounds", "1", "-o", out)
    assert _one_line_error(p) and "--sigma-r 1e-300 is too small" in p.stderr and not out.exists()


def test_sigma_s_too_small_for_the_mesh_names_the_mesh(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "torus.ply", "--rounds", "1", "--sigma-s", "1e-160", "-o", out)
    assert _one_line_error(p) and "torus.ply: spatial kernel width" in p.stderr
    assert "its square underflows" in p.stderr and not out.exists()


def test_fidelity_option_reaches_the_vertex_update(cli, cube_pair, tmp_path):
    noisy, clean = cube_pair
    theta = {}
    for mu in ("0", "0.5"):
        rep = tmp_path / f"r{mu}.json"
        p = cli("denoise", noisy, "--fidelity", mu, "--reference", clean, "-o", tmp_path / "d.ply",
                "--report", rep)
        assert p.returncode == 0, p.stderr
        assert json.loads(rep.read_text())["params"]["fidelity"] == float(mu)
        assert _metrics(rep)["fidelity"] == float(mu)
        theta[mu] = _metrics(rep)["mean_normal_angle_deg"]
    # a strong pull back to the noisy input keeps much of its noise
    assert theta["0.5"] > 2 * theta["0"]
    out = tmp_path / "x.ply"
    p = cli("denoise", noisy, "--fidelity", "1.5", "-o", out)
    assert p.returncode == 2 and "--fidelity" in p.stderr and not out.exists()


def test_dynamic_checks_every_frame_and_names_file_and_frame(cli, dfx, tmp_path):
    Vn, F, _ = dfx.noisy_wave(frames=4)
    out = tmp_path / "d.npz"
    flat = Vn.copy()
    flat[2][:, 1:] = 0.0  # every point of frame 2 on a line: no face of any area
    src = tmp_path / "flat.npz"
    src.write_bytes(animation_to_bytes(Animation(flat, F)))
    p = cli("denoise", src, "--dynamic", "-o", out)
    assert _one_line_error(p) and "flat.npz: frame 2: degenerate mesh" in p.stderr and not out.exists()
    # a problem the method finds in one frame names the file and the frame
    src = tmp_path / "wave.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn, F)))
    p = cli("denoise", src, "--dynamic", "--sigma-s", "1e-160", "-o", out)
    assert _one_line_error(p) and "wave.npz: frame 0: spatial kernel width" in p.stderr and not out.exists()
    mesh = tmp_path / "frame.ply"
    save_mesh(mesh, Mesh(Vn[0], F))
    p = cli("denoise", src, "--dynamic", "--reference", mesh, "-o", out)
    assert _one_line_error(p) and "with --dynamic the reference is an animation" in p.stderr
    # a reference animation with a frame of no area is refused too, naming the frame
    ref = tmp_path / "ref.npz"
    ref.write_bytes(animation_to_bytes(Animation(flat, F)))
    p = cli("denoise", src, "--dynamic", "--reference", ref, "-o", out)
    assert _one_line_error(p) and "ref.npz: the reference is degenerate (frame 2): every face has zero area" \
        in p.stderr and not out.exists()
    # other counts: no advice on --no-clean, which --dynamic refuses
    ref.write_bytes(animation_to_bytes(Animation(Vn, F[:0])))
    p = cli("denoise", src, "--dynamic", "--reference", ref, "-o", out)
    assert _one_line_error(p) and "ref.npz: reference connectivity differs from the input" in p.stderr
    assert "same faces in the same order\n" in p.stderr and not out.exists()
    # the outlier field travels to the output: non-finite values are refused there too
    src = tmp_path / "inf.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn, F, {"outlier": np.full(Vn.shape[:2], np.inf)})))
    p = cli("denoise", src, "--dynamic", "-o", out)
    assert _one_line_error(p) and "'outlier' property has non-finite values" in p.stderr and not out.exists()


def test_dynamic_with_an_unused_last_vertex(cli, dfx, tmp_path):
    Vn, F, _ = dfx.noisy_wave(frames=3)
    extra = np.concatenate([Vn, np.full((3, 1, 3), 5.0)], axis=1)
    src, out, rep = tmp_path / "extra.npz", tmp_path / "d.npz", tmp_path / "r.json"
    src.write_bytes(animation_to_bytes(Animation(extra, F)))
    p = cli("denoise", src, "--dynamic", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    V = load_animation(out).V
    assert np.isfinite(V).all() and np.array_equal(V[:, -1], extra[:, -1])
    assert _metrics(rep)["fidelity"] == 0.005


def test_huge_sigma_r_is_a_plain_average(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "torus.ply", "--sigma-r", "1e200", "--rounds", "1", "-o", out)
    assert p.returncode == 0, p.stderr


def test_fit_options_unused_are_noted(cli, fixture_dir, tmp_path):
    out = tmp_path / "o.ply"
    p = cli("denoise", fixture_dir / "torus.ply", "--fidelity", "0.1", "-o", out)
    assert p.returncode == 0 and "note: --fidelity not used: the mesh reads as clean" in p.stderr
    p = cli("denoise", fixture_dir / "torus.ply", "--rounds", "1", "--vertex-iterations", "0",
            "--fidelity", "0.1", "-o", out)
    assert p.returncode == 0 and "note: --fidelity not used: no vertex sweep ran" in p.stderr
    rep = tmp_path / "r.json"  # and it is null in the report (it had been recorded as if it had acted)
    p = cli("denoise", fixture_dir / "torus.ply", "--rounds", "1", "--vertex-iterations", "0",
            "--fidelity", "0.1", "-o", out, "--report", rep)
    assert json.loads(rep.read_text())["metrics"]["fidelity"] is None
    p = cli("denoise", fixture_dir / "torus.ply", "--rounds", "1", "--normal-iterations", "0",
            "--sigma-r", "0.3", "-o", out)
    assert "note: --sigma-r not used: no filter pass ran (--normal-iterations 0)" in p.stderr


def test_options_the_narrow_passes_use_with_no_scheduled_pass(cli, fixture_dir, tmp_path):
    # with --normal-iterations 0 the crease repair's narrow passes still run in the last round:
    # --sigma-s acts (it had been called unused) and --sigma-r, --guidance-mix do not (they had
    # been reported as if they had)
    noisy, rep = tmp_path / "n.ply", tmp_path / "r.json"
    assert cli("perturb", fixture_dir / "cube.ply", "--noise", "0.3", "--seed", "1", "-o", noisy).returncode == 0
    base = ("denoise", noisy, "--rounds", "2", "--normal-iterations", "0")
    p = cli(*base, "--sigma-s", "1.5", "--sigma-r", "0.4", "--guidance-mix", "0.3", "-o", tmp_path / "a.ply",
            "--report", rep)
    assert p.returncode == 0 and ("note: --sigma-r, --guidance-mix not used: no pass of the schedule ran "
                                  "(--normal-iterations 0); the last round's narrow guided passes") \
        in " ".join(p.stderr.split()), p.stderr
    m = json.loads(rep.read_text())["metrics"]
    assert m["sigma_s"] == 1.5 and m["sigma_r"] is None and m["guidance_mix"] is None
    assert cli(*base, "-o", tmp_path / "b.ply").returncode == 0
    assert (tmp_path / "a.ply").read_bytes() != (tmp_path / "b.ply").read_bytes()  # --sigma-s acted
    # --method decides whether the crease repair runs: not called unused (it had been)
    p = cli(*base, "--method", "bilateral", "-o", tmp_path / "c.ply")
    assert p.returncode == 0 and "--method not used" not in p.stderr, p.stderr
    assert (tmp_path / "c.ply").read_bytes() != (tmp_path / "b.ply").read_bytes()


def test_dynamic_from_standard_input_says_where_animations_are_read(cli, tmp_path):
    p = cli("denoise", "-", "--dynamic", "-o", tmp_path / "d.npz", stdin=b"PK\x03\x04")
    assert _one_line_error(p) and "-: --dynamic reads an animation from a file or folder" in p.stderr


def test_animations_in_and_out_as_folders_of_frames(cli, dfx, tmp_path):
    # --dynamic and --outliers on an animation write the same frames to a
    # folder as to a .npz, and a folder written so reads back as the input
    Vn, F, V = dfx.noisy_wave(frames=3)
    src, ref = tmp_path / "noisy.npz", tmp_path / "clean.npz"
    src.write_bytes(animation_to_bytes(Animation(Vn, F)))
    ref.write_bytes(animation_to_bytes(Animation(V, F)))
    p = cli("perturb", ref, "--noise", "0", "--seed", "1", "-o", str(tmp_path / "clean") + "/")
    assert p.returncode == 0, p.stderr
    runs = {}
    for name, out in (("npz", tmp_path / "d.npz"), ("folder", str(tmp_path / "d") + "/")):
        rep = tmp_path / f"{name}.json"
        reference = ref if name == "npz" else tmp_path / "clean"
        p = cli("denoise", src, "--dynamic", "--reference", reference, "-o", out, "--report", rep)
        assert p.returncode == 0, p.stderr
        runs[name] = (load_animation(out), _metrics(rep))
    (a, ma), (b, mb) = runs["npz"], runs["folder"]
    assert np.array_equal(a.V, b.V) and b.n_frames == 3
    assert ma["mean_normal_angle_deg"] == mb["mean_normal_angle_deg"]
    P = dfx.animated_cloud(count=300, frames=4)
    moving = tmp_path / "moving.npz"
    moving.write_bytes(animation_to_bytes(Animation(P, np.zeros((0, 3), dtype=np.int64))))
    for out in (tmp_path / "m.npz", str(tmp_path / "m") + "/"):
        p = cli("perturb", moving, "--noise", "0.1", "--outliers", "0.1", "--seed", "2", "-o", out)
        assert p.returncode == 0, p.stderr
    outs = []
    for src_m, out in ((tmp_path / "m.npz", tmp_path / "mo.npz"), (tmp_path / "m", str(tmp_path / "mo") + "/")):
        p = cli("denoise", src_m, "--outliers", "-o", out)
        assert p.returncode == 0, p.stderr
        outs.append(load_animation(out))
    assert np.array_equal(outs[0].V, outs[1].V) and outs[1].F.shape == (0, 3)
    assert all(np.array_equal(outs[0].fields[k], outs[1].fields[k]) for k in ("outlier_score", "outlier_detected"))


def test_dynamic_on_a_mesh_names_the_input_before_a_folder_output(cli, fixture_dir, tmp_path):
    # a folder of meshes as -o had been refused for its meshes, hiding that the input is no animation
    folder = tmp_path / "meshes"
    folder.mkdir()
    (folder / "cube.ply").write_bytes((fixture_dir / "cube.ply").read_bytes())
    p = cli("denoise", folder / "cube.ply", "--dynamic", "-o", folder)
    assert _one_line_error(p) and "cube.ply: --dynamic needs an animation" in p.stderr
    p = cli("denoise", folder / "gone.ply", "--dynamic", "-o", tmp_path / "o.npz")
    assert _one_line_error(p) and "gone.ply: no such file or folder" in p.stderr
