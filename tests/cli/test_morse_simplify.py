"""``geoproc morse-simplify`` through the real command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from geoproc.mesh import Mesh, load_mesh, save_mesh
from geoproc.morse import discrete_gradient, surface_complex


def metrics(path):
    return json.loads(path.read_text())["metrics"]


def test_torus_x_known_answer_and_outputs(cli, fixture_dir, tmp_path):
    out, crit, png, rep = tmp_path / "t.ply", tmp_path / "c.json", tmp_path / "d.png", tmp_path / "r.json"
    p = cli("morse-simplify", fixture_dir / "torus.ply", "--field", "x", "--persistence", "0.1",
            "-o", out, "--critical", crit, "--diagram", png, "--report", rep, "--quiet")
    assert p.returncode == 0, p.stderr
    m = metrics(rep)
    assert (m["minima_before"], m["saddles_before"], m["maxima_before"]) == (1, 2, 1)
    assert (m["minima_after"], m["saddles_after"], m["maxima_after"]) == (1, 2, 1)
    assert m["euler_characteristic"] == 0 and (m["betti_0"], m["betti_1"], m["betti_2"]) == (1, 2, 1)
    assert m["pairs_removed"] == 0 and m["pairs_kept"] == 0 and m["threshold"] == 0.1
    mesh = load_mesh(out)
    assert {"x_value", "x_value_original"} <= set(mesh.vertex_fields)
    np.testing.assert_array_equal(mesh.vertex_fields["x_value_original"], mesh.V[:, 0])
    assert np.abs(mesh.vertex_fields["x_value"] - mesh.V[:, 0]).max() <= 0.05
    doc = json.loads(crit.read_text())
    assert [c["dimension"] for c in doc["before"]] == [0, 1, 1, 2]
    assert all(c["paired_with"] is None and c["persistence"] is None for c in doc["before"])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_diagram_shows_the_pairs_before_and_after(cli, tmp_path, make_fixtures):
    # the picture is the diagrams of the input field and of the written, simplified one
    from geoproc.morse import lower_star_persistence, surface_complex
    from geoproc.morse.diagram_plot import persistence_diagram_png

    V, F = make_fixtures.icosphere(3)
    f = V[:, 2] + 0.05 * np.random.default_rng(2).standard_normal(len(V))
    src, out, png = tmp_path / "f.ply", tmp_path / "o.ply", tmp_path / "d.png"
    save_mesh(src, Mesh(V, F, vertex_fields={"f": f}))
    p = cli("morse-simplify", src, "--field", "f", "--persistence", "0.05", "-o", out, "--diagram", png, "--quiet")
    assert p.returncode == 0, p.stderr
    g = load_mesh(out).vertex_fields["f"]
    cx = surface_complex(F, len(V))
    before, after = lower_star_persistence(cx, f), lower_star_persistence(cx, g)
    assert png.read_bytes() == persistence_diagram_png(before, after, 0.05, title="f.ply: f, P = 0.05")
    assert png.read_bytes() != persistence_diagram_png(before, before, 0.05, title="f.ply: f, P = 0.05")


def test_critical_cells_before_simplification_against_the_mesh_and_gudhi(cli, tmp_path, make_fixtures):
    # a noisy height on a sphere (78 critical cells): every "before" row is checked against the
    # input's own numbering and values, the mesh's simplices, and gudhi's lower-star pairs
    pytest.importorskip("gudhi")
    from tests.geoproc.test_morse import gudhi_diagrams

    V, F = make_fixtures.icosphere(3)
    f = V[:, 2] + 0.05 * np.random.default_rng(2).standard_normal(len(V))
    src, crit = tmp_path / "f.ply", tmp_path / "c.json"
    save_mesh(src, Mesh(V, F, vertex_fields={"f": f}))
    p = cli("morse-simplify", src, "--field", "f", "--persistence", "0.05", "-o", tmp_path / "o.ply",
            "--critical", crit, "--quiet")
    assert p.returncode == 0, p.stderr
    rows = json.loads(crit.read_text())["before"]
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    simplices = {1: set(range(len(V))), 2: set(map(tuple, E.tolist())), 3: set(map(tuple, np.sort(F, axis=1).tolist()))}
    highest = lambda s: max(s, key=lambda i: (f[i], i))  # noqa: E731  the (value, index) order
    assert len(rows) > 20
    for r in rows:
        cell = tuple(sorted(r["simplex"]))
        assert len(cell) == r["dimension"] + 1 and (cell if len(cell) > 1 else cell[0]) in simplices[len(cell)]
        assert r["vertex"] == highest(cell) and r["value"] == f[r["vertex"]]
        pw = r["paired_with"]
        if pw is not None:
            assert pw["vertex"] == highest(pw["simplex"]) and abs(pw["dimension"] - r["dimension"]) == 1
            assert r["persistence"] == pytest.approx(abs(f[pw["vertex"]] - r["value"]), abs=1e-15)
    keys = [(r["dimension"], r["value"], r["vertex"]) for r in rows]
    assert keys == sorted(keys)
    # finite pairs: minimum-saddle from the minima's rows, saddle-maximum from the maxima's
    diagrams = gudhi_diagrams(F, f)
    for dim, sign in ((0, 1), (2, -1)):
        ours = sorted((r["value"], r["value"] + r["persistence"]) if sign > 0 else
                      (r["value"] - r["persistence"], r["value"])
                      for r in rows if r["dimension"] == dim and r["paired_with"] is not None)
        d = diagrams[dim // 2]
        d = d[np.isfinite(d[:, 1]) & (d[:, 1] > d[:, 0])]
        assert len(ours) > 5
        np.testing.assert_allclose(np.array(ours).reshape(-1, 2), d[np.lexsort((d[:, 1], d[:, 0]))], atol=1e-12)


def test_chained_property_field_relative(cli, fixture_dir, tmp_path, make_fixtures):
    V, F = make_fixtures.icosphere(3)
    d = V[:, 2] + 0.1 * np.random.default_rng(2).standard_normal(len(V))
    src = tmp_path / "d.ply"
    save_mesh(src, Mesh(V, F, vertex_fields={"distance": d}))
    out, rep = tmp_path / "s.ply", tmp_path / "r.json"
    p = cli("morse-simplify", src, "--field", "distance", "--persistence", "2", "--relative",
            "-o", out, "--report", rep)
    assert p.returncode == 0, p.stderr
    m = metrics(rep)
    assert m["threshold"] == pytest.approx(2 * (d.max() - d.min()))
    assert (m["minima_after"], m["saddles_after"], m["maxima_after"]) == (1, 0, 1)
    assert m["minima_before"] > 10 and m["pairs_kept"] == 0
    assert m["pairs_removed"] == m["minima_before"] - 1 + m["maxima_before"] - 1
    mesh = load_mesh(out)
    g = mesh.vertex_fields["distance"]
    np.testing.assert_array_equal(mesh.vertex_fields["distance_original"], d)
    assert m["max_abs_change"] == pytest.approx(np.abs(g - d).max())
    assert np.abs(g - d).max() <= m["threshold"] / 2
    # independent of our persistence code: sorting g by (value, index) and
    # reading each vertex's lower link gives one minimum and one maximum
    grad = discrete_gradient(surface_complex(mesh.F, len(g)), g)
    assert (len(grad.critical_vertices), len(grad.critical_triangles)) == (1, 1)


def test_replacing_an_input_property_is_noted(cli, fixture_dir, tmp_path):
    # --field x writes x_value: an input property of that name used to vanish silently
    torus = load_mesh(fixture_dir / "torus.ply")
    src = tmp_path / "xv.ply"
    save_mesh(src, Mesh(torus.V, torus.F, {"x_value": np.zeros(len(torus.V))}))
    p = cli("morse-simplify", src, "-f", "x", "-p", "0.1", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and "note: replacing the input's vertex property 'x_value'" in p.stderr
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", "x", "-p", "0.1", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and "replacing" not in p.stderr
    # --barycentric writes 'cell_dim': an input property of that name is replaced with a note,
    # and a field of that name, which the result would have overwritten silently, is refused
    src = tmp_path / "cd.ply"
    save_mesh(src, Mesh(torus.V, torus.F, {"cell_dim": torus.V[:, 2]}))
    out = tmp_path / "b.ply"
    p = cli("morse-simplify", src, "-f", "x", "-p", "0.1", "--barycentric", "-o", out)
    assert p.returncode == 0 and "note: replacing the input's vertex property 'cell_dim'" in p.stderr
    p = cli("morse-simplify", src, "-f", "cell_dim", "-p", "0.1", "--barycentric", "-o", tmp_path / "c.ply")
    assert p.returncode == 2 and "--field cell_dim with --barycentric" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and not (tmp_path / "c.ply").exists()


def test_npy_field_and_curvature(cli, fixture_dir, tmp_path):
    mesh = load_mesh(fixture_dir / "icosphere.ply")
    vals = np.random.default_rng(3).standard_normal(len(mesh.V))
    npy = tmp_path / "noise.npy"
    np.save(npy, vals)
    rep = tmp_path / "r.json"
    p = cli("morse-simplify", fixture_dir / "icosphere.ply", "--field", npy, "--persistence", "0.5",
            "--relative", "-o", tmp_path / "n.ply", "--report", rep, "--check", "minima_after==1")
    assert p.returncode == 0, p.stderr
    assert "noise" in load_mesh(tmp_path / "n.ply").vertex_fields
    p = cli("morse-simplify", fixture_dir / "torus.ply", "--field", "gaussian-curvature",
            "--persistence", "0.05", "--relative", "-o", tmp_path / "k.ply", "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    m = metrics(rep)
    assert m["minima_after"] - m["saddles_after"] + m["maxima_after"] == 0


def test_a_stored_property_named_as_a_curvature_is_read(cli, fixture_dir, tmp_path):
    # a property 'mean-curvature' (another tool's) had been shadowed by libigl's curvature, without a word
    mesh = load_mesh(fixture_dir / "icosphere.ply")
    save_mesh(tmp_path / "c.ply", Mesh(mesh.V, mesh.F, {"mean-curvature": mesh.V[:, 1].copy()}))
    p = cli("morse-simplify", tmp_path / "c.ply", "-f", "mean-curvature", "-p", "0", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and "--field mean-curvature: read from the input's vertex property" in p.stderr
    out = load_mesh(tmp_path / "o.ply").vertex_fields
    assert sorted(out) == ["mean-curvature", "mean-curvature_original"]
    np.testing.assert_array_equal(out["mean-curvature_original"], mesh.V[:, 1])
    # without the property: libigl's, under its own name, no note
    p = cli("morse-simplify", fixture_dir / "icosphere.ply", "-f", "mean-curvature", "-p", "0",
            "-o", tmp_path / "k.ply")
    assert p.returncode == 0 and "note" not in p.stderr, p.stderr
    assert load_mesh(tmp_path / "k.ply").vertex_fields["mean_curvature_original"].mean() > 0.5


def test_pairs_of_exactly_the_threshold_count_as_kept(cli, fixture_dir, tmp_path):
    # an integer field: pairs of persistence exactly P stay, and the counts add up
    pytest.importorskip("gudhi")
    from tests.geoproc.test_morse import gudhi_diagrams

    mesh = load_mesh(fixture_dir / "icosphere.ply")
    vals = np.random.default_rng(3).integers(0, 12, len(mesh.V)).astype(np.float64)
    np.save(tmp_path / "k.npy", vals)
    pers = np.concatenate([d[np.isfinite(d[:, 1]), 1] - d[np.isfinite(d[:, 1]), 0]
                           for d in gudhi_diagrams(mesh.F, vals)[:2]])
    pers = pers[pers > 0]
    assert (pers == 3.0).sum() >= 3
    rep = tmp_path / "r.json"
    p = cli("morse-simplify", fixture_dir / "icosphere.ply", "--field", tmp_path / "k.npy", "--persistence", "3",
            "-o", tmp_path / "k.ply", "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    m = metrics(rep)
    # removed also counts the pairs of zero persistence that ties make (gudhi lists none)
    assert m["pairs_kept"] == (pers >= 3.0).sum() and m["pairs_removed"] >= (pers < 3.0).sum()


@pytest.mark.parametrize("name,needle", [("bowtie.obj", "vertex"), ("fin.obj", "edge")])
def test_non_manifold_refused(cli, fixture_dir, tmp_path, name, needle):
    out = tmp_path / "o.ply"
    p = cli("morse-simplify", fixture_dir / name, "--field", "z", "--persistence", "0.1", "-o", out)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "non-manifold" in lines[0]
    assert f"first: {needle}" in lines[0]
    hint = " (--split-nonmanifold gives each fan of faces at a vertex its own vertex)" if needle == "vertex" else ""
    assert lines[0].endswith("; morse-simplify needs a manifold mesh" + hint)
    assert not out.exists()
    if needle == "edge":  # splitting vertices does not mend an edge with three faces
        p = cli("morse-simplify", fixture_dir / name, "--field", "z", "--persistence", "0.1", "-o", out,
                "--split-nonmanifold")
        assert p.returncode == 2 and "edges have more than two faces" in p.stderr and not out.exists()


def test_split_nonmanifold_gives_each_fan_its_vertex(cli, fixture_dir, tmp_path, make_fixtures):
    # the bowtie's two triangles become two discs; fields follow input_vertex
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("morse-simplify", fixture_dir / "bowtie.obj", "--field", "x", "--persistence", "0", "-o", out,
            "--split-nonmanifold", "--report", rep)
    assert p.returncode == 0, p.stderr
    assert "split 1 non-manifold vertex into 2" in p.stderr
    m = load_mesh(out, clean=False)
    assert np.array_equal(m.vertex_fields["input_vertex"], [0, 1, 2, 3, 4, 0])
    assert m.vertex_fields["input_vertex"].dtype.kind == "i"
    np.testing.assert_array_equal(m.vertex_fields["x_value_original"], m.V[:, 0])
    r = json.loads(rep.read_text())
    assert r["params"]["split_nonmanifold"] is True
    assert (r["metrics"]["betti_0"], r["metrics"]["euler_characteristic"]) == (2, 2)
    # two spheres touching at a vertex: each copy gets the curvature of one sphere there
    # (libigl's on the single sphere; the unsplit vertex would have summed both fans' angles)
    import igl

    V, F = make_fixtures.icosphere(2)
    n = len(V)
    mirrored = V - 2 * (V @ V[0] - 1)[:, None] * V[0]  # through the plane touching the sphere at vertex 0
    two = Mesh(np.concatenate([V, mirrored]),
               np.concatenate([F, np.where(F == 0, 0, F + n)[:, ::-1]]))
    src = tmp_path / "two.ply"
    save_mesh(src, two)
    p = cli("morse-simplify", src, "--field", "gaussian-curvature", "--persistence", "0", "-o", out,
            "--split-nonmanifold", "--quiet")
    assert p.returncode == 0, p.stderr
    m = load_mesh(out, clean=False)
    k = m.vertex_fields["gaussian_curvature_original"]
    K = igl.gaussian_curvature(V, F) / igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI).diagonal()
    copies = np.flatnonzero(m.vertex_fields["input_vertex"] == 0)
    assert len(copies) == 2
    np.testing.assert_allclose(k[copies], K[0], rtol=1e-9)
    p = cli("morse-simplify", fixture_dir / "torus.ply", "--field", "x", "--persistence", "0", "-o", out,
            "--split-nonmanifold")
    assert p.returncode == 0 and "--split-nonmanifold changed nothing and adds no input_vertex" in p.stderr
    assert "input_vertex" not in load_mesh(out).vertex_fields
    # on the barycentric subdivision only the mesh's own vertices have an input vertex
    p = cli("morse-simplify", fixture_dir / "bowtie.obj", "--field", "x", "--persistence", "0", "-o", out,
            "--split-nonmanifold", "--barycentric", "--report", rep)
    assert p.returncode == 0, p.stderr
    m = load_mesh(out, clean=False)
    dim, iv = m.vertex_fields["cell_dim"], m.vertex_fields["input_vertex"]
    assert np.array_equal(iv[dim == 0], [0, 1, 2, 3, 4, 0]) and (iv[dim > 0] == -1).all()
    assert json.loads(rep.read_text())["metrics"]["vertices"] == 5  # the input's, as loaded
    # an input_vertex the input carries (from an earlier run) is replaced, with a note
    bow = load_mesh(fixture_dir / "bowtie.obj")
    again, src = tmp_path / "again.ply", tmp_path / "bow.ply"
    save_mesh(src, Mesh(bow.V, bow.F, vertex_fields={"input_vertex": np.full(len(bow.V), 9, dtype=np.int32)}))
    p = cli("morse-simplify", src, "--field", "x", "--persistence", "0", "-o", again, "--split-nonmanifold")
    assert p.returncode == 0 and "replacing the input's vertex property 'input_vertex'" in p.stderr
    assert np.array_equal(load_mesh(again, clean=False).vertex_fields["input_vertex"], [0, 1, 2, 3, 4, 0])
    # a map carried from an earlier split is -1 on the subdivision's new vertices too
    p = cli("morse-simplify", again, "--no-clean", "--field", "x", "--persistence", "0", "--barycentric", "-o", out)
    assert p.returncode == 0, p.stderr
    m = load_mesh(out, clean=False)
    dim, iv = m.vertex_fields["cell_dim"], m.vertex_fields["input_vertex"]
    assert np.array_equal(iv[dim == 0], [0, 1, 2, 3, 4, 0]) and (iv[dim > 0] == -1).all()
    # the map cannot be the field simplified in the same run
    p = cli("morse-simplify", src, "--field", "input_vertex", "--persistence", "0", "--split-nonmanifold", "-o",
            tmp_path / "iv.ply")
    assert p.returncode == 2 and "--field input_vertex with --split-nonmanifold" in p.stderr
    assert not (tmp_path / "iv.ply").exists()


def test_bad_fields_and_threshold(cli, fixture_dir, tmp_path):
    ico = fixture_dir / "icosphere.ply"
    n = len(load_mesh(ico).V)
    short, nan = tmp_path / "short.npy", tmp_path / "nan.npy"
    np.save(short, np.zeros(n - 1))
    v = np.zeros(n)
    v[7] = np.nan
    np.save(nan, v)
    cplx, wide = tmp_path / "cplx.npy", tmp_path / "wide.npy"
    np.save(cplx, np.zeros(n) + 1j)
    np.save(wide, np.where(np.arange(n) % 2, 1e308, -1e308))  # max - min overflows
    empty, near = tmp_path / "empty.npy", tmp_path / "near.npy"
    empty.write_bytes(b"")
    np.save(near, np.where(np.arange(n) % 2, 8.9e307, -8.9e307))  # its range fits, twice it does not
    big, text = tmp_path / "big.npy", tmp_path / "text.npy"
    np.save(big, 2**60 + np.arange(n, dtype=np.int64))  # doubles 256 apart there: read as a few distinct values
    text.write_text("0 1 2\n")  # np.load took it for a pickle and asked for allow_pickle
    out = tmp_path / "o.ply"
    cases = [
        (["--field", big, "--persistence", "1"], f"big.npy: field 'big' has integers beyond 2^53, where doubles "
                                                 f"cannot tell them apart: its {n} distinct values become"),
        (["--field", text, "--persistence", "1"], "text.npy: cannot read field: not a NumPy .npy file"),
        (["--field", short, "--persistence", "1"], f"{n - 1} values for {n} vertices"),
        (["--field", nan, "--persistence", "1"], "non-finite"),
        (["--field", cplx, "--persistence", "1"], "cplx.npy: field 'cplx' must hold real numbers"),
        (["--field", wide, "--persistence", "0.1", "--relative"], "wide.npy: field 'wide' spans more than"),
        (["--field", "z", "--persistence", "1", "--diagram", tmp_path / "d.jpg"], "d.jpg: must end in .png (or be -)"),
        (["--field", empty, "--persistence", "1"], "empty.npy: cannot read field"),
        (["--field", "z", "--persistence", "0.1", "--barycentric", "--exact-windows", "2"], "--exact-windows: not"),
        (["--field", near, "--persistence", "2", "--relative"], "overflows; use a smaller P"),
        (["--field", "z", "--persistence", "-0.5"], "--persistence"),
        (["--field", "nope", "--persistence", "1"], "no vertex property 'nope'"),
    ]
    for args, needle in cases:
        p = cli("morse-simplify", ico, *args, "-o", out)
        assert p.returncode == 2, (args, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0], (args, p.stderr)
        assert not out.exists()
    p = cli("morse-simplify", ico, "--field", "z", "--persistence", "1", "-o", tmp_path / "o.obj")
    assert p.returncode == 2 and ".ply" in p.stderr
    np.save(big, 2**60 * (np.arange(n, dtype=np.int64) % 3))  # beyond 2^53 but exact as doubles: read
    assert cli("morse-simplify", ico, "--field", big, "--persistence", "1", "-o", out).returncode == 0


def test_npy_with_one_value_per_stored_vertex_names_the_clean_up(cli, fixture_dir, tmp_path):
    # the icosphere with one vertex no face uses: loading drops it, and a field saved for
    # the file's vertices had been refused as '43 values for 42 vertices', without a why
    m = load_mesh(fixture_dir / "icosphere.ply")
    V = np.vstack([m.V, [[5.0, 5.0, 5.0]]])
    mesh = tmp_path / "extra.off"
    mesh.write_text(f"OFF\n{len(V)} {len(m.F)} 0\n" + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
                    + "".join(f"3 {a} {b} {c}\n" for a, b, c in m.F.tolist()))
    npy = tmp_path / "f.npy"
    np.save(npy, np.r_[m.V[:, 2], 0.0])
    p = cli("morse-simplify", mesh, "--field", npy, "--persistence", "0.1", "-o", tmp_path / "o.ply")
    assert p.returncode == 2 and not (tmp_path / "o.ply").exists()
    assert p.stderr.strip() == (f"error: {npy}: field has {len(V)} values, one per vertex stored in extra.off, "
                                f"but loading merged 0 and dropped 1 unreferenced, leaving {len(m.V)}; pass "
                                "--no-clean to keep every stored vertex")
    p = cli("morse-simplify", mesh, "--field", npy, "--persistence", "0.1", "--no-clean", "-o", tmp_path / "o.ply")
    assert p.returncode == 0, p.stderr


def test_notes_on_a_constant_relative_field_and_a_non_orientable_mean_curvature(cli, fixture_dir, tmp_path):
    # both had run without a word: P came out 0 and nothing was simplified; the sign of the
    # mean curvature flipped across the strip's seam (-1.41 next to +0.08)
    p = cli("morse-simplify", fixture_dir / "grid.ply", "--field", "z", "--persistence", "0.1", "--relative",
            "-o", tmp_path / "g.ply")
    assert p.returncode == 0 and "grid.ply: the field is constant on the surface, so --relative makes P 0" in p.stderr
    n, w = 48, 0.3
    t = 2 * np.pi * np.arange(n) / n
    V = np.empty((2 * n, 3))
    for k, s in enumerate((-w, w)):  # a Moebius strip: vertex 2i + k at angle t_i, offset s
        V[k::2] = np.column_stack([(1 + s * np.cos(t / 2)) * np.cos(t), (1 + s * np.cos(t / 2)) * np.sin(t),
                                   s * np.sin(t / 2)])
    a, b = 2 * np.arange(n), 2 * np.arange(n) + 1
    F = [f for i in range(n - 1) for f in ([a[i], a[i + 1], b[i + 1]], [a[i], b[i + 1], b[i]])]
    F += [[a[-1], b[0], a[0]], [a[-1], a[0], b[-1]]]  # the half twist closes it
    strip = tmp_path / "strip.ply"
    save_mesh(strip, Mesh(V, np.array(F)))
    note = "strip.ply: the surface is not orientable, so the mean curvature's sign flips across a seam"
    p = cli("morse-simplify", strip, "--field", "mean-curvature", "--persistence", "0.1", "-o", tmp_path / "s.ply")
    assert p.returncode == 0 and note in p.stderr
    p = cli("morse-simplify", strip, "--field", "gaussian-curvature", "--persistence", "0.1", "-o", tmp_path / "s.ply")
    assert p.returncode == 0 and "not orientable" not in p.stderr


@pytest.mark.parametrize("barycentric", [False, True])
def test_a_vertex_no_face_uses_is_no_part_of_the_topology(cli, fixture_dir, tmp_path, barycentric):
    # kept under --no-clean, it had been a component and an essential minimum of its own:
    # minima_after, betti_0 and euler_characteristic disagreed with info's for the same file
    m = load_mesh(fixture_dir / "icosphere.ply")
    V = np.vstack([[[5.0, 5.0, -9.0]], m.V])  # numbered first, below every surface value
    mesh = tmp_path / "extra.off"
    mesh.write_text(f"OFF\n{len(V)} {len(m.F)} 0\n" + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
                    + "".join(f"3 {a + 1} {b + 1} {c + 1}\n" for a, b, c in m.F.tolist()))
    extra = ["--barycentric"] if barycentric else []
    runs = {}
    for name, src, clean in (("plain", fixture_dir / "icosphere.ply", []), ("extra", mesh, ["--no-clean"])):
        out, rep, crit = tmp_path / f"{name}.ply", tmp_path / f"{name}.json", tmp_path / f"{name}_c.json"
        p = cli("morse-simplify", src, "--field", "z", "--persistence", "0.5", "--relative", *clean, *extra,
                "-o", out, "--report", rep, "--critical", crit)
        assert p.returncode == 0, p.stderr
        runs[name] = (json.loads(rep.read_text())["metrics"], json.loads(crit.read_text()), load_mesh(out, clean=False),
                      p.stderr)
    (mp, cp, op, _), (me, ce, oe, err) = runs["plain"], runs["extra"]
    counts = ("vertices", "input_vertices")
    assert {k: v for k, v in me.items() if k not in counts} == {k: v for k, v in mp.items() if k not in counts}
    assert (me["vertices"], mp["vertices"], me["betti_0"], me["euler_characteristic"]) == (643, 642, 1, 2)
    if barycentric:  # the subdivision is of the surface, numbered as the plain run's
        assert ce == cp and np.array_equal(oe.V, op.V)
        assert "1 vertices no face uses are left out of the subdivision" in err
    else:  # the stray vertex keeps its value; the critical cells name the input's vertices
        assert np.array_equal(oe.vertex_fields["z_value"], np.r_[-9.0, op.vertex_fields["z_value"]])
        assert [r["vertex"] for r in ce["before"]] == [r["vertex"] + 1 for r in cp["before"]]


@pytest.mark.parametrize("name", ["camelhead.off", "fertility.off", "cow.obj", "teapot.obj"])
def test_shared_meshes(cli, shared_data, tmp_path, name):
    out, rep = tmp_path / "o.ply", tmp_path / "r.json"
    p = cli("morse-simplify", shared_data / "meshes" / name, "--field", "y", "--persistence", "0.05",
            "--relative", "-o", out, "--report", rep, "-q")
    if name in ("cow.obj", "teapot.obj"):  # not manifolds: refused, naming the vertex
        assert p.returncode == 2 and "non-manifold" in p.stderr and not out.exists()
        return
    assert p.returncode == 0, p.stderr
    m = metrics(rep)
    chi = m["euler_characteristic"]
    assert m["minima_after"] - m["saddles_after"] + m["maxima_after"] == chi
    assert m["minima_before"] - m["saddles_before"] + m["maxima_before"] == chi
    assert chi == {"camelhead.off": 1, "fertility.off": -6}[name]


def test_exact_windows_option(cli, shared_data, tmp_path):
    # camelhead, height + 2% noise, P = 5% of the range: the default (4 windows) leaves
    # five vertices beyond P/2 (0.556 P), every window (-1) one (6 and 0 when the canonical
    # face order kept the winding); -2 is refused
    from tests.conftest import load_fixture_module

    name = shared_data / "meshes" / "camelhead.off"
    field = tmp_path / "f.npy"
    np.save(field, load_fixture_module("morse_fixtures").noisy_height(load_mesh(name).V, axis=1, noise=0.02,
                                                                       seed=10))
    seen = {}
    for windows in ("4", "-1"):
        out, rep = tmp_path / f"o{windows}.ply", tmp_path / f"r{windows}.json"
        p = cli("morse-simplify", name, "--field", field, "--persistence", "0.05", "--relative",
                "--exact-windows", windows, "-o", out, "--report", rep, "-q")
        assert p.returncode == 0, p.stderr
        m = metrics(rep)
        seen[windows] = (m["vertices_beyond_half_threshold"], m["max_abs_change"] / m["threshold"])
    assert seen["4"][0] == 5 and seen["-1"][0] == 1  # measured
    assert 0.5 < seen["-1"][1] <= seen["4"][1] < 0.56
    p = cli("morse-simplify", name, "--field", "y", "--persistence", "1", "--exact-windows", "-2",
            "-o", tmp_path / "bad.ply")
    assert p.returncode == 2 and "--exact-windows" in p.stderr and not (tmp_path / "bad.ply").exists()


def test_a_ply_on_stdout_carries_nothing_the_window_solver_prints(cli, shared_data, tmp_path):
    # noisy fandisk, z, P = 5 %: HiGHS's MIP solver in the exact windows printed
    # "HighsMipSolverData::..." debug lines on C stdout, ahead of the binary PLY
    noisy = tmp_path / "n.ply"
    p = cli("perturb", shared_data / "meshes" / "fandisk.off", "--noise", "0.3", "--seed", "1", "-o", noisy)
    assert p.returncode == 0, p.stderr
    out = tmp_path / "o.ply"
    args = ("morse-simplify", noisy, "-f", "z", "-p", "0.05", "--relative", "-q")
    p = cli(*args, "-o", "-")
    assert p.returncode == 0, p.stderr
    assert cli(*args, "-o", out).returncode == 0
    assert p.stdout == out.read_bytes()


def test_barycentric_reaches_half_threshold_and_chains(cli, shared_data, tmp_path):
    # bunny, height + 2% noise, P = 1% of the range: no vertex function on the mesh
    # stays within P/2 (certified 0.802 P in test_morse_bound); on the subdivision g does
    from tests.conftest import load_fixture_module

    name = shared_data / "meshes" / "bunny.off"
    mesh = load_mesh(name)
    f = load_fixture_module("morse_fixtures").noisy_height(mesh.V, axis=1, noise=0.02, seed=10)
    src = tmp_path / "f.ply"
    save_mesh(src, Mesh(mesh.V, mesh.F, vertex_fields={"h": f, "u": mesh.V[:, 0]},
                        face_fields={"part": np.arange(len(mesh.F), dtype=np.float64)}))
    out, rep, crit = tmp_path / "o.ply", tmp_path / "r.json", tmp_path / "c.json"
    p = cli("morse-simplify", src, "--field", "h", "--persistence", "0.01", "--relative", "--barycentric",
            "-o", out, "--report", rep, "--critical", crit, "-q")
    assert p.returncode == 0, p.stderr
    m = metrics(rep)
    sd = load_mesh(out)
    n, faces = len(mesh.V), len(mesh.F)
    edges = n + faces - m["euler_characteristic"]
    assert len(sd.V) == m["subdivision_vertices"] == n + edges + faces and len(sd.F) == 6 * faces
    dim = sd.vertex_fields["cell_dim"]
    assert np.bincount(dim.astype(int)).tolist() == [n, edges, faces]
    np.testing.assert_allclose(sd.vertex_fields["h_original"][:n], f)
    np.testing.assert_allclose(sd.vertex_fields["u"], sd.V[:, 0], atol=1e-12)  # other fields interpolated
    assert np.array_equal(sd.face_fields["part"], np.repeat(np.arange(faces), 6))  # six per input triangle
    g, fe = sd.vertex_fields["h"], sd.vertex_fields["h_original"]
    assert m["vertices_beyond_half_threshold"] == 0
    assert np.abs(g - fe).max() <= m["threshold"] / 2 * (1 + 1e-12)
    assert m["minima_after"] - m["saddles_after"] + m["maxima_after"] == m["euler_characteristic"]
    assert m["minima_after"] + m["saddles_after"] + m["maxima_after"] == 2 * m["pairs_kept"] + 2
    # the minima of g on the subdivision, found from the output file alone
    grad = discrete_gradient(surface_complex(sd.F, len(g)), g)
    assert len(grad.critical_vertices) == m["minima_after"] and (dim[grad.critical_vertices] == 0).all()
    after = json.loads(crit.read_text())["after"]
    assert len(after) == 2 * m["pairs_kept"] + 2
    for row in after:  # the mesh cell behind each critical subdivision vertex, at its barycentre
        cell = row["mesh_cell"]
        assert cell["dimension"] == dim[row["vertex"]] and len(cell["vertices"]) == cell["dimension"] + 1
        np.testing.assert_allclose(sd.V[row["vertex"]], mesh.V[cell["vertices"]].mean(axis=0), atol=1e-9)
    for d in (0, 1, 2):  # minima at mesh vertices, saddles at edge midpoints, maxima at triangle centres
        assert {row["mesh_cell"]["dimension"] for row in after if row["dimension"] == d} == {d}
    # the output chains: the subdivided field is a valid input
    p = cli("morse-simplify", out, "--field", "h", "--persistence", "0.01", "--relative", "-o",
            tmp_path / "again.ply", "--report", tmp_path / "r2.json", "-q")
    assert p.returncode == 0, p.stderr
    m2 = metrics(tmp_path / "r2.json")
    for kind in ("minima", "saddles", "maxima"):
        assert m2[f"{kind}_before"] == m[f"{kind}_after"]


def test_npy_named_like_a_coordinate(cli, fixture_dir, tmp_path):
    # x.npy was written under 'x', the coordinate: exit 3 from the PLY writer
    n = len(load_mesh(fixture_dir / "torus.ply").V)
    field = tmp_path / "x.npy"
    np.save(field, np.random.default_rng(0).random(n))
    out = tmp_path / "o.ply"
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", field, "-p", "0.1", "-o", out)
    assert p.returncode == 0, p.stderr
    assert {"x_value", "x_value_original"} <= set(load_mesh(out).vertex_fields)
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", tmp_path / "missing.npy", "-p", "0.1", "-o", out)
    assert p.returncode == 2 and "missing.npy: no such file" in p.stderr


def test_rounding_past_half_threshold_is_not_counted(cli, make_fixtures, tmp_path):
    # Gaussian curvature of an icosphere: few distinct values, many ties; 60 vertices
    # moved past P/2 by at most 17 units in the last place, which were counted
    V, F = make_fixtures.icosphere(3)
    src, out, rep = tmp_path / "s.ply", tmp_path / "o.ply", tmp_path / "r.json"
    save_mesh(src, Mesh(V, F))
    p = cli("morse-simplify", src, "-f", "gaussian-curvature", "-p", "0.05", "--relative", "-o", out,
            "--report", rep, "--check", "vertices_beyond_half_threshold==0", "-q")
    assert p.returncode == 0, p.stderr
    m = load_mesh(out)
    f, g = m.vertex_fields["gaussian_curvature_original"], m.vertex_fields["gaussian_curvature"]
    past = np.abs(g - f) - metrics(rep)["threshold"] / 2
    assert past.max() <= 64 * np.finfo(np.float64).eps * np.abs(f).max()


def test_tie_breaking_past_half_threshold_is_not_counted(cli, fixture_dir, tmp_path):
    # a field with plateaus (height + noise rounded to 0.1): breaking the ties of a plateau
    # raises its vertices by one unit in the last place each, up to ~450 units beyond P/2;
    # 393 such vertices were counted beyond P/2 (the 64-unit allowance is for rounding)
    import igl

    mesh = load_mesh(fixture_dir / "torus.ply")
    V, F = igl.loop(*igl.loop(mesh.V, mesh.F))
    y = (V[:, 1] - V[:, 1].min()) / np.ptp(V[:, 1])
    f = np.round(y + 0.05 * np.random.default_rng(0).standard_normal(len(V)), 1)
    src, npy, out, rep = tmp_path / "t.ply", tmp_path / "plateau.npy", tmp_path / "o.ply", tmp_path / "r.json"
    save_mesh(src, Mesh(V, F))
    np.save(npy, f)
    p = cli("morse-simplify", src, "-f", npy, "-p", "0.1", "-o", out, "--report", rep,
            "--check", "vertices_beyond_half_threshold==0", "-q")
    assert p.returncode == 0, p.stderr
    g = load_mesh(out).vertex_fields["plateau"]
    past = np.abs(g - f) - 0.05
    assert 64 * np.finfo(np.float64).eps < past.max() < 1e-12  # beyond 64 units, yet only tie-breaking


def test_long_double_field_beyond_float64_is_one_line(cli, fixture_dir, tmp_path):
    # finite long doubles past 1.8e308 printed numpy's overflow warning and its source line,
    # then called the values non-finite
    n = len(load_mesh(fixture_dir / "torus.ply").V)
    field = tmp_path / "ld.npy"
    values = np.ones(n, dtype=np.longdouble)
    if np.finfo(np.longdouble).max <= np.finfo(np.float64).max:
        pytest.skip("long double is float64 on this platform")
    values[5] = np.longdouble(10) ** 400
    np.save(field, values)
    out = tmp_path / "o.ply"
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", field, "-p", "0.1", "-o", out)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert "field 'ld' has 1 values beyond the float64 range (first: vertex 5)" in p.stderr and not out.exists()


@pytest.mark.parametrize("barycentric", [False, True])
def test_a_field_too_coarse_for_its_values_counts_the_moves_past_half(cli, make_fixtures, tmp_path, barycentric):
    # a field of range ~2 offset by 1e15: its range holds ~16 doubles for 642 (or 3842) values, and
    # breaking g's ties moved them by many units of P; those moves had been excused as tie-breaking
    # whatever their size (vertices_beyond_half_threshold 0, no note, bunny: 20,027 of 20,900 beyond)
    V, F = make_fixtures.icosphere(3)
    src, field = tmp_path / "s.ply", tmp_path / "f.npy"
    save_mesh(src, Mesh(V, F))
    np.save(field, 1e15 + V[:, 2])
    rep = tmp_path / "r.json"
    extra = ["--barycentric"] if barycentric else []
    p = cli("morse-simplify", src, "-f", field, "-p", "0.1", "--relative", *extra, "-o", tmp_path / "o.ply",
            "--report", rep)
    assert p.returncode == 0, p.stderr
    met = json.loads(rep.read_text())["metrics"]
    g, f = (load_mesh(tmp_path / "o.ply").vertex_fields[k] for k in ("f", "f_original"))
    assert met["max_abs_change"] > met["threshold"]
    assert met["vertices_beyond_half_threshold"] > len(g) / 4
    assert met["vertices_beyond_half_threshold"] <= int((np.abs(g - f) > met["threshold"] / 2).sum())
    assert "subtract a constant from the field" in p.stderr


def test_negative_zero_persistence_is_reported_as_zero(cli, fixture_dir, tmp_path):
    # -p -0 is P = 0; the report had carried "threshold": -0.0
    rep = tmp_path / "r.json"
    p = cli("morse-simplify", fixture_dir / "torus.ply", "-f", "z", "-p", "-0", "-o", tmp_path / "t.ply",
            "--report", rep)
    assert p.returncode == 0, p.stderr
    r = json.loads(rep.read_text())
    assert math.copysign(1.0, r["metrics"]["threshold"]) == math.copysign(1.0, r["params"]["persistence"]) == 1.0


def test_a_relative_persistence_past_the_range_is_noted(cli, fixture_dir, tmp_path):
    # -p 5 --relative (five times the range) had been taken without a word
    p = cli("morse-simplify", fixture_dir / "icosphere.ply", "-f", "z", "-p", "5", "--relative", "-o",
            tmp_path / "o.ply", "--report", tmp_path / "r.json")
    assert p.returncode == 0 and "is more than the field's whole range: every critical pair is removed" in p.stderr
    m = json.loads((tmp_path / "r.json").read_text())["metrics"]
    assert m["pairs_kept"] == 0 and (m["minima_after"], m["saddles_after"], m["maxima_after"]) == (1, 0, 1)
    p = cli("morse-simplify", fixture_dir / "icosphere.ply", "-f", "z", "-p", "1", "--relative", "-o",
            tmp_path / "o.ply")
    assert p.returncode == 0 and "whole range" not in p.stderr


def test_faces_collapsed_by_merging_are_named_with_the_way_out(cli, tmp_path):
    import trimesh

    ico = trimesh.creation.icosphere(2)
    V = ico.vertices.copy()
    V[ico.faces[0, 1]] = V[ico.faces[0, 0]]  # two vertices at one position: a valid mesh as stored
    path, out = tmp_path / "collapse.ply", tmp_path / "o.ply"
    save_mesh(path, Mesh(V, ico.faces))
    p = cli("morse-simplify", path, "-f", "z", "-p", "0.1", "-o", out)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and not out.exists()
    assert p.stderr.startswith(f"error: {path}: 2 faces repeat a vertex (first: face 0, vertices ")
    assert ("; merging coincident positions on loading made all of them (--no-clean keeps the stored vertices); "
            "morse-simplify needs a manifold mesh") in p.stderr
    p = cli("morse-simplify", path, "-f", "z", "-p", "0.1", "-o", out, "--no-clean", "-q")
    assert p.returncode == 0, p.stderr
    assert len(load_mesh(out, clean=False).V) == len(V)


def test_a_normal_component_as_the_field_with_barycentric_notes_the_others(cli, fixture_dir, tmp_path):
    # -f nx --barycentric keeps nx as the field and interpolates ny, nz: they had gone without a word
    import igl

    m = load_mesh(fixture_dir / "icosphere.ply")
    N = igl.per_vertex_normals(m.V, m.F)
    src = tmp_path / "n.ply"
    save_mesh(src, Mesh(m.V, m.F, {"nx": N[:, 0].copy(), "ny": N[:, 1].copy(), "nz": N[:, 2].copy()}))
    p = cli("morse-simplify", src, "-f", "nx", "-p", "0.1", "--relative", "--barycentric", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and ("--field nx with --barycentric: the other normal components (ny, nz) are "
                                  "interpolated on the subdivision") in " ".join(p.stderr.split()), p.stderr
    p = cli("morse-simplify", src, "-f", "z", "-p", "0.1", "--relative", "--barycentric", "-o", tmp_path / "o.ply")
    assert p.returncode == 0 and "other normal components" not in p.stderr
