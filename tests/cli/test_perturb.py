"""``geoproc perturb`` through the real command line."""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np
import pytest

from geoproc.animation import load_animation
from geoproc.mesh import Mesh, load_mesh, save_mesh
from geoproc.perturb import noise_scale
from geoproc.report import validate_report
from tests.conftest import load_fixture_module, run_cli_under


def denoise_fixtures():
    return load_fixture_module("denoise_fixtures")


def test_same_seed_same_bytes_and_requested_sigma(cli, fixture_dir, tmp_path):
    a, b = tmp_path / "a.ply", tmp_path / "b.ply"
    for out in (a, b):
        p = cli("perturb", fixture_dir / "icosphere.ply", "--noise", "0.3", "--seed", "7", "-o", out)
        assert p.returncode == 0, p.stderr
    assert a.read_bytes() == b.read_bytes()
    clean = load_mesh(fixture_dir / "icosphere.ply")
    noisy = load_mesh(a)
    along = np.einsum("ij,ij->i", noisy.V - clean.V, clean.V)  # unit sphere: the normal is the position
    # 642 vertices: the sample std is within ~3 % of sigma (one standard error); allow 10 %
    assert abs(along.std() / noise_scale(clean.V, clean.F) - 0.3) < 0.1 * 0.3


def test_a_point_cloud_with_the_same_seed_gives_the_same_bytes(cli, fixture_dir, tmp_path):
    outs = [tmp_path / "a.ply", tmp_path / "b.ply", tmp_path / "c.ply"]
    for out, seed in zip(outs, ("5", "5", "6"), strict=True):
        p = cli("perturb", fixture_dir / "points.ply", "--noise", "0.3", "--outliers", "0.1", "--outlier-range",
                "0.02", "--seed", seed, "-o", out)
        assert p.returncode == 0, p.stderr
    assert outs[0].read_bytes() == outs[1].read_bytes() != outs[2].read_bytes()


def test_stored_normals_follow_the_moved_vertices(cli, fixture_dir, tmp_path):
    # a sphere with its radial normals stored, perturbed, then denoised: the stored normals
    # had come out as the input's (764 of the bunny's 3,485 more than 20 degrees off its own)
    import igl

    m = load_mesh(fixture_dir / "icosphere.ply")
    R = m.V / np.linalg.norm(m.V, axis=1, keepdims=True)
    src = tmp_path / "n.ply"
    save_mesh(src, Mesh(m.V, m.F, {"nx": R[:, 0], "ny": R[:, 1], "nz": R[:, 2], "label": np.arange(len(m.V)) * 1.0}))
    noisy, clean, refined = tmp_path / "p.ply", tmp_path / "d.ply", tmp_path / "r.ply"
    # (denoise --outliers --refined moves a mesh's vertices too: its normals had stayed the input's)
    for args in (("perturb", src, "--noise", "0.5", "--seed", "3", "-o", noisy), ("denoise", noisy, "-o", clean),
                 ("denoise", noisy, "--outliers", "--refined", "--keep-all", "-o", refined)):
        p = cli(*args)
        assert p.returncode == 0 and "note: recomputed the vertex normals (nx, ny, nz)" in p.stderr, p.stderr
        out = load_mesh(args[-1])
        N = np.stack([out.vertex_fields[k] for k in ("nx", "ny", "nz")], axis=1)
        own = igl.per_vertex_normals(out.V, out.F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
        np.testing.assert_allclose(N, own, atol=1e-12)  # libigl's area-weighted normals of the output
        assert np.array_equal(out.vertex_fields["label"], np.arange(len(m.V)))  # other properties carried
        assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", N, R), -1, 1))).max() > 5  # they did move


def test_outlier_values_other_than_0_and_1_are_noted(cli, fixture_dir, tmp_path):
    # flags interpolated by an earlier command: read as flags above 0.5, rewritten as 0/1
    m = load_mesh(fixture_dir / "points.ply")
    flags = np.zeros(len(m.V))
    flags[:4] = [0.3, 0.7, 1.0, 0.5]
    src, out = tmp_path / "f.ply", tmp_path / "o.ply"
    save_mesh(src, Mesh(m.V, m.F, {"outlier": flags}))
    p = cli("perturb", src, "--noise", "0", "--outliers", "0.01", "--seed", "1", "-o", out)
    assert p.returncode == 0, p.stderr
    assert (f"note: {src}: the 'outlier' property has 3 values other than 0 and 1: read as outlier flags "
            "where above 0.5, and written as 0 and 1") in " ".join(p.stderr.split())
    got = load_mesh(out).vertex_fields["outlier"]
    assert set(np.unique(got).tolist()) <= {0.0, 1.0} and got[1] == 1.0 and got[0] == 0.0 and got[3] == 0.0


def test_outliers_property_and_report(cli, fixture_dir, tmp_path):
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("perturb", fixture_dir / "points.ply", "--noise", "0", "--outliers", "0.25", "--outlier-range",
            "0.05", "--seed", "1", "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    m = load_mesh(out)
    assert m.is_point_cloud and m.vertex_fields["outlier"].sum() == 50
    assert json.loads(rep.read_text())["metrics"]["outlier_vertices"] == 50


def test_outlier_flags_of_an_earlier_run_are_kept(cli, fixture_dir, tmp_path):
    once, twice, rep = tmp_path / "o1.ply", tmp_path / "o2.ply", tmp_path / "r.json"
    args = ("--noise", "0", "--outliers", "0.1")
    assert cli("perturb", fixture_dir / "points.ply", *args, "--seed", "1", "-o", once).returncode == 0
    p = cli("perturb", once, *args, "--seed", "2", "-o", twice, "--report", rep)
    assert p.returncode == 0, p.stderr
    clean, a, b = load_mesh(fixture_dir / "points.ply"), load_mesh(once), load_mesh(twice)
    moved = np.linalg.norm(b.V - clean.V, axis=1) > 0
    flagged = b.vertex_fields["outlier"] > 0.5
    assert np.array_equal(moved, flagged) and flagged.sum() > a.vertex_fields["outlier"].sum()
    assert json.loads(rep.read_text())["metrics"]["outlier_vertices"] == int(flagged.sum())


def test_animation_npz(cli, tmp_path):
    dfx = denoise_fixtures()
    V, F = dfx.wave_animation(3)
    from geoproc.animation import Animation, animation_to_bytes

    src = tmp_path / "wave.npz"
    src.write_bytes(animation_to_bytes(Animation(V, F)))
    outs = [tmp_path / "n1.npz", tmp_path / "n2.npz"]
    for out in outs:
        p = cli("perturb", src, "--noise", "0.3", "--seed", "3", "-o", out)
        assert p.returncode == 0, p.stderr
    assert outs[0].read_bytes() == outs[1].read_bytes()
    a = load_animation(outs[0])
    assert a.V.shape == V.shape and np.array_equal(a.F, F)
    rep = tmp_path / "r.json"
    assert cli("perturb", src, "--noise", "0.3", "--seed", "3", "-o", outs[0], "--report", rep).returncode == 0
    rms = json.loads(rep.read_text())["metrics"]["rms_displacement"]
    assert np.isclose(rms, np.sqrt(np.mean(np.sum((a.V - V) ** 2, axis=2))))
    assert not np.allclose(a.V[0], V[0]) and not np.allclose(a.V[0] - V[0], a.V[1] - V[1])


def test_checks_on_metrics_of_the_other_kind_of_input_are_refused_before_the_work(cli, fixture_dir, tmp_path):
    # they had been refused after the run, as "depends on the input's content"
    dfx = denoise_fixtures()
    from geoproc.animation import Animation, animation_to_bytes

    src = tmp_path / "wave.npz"
    src.write_bytes(animation_to_bytes(Animation(*dfx.wave_animation(3))))
    for input, gate, wanted in ((fixture_dir / "torus.ply", "frames>=1", "only with an animation"),
                                (src, "input_vertices>=1", "only with a mesh or point cloud (not an animation)")):
        out = tmp_path / ("o.npz" if input == src else "o.ply")
        p = cli("perturb", input, "--seed", "1", "-o", out, "--check", gate)
        assert p.returncode == 2 and wanted in p.stderr and p.stderr.count("\n") == 1, p.stderr
        assert not out.exists()
    rep = tmp_path / "r.json"
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "o.npz", "--report", rep)
    assert p.returncode == 0 and not set(json.loads(rep.read_text())["metrics"]) & {"input_vertices", "input_faces"}


def test_moving_point_cloud(cli, tmp_path):
    # a point-cloud animation (no faces) takes noise and outliers; the outlier
    # flags then score denoise --outliers (the README's moving-cloud example)
    from geoproc.animation import Animation, animation_to_bytes

    V = denoise_fixtures().animated_cloud(count=600, frames=6)
    none = np.zeros((0, 3), dtype=np.int64)
    src, dirty = tmp_path / "moving.npz", tmp_path / "dirty.npz"
    src.write_bytes(animation_to_bytes(Animation(V, none)))
    p = cli("perturb", src, "--noise", "0.3", "--direction", "random", "--outliers", "0.2", "--outlier-range",
            "0.02", "--seed", "4", "-o", dirty, "--report", tmp_path / "r.json")
    assert p.returncode == 0, p.stderr
    a = load_animation(dirty)
    metrics = json.loads((tmp_path / "r.json").read_text())["metrics"]
    assert a.V.shape == V.shape and len(a.F) == 0 and metrics["faces"] == 0
    assert metrics["outlier_vertices"] == a.fields["outlier"].sum() == round(0.2 * 600) * 6
    rep = tmp_path / "d.json"
    p = cli("denoise", dirty, "--outliers", "-o", tmp_path / "clean.npz", "--report", rep)
    assert p.returncode == 0, p.stderr
    assert json.loads(rep.read_text())["metrics"]["true_outliers"] == round(0.2 * 600) * 6, rep.read_text()
    V[2] = V[2, 0]  # frame 2: every point in one place
    src.write_bytes(animation_to_bytes(Animation(V, none)))
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "bad.npz")
    assert p.returncode == 2 and "moving.npz: frame 2: a point cloud needs at least 3 distinct points" in p.stderr


def test_bad_options_exit_2_without_output(cli, fixture_dir, tmp_path):
    out = tmp_path / "x.ply"
    for args, needle in ((["--outliers", "1.5"], "fraction"), (["--noise", "1e300"], "beyond the +-1e+50"),
                         (["--outliers", "0.5", "--outlier-range", "1e60"], "beyond the +-1e+50"),
                         (["--noise", "1e308"], "to non-finite positions"),
                         (["--outlier-range", "0.5"], "--outlier-range: only with --outliers"),
                         (["--noise", "0", "--direction", "random"], "--direction: not used with --noise 0"),
                         (["--outliers", "0.1", "--outlier-range", "0"], "--outlier-range 0.0: must be > 0"),
                         (["--noise", "1e60"], "error: --noise 1e+60 moves vertices as far as")):
        p = cli("perturb", fixture_dir / "icosphere.ply", "--seed", "1", "-o", out, *args)
        assert p.returncode == 2 and p.stderr.startswith("error:") and len(p.stderr.strip().splitlines()) == 1
        assert needle in p.stderr
    assert not out.exists()
    p = cli("perturb", fixture_dir / "nan.ply", "--seed", "1", "-o", out)
    assert p.returncode == 2 and not out.exists()


def test_animation_with_a_degenerate_frame_or_no_clean_exit_2(cli, tmp_path):
    from geoproc.animation import Animation, animation_to_bytes

    V, F = denoise_fixtures().wave_animation(3)
    flat = V.copy()
    flat[1][:, 1:] = 0.0  # frame 1: every point on a line
    src, out = tmp_path / "flat.npz", tmp_path / "o.npz"
    src.write_bytes(animation_to_bytes(Animation(flat, F)))
    p = cli("perturb", src, "--seed", "1", "--outliers", "0.1", "-o", out)
    assert p.returncode == 2 and "flat.npz: frame 1: degenerate mesh" in p.stderr and not out.exists()
    src.write_bytes(animation_to_bytes(Animation(V, F)))
    p = cli("perturb", src, "--seed", "1", "--no-clean", "-o", out)
    assert p.returncode == 2 and "--no-clean: not used for an animation" in p.stderr and not out.exists()


def test_animation_with_differing_connectivity_exit_2(cli, tmp_path):
    np.savez(tmp_path / "bad.npz", vertices=np.zeros((2, 3, 3)), faces=np.array([[[0, 1, 2]], [[0, 2, 1]]]))
    out = tmp_path / "o.npz"
    p = cli("perturb", tmp_path / "bad.npz", "--seed", "1", "-o", out)
    assert p.returncode == 2 and "connectivity" in p.stderr and not out.exists()


def test_frame_properties_named_like_the_geometry_do_not_replace_it(cli, tmp_path):
    V, F = denoise_fixtures().wave_animation(3)
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, Vk in enumerate(V):
        fields = {"vertices": np.ones(len(Vk)), "faces": np.ones(len(Vk)), "tag": np.full(len(Vk), k + 0.5)}
        save_mesh(folder / f"f{k}.ply", Mesh(Vk, F, vertex_fields=fields))
    out = tmp_path / "n.npz"
    p = cli("perturb", folder, "--noise", "0.3", "--seed", "3", "-o", out)
    assert p.returncode == 0, p.stderr
    z = np.load(out)
    assert sorted(z.files) == ["faces", "tag", "vertices"]
    assert z["vertices"].shape == V.shape and np.array_equal(z["faces"], F)
    assert np.abs(z["vertices"] - V).max() > 0 and z["tag"][:, 0].tolist() == [0.5, 1.5, 2.5]


def test_a_bad_frame_of_a_folder_is_named_by_its_file(cli, tmp_path):
    V, F = denoise_fixtures().wave_animation(4)
    for case in ("degenerate", "outlier"):
        folder = tmp_path / case
        folder.mkdir()
        for k, Vk in enumerate(V):
            flags = np.zeros(len(Vk))
            flags[5] = np.nan if (case == "outlier" and k == 2) else 0.0
            Vk = Vk * 0.0 if (case == "degenerate" and k == 2) else Vk
            save_mesh(folder / f"shot_{10 * (k + 1)}.ply", Mesh(Vk, F, vertex_fields={"outlier": flags}))
        out = tmp_path / f"{case}.npz"
        p = cli("perturb", folder, "--seed", "1", "-o", out)
        assert p.returncode == 2 and p.stderr.startswith(f"error: {folder / 'shot_30.ply'}: "), p.stderr
        assert not out.exists()


def test_animation_noise_scale_is_the_mean_of_the_frames(cli, tmp_path):
    V, F = denoise_fixtures().wave_animation(3)
    V = V * np.array([1.0, 10.0, 100.0])[:, None, None]
    np.savez(tmp_path / "s.npz", vertices=V, faces=F)
    rep = tmp_path / "r.json"
    p = cli("perturb", tmp_path / "s.npz", "--seed", "1", "-o", tmp_path / "n.npz", "--report", rep)
    assert p.returncode == 0, p.stderr
    scales = [noise_scale(Vk, F) for Vk in V]
    assert json.loads(rep.read_text())["metrics"]["noise_scale"] == pytest.approx(np.mean(scales), rel=1e-12)
    # but each frame's noise is in its own frame's mean edge length (libigl's edges here):
    # sigma 0.3 along the normals, RMS within 10 % over 1536 vertices (over 5 standard errors)
    import igl

    p = cli("perturb", tmp_path / "s.npz", "--noise", "0.3", "--seed", "1", "-o", tmp_path / "m.npz")
    assert p.returncode == 0, p.stderr
    W = np.load(tmp_path / "m.npz")["vertices"]
    E = igl.edges(F)
    for Vk, Wk in zip(V, W, strict=True):
        h = np.linalg.norm(Vk[E[:, 0]] - Vk[E[:, 1]], axis=1).mean()
        rms = np.sqrt(np.mean(np.sum((Wk - Vk) ** 2, axis=1)))
        assert rms / h == pytest.approx(0.3, rel=0.1)


def test_animation_folder_is_recorded_in_the_report(cli, tmp_path):
    import trimesh

    V, F = denoise_fixtures().wave_animation(3)
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, Vk in enumerate(V):
        trimesh.Trimesh(Vk, F, process=False).export(folder / f"frame{k:03d}.obj")

    def recorded():
        rep = tmp_path / "r.json"
        p = cli("perturb", folder, "--noise", "0.3", "--seed", "3", "-o", tmp_path / "n.npz", "--report", rep)
        assert p.returncode == 0, p.stderr
        report = json.loads(rep.read_text())
        validate_report(report)
        (entry,) = report["inputs"]
        assert entry["path"] == str(folder)
        frames = [folder / f"frame{k:03d}.obj" for k in range(len(V))]
        digests = [hashlib.sha256(f.read_bytes()).hexdigest() for f in frames]
        assert entry["frames"] == [{"path": str(f), "sha256": d} for f, d in zip(frames, digests, strict=True)]
        # the folder's hash: its frame files sorted by name, each as name, NUL, hex SHA-256
        pairs = zip(frames, digests, strict=True)
        expect = hashlib.sha256(b"".join(f.name.encode() + b"\0" + d.encode() for f, d in pairs))
        assert entry["sha256"] == expect.hexdigest()
        return entry["sha256"]

    first = recorded()
    trimesh.Trimesh(V[1] + 1e-3, F, process=False).export(folder / "frame001.obj")
    assert recorded() != first  # the folder's hash follows its frames' contents
    second = recorded()
    with open(os.path.join(os.fsencode(folder), b"notes\xff.txt"), "wb") as fh:  # a name that is not UTF-8
        fh.write(b"x")
    (folder / "ply").write_text("not a frame")  # no extension: not a frame mesh either
    assert recorded() == second  # files that are not frames are not inputs; no crash on the name
    np.savez(tmp_path / "c.npz", vertices=V.astype(np.complex128), faces=F)
    p = cli("perturb", tmp_path / "c.npz", "--seed", "3", "-o", tmp_path / "n.npz")
    assert p.returncode == 2 and "'vertices' must hold real numbers, got dtype complex128" in p.stderr


def test_fractions_that_round_to_no_vertex_are_noted(cli, fixture_dir, tmp_path):
    out = tmp_path / "p.ply"
    p = cli("perturb", fixture_dir / "torus.ply", "--impulsive", "1e-300", "--seed", "1", "-o", out)
    assert p.returncode == 0 and "note: --impulsive 1e-300 of 1152 vertices rounds to none" in p.stderr
    p = cli("perturb", fixture_dir / "torus.ply", "--outliers", "1e-9", "--seed", "1", "-o", out)
    assert p.returncode == 0 and "note: --outliers 1e-09 of 1152 vertices rounds to none" in p.stderr
    p = cli("perturb", fixture_dir / "torus.ply", "--impulsive", "0.1", "--seed", "1", "-o", out)
    assert p.returncode == 0 and "rounds to none" not in p.stderr


def test_npz_members_not_carried_are_noted(cli, tmp_path):
    # arrays that are not (frames, n) numbers were dropped from the output without a word
    V = np.random.default_rng(0).random((3, 4, 3))
    src, out = tmp_path / "a.npz", tmp_path / "b.npz"
    np.savez(src, vertices=V, faces=np.array([[0, 1, 2], [0, 2, 3]]), scale=np.arange(3.0), tag=np.ones((3, 4)))
    p = cli("perturb", src, "--noise", "0.1", "--seed", "1", "-o", out, "--report", tmp_path / "r.json")
    assert p.returncode == 0, p.stderr
    assert f"note: {src}: not carried (only real numeric arrays shaped (frames, n) travel): scale (3,)" in p.stderr
    assert json.loads((tmp_path / "r.json").read_text())["inputs"][0]["not_carried"] == ["scale (3,)"]
    assert sorted(np.load(out).files) == ["faces", "tag", "vertices"]
    # a folder of frames: a face property and a vertex property of one frame only
    from geoproc.mesh import Mesh, save_mesh

    folder = tmp_path / "frames"
    folder.mkdir()
    F = np.array([[0, 1, 2], [0, 2, 3]])
    for k, Vk in enumerate(V):
        save_mesh(folder / f"f{k}.ply", Mesh(Vk, F, {"tag": np.ones(4)} | ({"only0": np.ones(4)} if k == 0 else {}),
                                             {"quality": np.ones(2)}))
    p = cli("perturb", folder, "--noise", "0.1", "--seed", "1", "-o", out)
    assert p.returncode == 0, p.stderr
    assert (f"note: {folder}: not carried (only per-vertex scalar properties of every frame travel): "
            "vertex only0 (not in every frame), face quality") in " ".join(p.stderr.split())
    assert sorted(np.load(out).files) == ["faces", "tag", "vertices"]


def test_outlier_flags_need_a_ply_output(cli, fixture_dir, tmp_path):
    # an .off output kept the moved vertices but not their flags, with exit 0 and a
    # report counting the outliers
    out = tmp_path / "p.off"
    p = cli("perturb", fixture_dir / "torus.ply", "--outliers", "0.1", "--outlier-range", "0.01", "--seed", "1",
            "-o", out)
    assert p.returncode == 2 and "only PLY keeps" in p.stderr and p.stderr.count("\n") == 1
    assert not list(tmp_path.iterdir())


def test_outputs_that_must_be_ply_name_the_real_problem(cli, fixture_dir, tmp_path):
    # a name with no or an unknown extension was told "only PLY keeps" the property;
    # denoise --outliers --keep-all wrote an .obj without its scores, with a note only
    torus = fixture_dir / "torus.ply"
    cloud = tmp_path / "c.ply"
    assert cli("perturb", torus, "--seed", "1", "--noise", "0", "--outliers", "0.1", "--outlier-range", "0.05",
               "-o", cloud).returncode == 0
    cases = [
        (["geodesic", torus, "-s", "0"], "noext", "no file extension to choose the format by"),
        (["geodesic", torus, "-s", "0"], "d.xyz", "cannot write '.xyz'"),
        (["geodesic", torus, "-s", "0"], "d.obj", "the distance is a vertex property, which only PLY keeps"),
        (["perturb", torus, "--seed", "1", "--outliers", "0.1", "--outlier-range", "0.01"], "p.xyz",
         "cannot write '.xyz'"),
        (["morse-simplify", torus, "-f", "z", "-p", "0.1"], "m", "no file extension to choose the format by"),
        (["morse-simplify", torus, "-f", "z", "-p", "0.1"], "m.off",
         "the fields are vertex properties, which only PLY keeps"),
        (["denoise", cloud, "--outliers", "--keep-all"], "o.obj",
         "--keep-all marks the outliers in vertex properties (outlier_score, outlier_detected), which only PLY keeps"),
    ]
    for args, name, problem in cases:
        out = tmp_path / name
        p = cli(*args, "-o", out)
        assert p.returncode == 2 and p.stderr.startswith(f"error: {out}: {problem}"), (name, p.stderr)
        assert not out.exists()
    p = cli("denoise", cloud, "--outliers", "-o", tmp_path / "o.obj", "-q")  # the inliers only: any format
    assert p.returncode == 0, p.stderr


def test_properties_a_geometry_format_drops_are_noted(cli, fixture_dir, tmp_path):
    src = tmp_path / "g.ply"
    assert cli("geodesic", fixture_dir / "torus.ply", "-s", "0", "-o", src, "-q").returncode == 0
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "p.obj")
    assert p.returncode == 0
    assert "note: " + str(tmp_path / "p.obj") + ": .obj keeps geometry only; not written: vertex distance" in p.stderr
    # STL's float32 corners: positions rounded and vertices renumbered when read back, said
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "p.stl")
    assert p.returncode == 0, p.stderr
    assert ("p.stl: STL stores each triangle's corners as 32-bit floats; read back: positions rounded (to about "
            "6e-8 of their size) and vertices numbered anew (in order of first use)") in p.stderr, p.stderr
    assert "STL stores" not in cli("perturb", src, "--seed", "1", "-o", tmp_path / "q.obj").stderr
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "p.ply")
    assert p.returncode == 0 and "keeps geometry only" not in p.stderr


def test_what_an_obj_input_stores_beyond_its_geometry_is_noted(cli, tmp_path):
    # texture coordinates and colours of an OBJ had been dropped without a word
    src = tmp_path / "t.obj"
    src.write_bytes(b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 1 1 1 1\nvt 0 0\n"
                    b"f 1/1 3/1 2/1\nf 1/1 2/1 4/1\nf 1/1 4/1 3/1\nf 2/1 3/1 4/1\n")
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "p.ply")
    assert p.returncode == 0, p.stderr
    assert (f"note: {src}: not carried (only positions and faces are read from OBJ): texture coordinates (vt), "
            "colours after x y z on v lines") in p.stderr
    # and in the report, where --quiet silences the note
    rep = tmp_path / "r.json"
    p = cli("perturb", src, "--seed", "1", "-o", tmp_path / "q.ply", "--quiet", "--report", rep)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    entry = json.loads(rep.read_text())["inputs"][0]
    assert entry["not_carried"] == ["texture coordinates (vt)", "colours after x y z on v lines"]
    p = cli("perturb", tmp_path / "q.ply", "--seed", "1", "-o", tmp_path / "r.ply", "--report", rep)
    assert "not_carried" not in json.loads(rep.read_text())["inputs"][0]


def test_impulsive_fraction_counts_from_none_to_all(cli, fixture_dir, tmp_path):
    # --impulsive 0 had meant every vertex; now 0 moves none (said) and 1, the default, every one
    src = fixture_dir / "torus.ply"
    V0 = load_mesh(src).V
    runs = {}
    for frac in (None, "1", "0", "0.5"):
        out = tmp_path / f"i{frac}.ply"
        p = cli("perturb", src, "--noise", "0.3", "--seed", "1", "-o", out, *(["--impulsive", frac] if frac else []))
        assert p.returncode == 0, p.stderr
        assert ("--impulsive 0: the Gaussian noise moves no vertex" in p.stderr) == (frac == "0")
        runs[frac] = np.linalg.norm(load_mesh(out).V - V0, axis=1) > 0
    assert runs[None].all() and runs["1"].all() and not runs["0"].any()
    assert runs["0.5"].sum() == round(0.5 * len(V0))
    assert (tmp_path / "iNone.ply").read_bytes() == (tmp_path / "i1.ply").read_bytes()


def _wave_npz(path, frames):
    from geoproc.animation import Animation, animation_to_bytes

    path.write_bytes(animation_to_bytes(Animation(*denoise_fixtures().wave_animation(frames))))
    return path


def test_an_animation_written_as_a_folder_of_frames(cli, tmp_path):
    # the frames read back as the .npz output does; a rerun with fewer frames
    # leaves none of the earlier run's extra frames behind
    src = _wave_npz(tmp_path / "wave.npz", 4)
    folder, npz = tmp_path / "frames", tmp_path / "n.npz"
    for out in (str(folder) + "/", npz):
        p = cli("perturb", src, "--seed", "3", "--outliers", "0.1", "-o", out, "--report", tmp_path / "r.json")
        assert p.returncode == 0, p.stderr
    a, b = load_animation(folder), load_animation(npz)
    assert [os.path.basename(f) for f in a.frame_files] == [f"frame_{t:04d}.ply" for t in range(4)]
    assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F) and a.fields.keys() == b.fields.keys() == {"outlier"}
    assert np.array_equal(a.fields["outlier"], b.fields["outlier"])
    assert json.loads((tmp_path / "r.json").read_text())["params"]["output"] == str(npz)
    (folder / "notes.txt").write_text("kept")
    p = cli("perturb", _wave_npz(tmp_path / "short.npz", 3), "--seed", "3", "-o", folder)  # existing: no '/'
    assert p.returncode == 0, p.stderr
    assert sorted(os.listdir(folder)) == ["frame_0000.ply", "frame_0001.ply", "frame_0002.ply", "notes.txt"]
    assert load_animation(folder).n_frames == 3


@pytest.mark.parametrize("case", ["foreign mesh", "input", "no parent", "not a name", "bad frame"])
def test_a_frame_folder_that_cannot_take_the_frames_is_refused(cli, tmp_path, case):
    src = _wave_npz(tmp_path / "wave.npz", 3)
    out, wanted = str(tmp_path / "out") + "/", None
    if case == "foreign mesh":  # it would be read back as a frame
        os.mkdir(out)
        (tmp_path / "out" / "scan.obj").write_text("v 0 0 0\n")
        wanted = "holds mesh files other than frame_N.ply (scan.obj)"
    elif case == "input":
        assert cli("perturb", src, "--seed", "1", "-o", out).returncode == 0
        src, wanted = out, "is also an input"
    elif case == "no parent":
        out, wanted = str(tmp_path / "a" / "b") + "/", "does not exist"
    elif case == "not a name":
        out, wanted = str(tmp_path / "frames"), "an animation is written as .npz or as a folder of frames"
    else:  # the frames fail after the checks: no folder is made
        V, F = denoise_fixtures().wave_animation(3)
        V[1][:, 1:] = 0.0
        from geoproc.animation import Animation, animation_to_bytes

        src.write_bytes(animation_to_bytes(Animation(V, F)))
        wanted = "frame 1: degenerate mesh"
    before = sorted(os.listdir(tmp_path))
    p = cli("perturb", src, "--seed", "1", "-o", out)
    assert p.returncode == 2 and wanted in p.stderr and p.stderr.count("\n") == 1, p.stderr
    assert sorted(os.listdir(tmp_path)) == before
    if case == "foreign mesh":
        assert os.listdir(out) == ["scan.obj"]


def test_a_field_no_frame_property_can_name_is_refused_without_output(cli, tmp_path):
    V, F = denoise_fixtures().wave_animation(3)
    np.savez(tmp_path / "w.npz", vertices=V, faces=F, x=np.zeros(V.shape[:2]))
    p = cli("perturb", tmp_path / "w.npz", "--seed", "1", "-o", str(tmp_path / "out") + "/")
    assert p.returncode == 2 and "field 'x' cannot be a PLY vertex property" in p.stderr
    assert not (tmp_path / "out").exists()


def _perturb_injected(script: str, *args):
    """``geoproc perturb args`` run after ``script`` (which patches what it injects)."""
    return run_cli_under(script + "from geoproc_cli.entry import main\nmain()\n", "perturb", *args)


def test_frames_of_an_earlier_run_come_back_when_the_new_ones_cannot_go_in(cli, tmp_path):
    # an earlier run's extra frames are hidden before the renames: a failure
    # puts them back, and no new frame, folder entry or report is left
    folder = tmp_path / "frames"
    assert cli("perturb", _wave_npz(tmp_path / "long.npz", 5), "--seed", "1", "-o", str(folder) + "/").returncode == 0
    before = {f: (folder / f).read_bytes() for f in os.listdir(folder)}
    script = ("import os\n"
              "rename = os.rename\n"
              "def failing(a, b, *k, **kw):\n"
              "    if str(b).endswith('.stale') and '0004' in str(a):\n"
              "        raise PermissionError(1, 'Operation not permitted', str(a))\n"
              "    return rename(a, b, *k, **kw)\n"
              "os.rename = failing\n")
    rep = tmp_path / "r.json"
    p = _perturb_injected(script, _wave_npz(tmp_path / "short.npz", 3), "--seed", "2", "-o", folder, "--report", rep)
    wanted = "cannot remove the earlier run's frame_0004.ply: Operation not permitted"
    assert p.returncode == 2 and wanted in p.stderr, p.stderr
    assert p.stderr.count("\n") == 1 and not rep.exists()
    assert {f: (folder / f).read_bytes() for f in os.listdir(folder)} == before


def test_a_signal_while_earlier_frames_are_removed_does_not_fail_a_finished_run(tmp_path, cli):
    # the outputs are in place before the hidden earlier frames are deleted:
    # a SIGTERM then is dropped (it had given exit 143 with the new frames written)
    folder = tmp_path / "frames"
    assert cli("perturb", _wave_npz(tmp_path / "long.npz", 6), "--seed", "1", "-o", str(folder) + "/").returncode == 0
    script = ("import os, signal\n"
              "remove = os.remove\n"
              "def killing(path, *a, **k):\n"
              "    if 'frame_' in str(path):\n"
              "        os.kill(os.getpid(), signal.SIGTERM)\n"
              "    return remove(path, *a, **k)\n"
              "os.remove = killing\n")
    p = _perturb_injected(script, _wave_npz(tmp_path / "short.npz", 3), "--seed", "2", "-o", folder)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert sorted(os.listdir(folder)) == ["frame_0000.ply", "frame_0001.ply", "frame_0002.ply"]


@pytest.mark.parametrize("entry", ["link to an input frame", "pipe", "folder"])
def test_a_frame_name_in_the_folder_that_is_not_a_plain_file_is_refused(cli, tmp_path, entry):
    # frames had been written through a link (onto the input's own frames) or into a pipe (which blocked)
    frames_in = tmp_path / "in"
    assert cli("perturb", _wave_npz(tmp_path / "w.npz", 3), "--seed", "1", "-o", str(frames_in) + "/").returncode == 0
    kept = {f: (frames_in / f).read_bytes() for f in os.listdir(frames_in)}
    out = tmp_path / "out"
    out.mkdir()
    target = out / "frame_0001.ply"
    if entry == "pipe":
        os.mkfifo(target)
    elif entry == "folder":
        target.mkdir()
    else:
        target.symlink_to(frames_in / "frame_0001.ply")
    p = cli("perturb", frames_in, "--seed", "2", "-o", out)
    what = "a symbolic link" if entry.startswith("link") else "not a plain file"
    assert p.returncode == 2 and f"frame_0001.ply is {what}" in p.stderr and p.stderr.count("\n") == 1, p.stderr
    assert {f: (frames_in / f).read_bytes() for f in os.listdir(frames_in)} == kept
    assert os.listdir(out) == ["frame_0001.ply"]


def test_an_output_linked_to_an_input_frame_is_refused(cli, tmp_path):
    frames_in = tmp_path / "in"
    assert cli("perturb", _wave_npz(tmp_path / "w.npz", 3), "--seed", "1", "-o", str(frames_in) + "/").returncode == 0
    kept = (frames_in / "frame_0000.ply").read_bytes()
    (tmp_path / "lnk.npz").symlink_to(frames_in / "frame_0000.ply")
    p = cli("perturb", frames_in, "--seed", "3", "-o", tmp_path / "lnk.npz")
    assert p.returncode == 2 and "lnk.npz: is also an input" in p.stderr
    assert (frames_in / "frame_0000.ply").read_bytes() == kept


def test_a_report_in_the_frame_folder_the_run_makes(cli, tmp_path):
    out = tmp_path / "new"
    p = cli("perturb", _wave_npz(tmp_path / "w.npz", 3), "--seed", "1", "-o", str(out) + "/", "--report",
            out / "r.json")
    assert p.returncode == 0, p.stderr
    assert sorted(os.listdir(out)) == ["frame_0000.ply", "frame_0001.ply", "frame_0002.ply", "r.json"]
    assert load_animation(out).n_frames == 3


def test_frame_folder_clashes_and_missing_targets_are_named_before_the_work(cli, tmp_path):
    src = _wave_npz(tmp_path / "w.npz", 3)
    p = cli("perturb", src, "--seed", "1", "-o", str(tmp_path / "x.json") + "/", "--report", tmp_path / "x.json")
    assert p.returncode == 2 and "given for two outputs" in p.stderr and not (tmp_path / "x.json").exists()
    (tmp_path / "dl").symlink_to(tmp_path / "gone" / "x")  # a dangling link: its target's folder is missing
    p = cli("perturb", src, "--seed", "1", "-o", str(tmp_path / "dl") + "/")
    assert p.returncode == 2 and f"output folder '{tmp_path / 'gone'}' does not exist" in p.stderr, p.stderr


def test_a_npz_output_for_one_mesh_with_outliers_is_told_to_use_ply(cli, fixture_dir, tmp_path):
    # the writer's message had offered .obj, .off and .stl, which the outlier flags then refused
    p = cli("perturb", fixture_dir / "icosphere.ply", "--outliers", "0.1", "--seed", "1", "-o", tmp_path / "m.npz")
    assert p.returncode == 2 and "m.npz: .npz holds animations, and the outliers are flagged in a vertex " \
        "property, which only PLY keeps; use a .ply output" in " ".join(p.stderr.split()), p.stderr
    assert not (tmp_path / "m.npz").exists()


def test_kept_seams_are_noted_under_no_clean(cli, fixture_dir, tmp_path):
    # a vertex stored twice (a seam) moves apart under --no-clean: denoise noted it, perturb had not
    m = load_mesh(fixture_dir / "cube.ply")
    V = np.vstack([m.V, m.V[:1]])
    F = m.F.copy()
    rows = np.flatnonzero((F == 0).any(axis=1))[:2]  # two of vertex 0's faces use its copy
    F[rows] = np.where(F[rows] == 0, len(m.V), F[rows])
    src = tmp_path / "seam.obj"
    save_mesh(src, Mesh(V, F))
    note = f"note: {src}: 1 vertex the faces use repeats the position of another, and --no-clean keeps them apart"
    for args in (("perturb", src, "--noise", "0.2", "--seed", "1"), ("denoise", src)):
        p = cli(*args, "--no-clean", "-o", tmp_path / "o.ply")
        assert p.returncode == 0 and note in " ".join(p.stderr.split()), p.stderr
        p = cli(*args, "-o", tmp_path / "o.ply")
        assert p.returncode == 0 and "--no-clean keeps them apart" not in p.stderr, p.stderr
