"""Reading, writing, clean-up and validation of meshes."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import trimesh

from geoproc.errors import InputError
from geoproc.fileio import write_files_atomic
from geoproc.mesh import Mesh, load_mesh, mesh_to_bytes, read_mesh_bytes, save_mesh
from geoproc.mesh.clean import merge_coincident_vertices, remove_unreferenced_vertices, unique_rows
from geoproc.mesh.read import sniff_format


@pytest.fixture()
def sphere(make_fixtures):
    V, F = make_fixtures.icosphere(2)
    rng = np.random.default_rng(0)
    fields = {"distance": rng.random(len(V)), "label": np.arange(len(V), dtype=float)}
    return Mesh(V, F, fields, {"area": rng.random(len(F))})


@pytest.mark.parametrize("binary", [True, False])
def test_ply_fields_round_trip_exactly(tmp_path, sphere, binary):
    path = tmp_path / "s.ply"
    save_mesh(path, sphere, binary=binary)
    back = load_mesh(path)
    assert np.array_equal(back.V, sphere.V) and np.array_equal(back.F, sphere.F)
    assert set(back.vertex_fields) == {"distance", "label"}
    for k, v in sphere.vertex_fields.items():
        assert np.array_equal(back.vertex_fields[k], v), k
    assert np.array_equal(back.face_fields["area"], sphere.face_fields["area"])


def test_ply_vector_field_is_split_into_components(tmp_path, sphere):
    sphere.vertex_fields = {"normal": np.tile([0.0, 0.0, 1.0], (len(sphere.V), 1))}
    save_mesh(tmp_path / "n.ply", sphere)
    back = load_mesh(tmp_path / "n.ply")
    assert sorted(back.vertex_fields) == ["normal_0", "normal_1", "normal_2"]
    assert np.all(back.vertex_fields["normal_2"] == 1.0)


@pytest.mark.parametrize("ext", ["obj", "off", "stl"])
def test_geometry_round_trip_other_formats(tmp_path, sphere, ext):
    save_mesh(tmp_path / f"s.{ext}", sphere)
    back = load_mesh(tmp_path / f"s.{ext}")
    assert back.F.shape == sphere.F.shape
    tol = 1e-6 if ext == "stl" else 0.0  # STL stores float32
    # compare as sets of triangles (STL merging may renumber vertices)
    assert np.abs(np.sort(back.V[back.F].reshape(-1, 9), axis=0)
                  - np.sort(sphere.V[sphere.F].reshape(-1, 9), axis=0)).max() <= tol


def test_trimesh_reads_our_ply(tmp_path, sphere):
    save_mesh(tmp_path / "s.ply", sphere)
    tm = trimesh.load(tmp_path / "s.ply", process=False)
    assert np.allclose(tm.vertices, sphere.V) and np.array_equal(tm.faces, sphere.F)


def test_ply_without_faces_is_a_point_cloud(fixture_dir):
    m = load_mesh(fixture_dir / "points.ply")
    assert m.is_point_cloud and m.V.shape == (200, 3)


def test_obj_uv_seams_do_not_split_vertices(shared_data):
    spot = shared_data / "meshes" / "spot.obj"
    stored = sum(1 for line in spot.read_text().splitlines() if line.startswith("v "))
    cleaned, kept = load_mesh(spot), load_mesh(spot, clean=False)
    assert stored == 2930 and len(kept.V) == len(cleaned.V) == stored
    assert cleaned.log.merged_vertices == 0 and (cleaned.F == kept.F).all()
    assert cleaned.log.cleaned and not kept.log.cleaned


def test_obj_no_clean_keeps_every_vertex_in_file_order(tmp_path):
    path = tmp_path / "t.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv 1 1 0\nv 1 0 0\n"
                    "vt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\nf 6//1 5//1 3//1\n")
    kept = load_mesh(path, clean=False)
    assert kept.V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [1, 1, 0], [1, 0, 0]]
    assert kept.F.tolist() == [[0, 1, 2], [5, 4, 2]]
    cleaned = load_mesh(path)
    assert cleaned.log.merged_vertices == 1 and cleaned.log.removed_unreferenced == 1
    assert cleaned.F.tolist() == [[0, 1, 2], [1, 3, 2]]


def test_malformed_ply_and_off_are_refused(tmp_path):
    head = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face {nf}\nproperty list uchar {kind} vertex_indices\nend_header\n"
            "0 0 0\n1 0 0\n0 1 0\n")
    cases = {
        "frac.ply": (head.format(nf=1, kind="float") + "3 0 1.5 2\n", "face 0 has a non-integer vertex index 1.5"),
        "empty_face.ply": (head.format(nf=2, kind="int") + "3 0 1 2\n0\n", "face 1 has fewer than 3 corners"),
        "short.off": ("OFF\n3 5 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                      "declares 3 vertices and 5 faces, but only 4 lines follow"),
        "short_face.off": ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "face 0 declares 3 corners but lists 2"),
        # a two-corner face is named the same way in every format (OBJ, OFF, PLY)
        "edge.off": ("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n2 0 1\n", "face 1 has fewer than 3 corners"),
        "edge.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2/1 3/1\n", "face 1 has fewer than 3 corners"),
    }
    for name, (text, fragment) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(InputError) as err:
            load_mesh(tmp_path / name)
        assert fragment in err.value.problem, (name, err.value.problem)
    (tmp_path / "bin.ply").write_bytes(b"ply\nformat ascii 1.0\n\xff\xfe garbage\n")
    with pytest.raises(InputError, match="header is not ASCII text"):
        load_mesh(tmp_path / "bin.ply")
    (tmp_path / "quad_float.ply").write_text(head.format(nf=1, kind="float") + "3 0 1.0 2\n")
    assert load_mesh(tmp_path / "quad_float.ply").F.tolist() == [[0, 1, 2]]


def test_polygons_are_triangulated_and_counted(fixture_dir):
    m = load_mesh(fixture_dir / "quad.obj")
    assert m.log.triangulated_polygons == 2 and len(m.F) == 4
    tm = trimesh.Trimesh(m.V, m.F, process=False)
    assert tm.area == pytest.approx(2.0)


def test_merge_keeps_first_occurrence_and_fields():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [5, 5, 5]], float)
    F = np.array([[0, 1, 2], [0, 3, 2]])
    V2, F2, keep = merge_coincident_vertices(V, F)
    assert keep.tolist() == [0, 1, 2, 4] and F2.tolist() == [[0, 1, 2], [0, 1, 2]]
    V3, F3, keep3 = remove_unreferenced_vertices(V2, F2)
    assert keep3.tolist() == [0, 1, 2] and len(V3) == 3


def _groups_by_dict(V):
    """Equal labels exactly for equal positions, by a dictionary of tuples (0.0 == -0.0)."""
    seen = {}
    return np.array([seen.setdefault(tuple(float(x) for x in row), len(seen)) for row in V])


@pytest.mark.parametrize("collide", [False, True])
def test_position_groups_are_the_equal_positions(monkeypatch, collide):
    from geoproc.mesh import clean

    if collide:  # every row one hash: the lexicographic sort decides
        monkeypatch.setattr(clean, "row_hashes", lambda V: np.zeros(len(V), dtype=np.uint64))
    rng = np.random.default_rng(7)
    for _ in range(100):
        n = int(rng.integers(1, 200))
        V = rng.integers(-2, 3, (n, 3)) * rng.choice([1.0, 0.5, 1e-300])
        V[rng.random((n, 3)) < 0.1] = -0.0
        got, want = clean.position_groups(V), _groups_by_dict(V)
        pairs = set(zip(got.tolist(), want.tolist(), strict=True))  # a one-to-one map between the labels
        assert len(pairs) == len(set(got.tolist())) == len(set(want.tolist()))


def test_row_hashes_separate_grid_positions():
    from geoproc.mesh.clean import row_hashes

    g = np.arange(-20, 21, dtype=float)
    V = np.stack(np.meshgrid(g, g, g), axis=-1).reshape(-1, 3)
    for scale in (1.0, 0.5, 1e-300, 1e300):  # coordinates whose low bits are all zero
        assert len(np.unique(row_hashes(V * scale))) == len(V)
    assert row_hashes(np.array([[-0.0, 0.0, -0.0]]))[0] == row_hashes(np.zeros((1, 3)))[0]


@pytest.mark.parametrize(
    "name, fragment",
    [
        ("truncated.ply", "PLY header declares 42 vertex rows and 80 face rows (at least 1088 bytes)"),
        ("nan.ply", "non-finite coordinates"),
        ("out_of_range.obj", "face index out of range"),
        ("empty.obj", "no faces"),
    ],
)
def test_bad_files_raise_input_error_naming_the_file(fixture_dir, name, fragment):
    with pytest.raises(InputError) as err:
        load_mesh(fixture_dir / name)
    assert fragment in err.value.problem
    assert err.value.path.endswith(name)


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_mesh(tmp_path / "nope.obj")
    (tmp_path / "m.xyz").write_text("1 2 3\n")
    with pytest.raises(InputError, match="unknown mesh format"):
        load_mesh(tmp_path / "m.xyz")
    (tmp_path / "e.off").write_bytes(b"")
    with pytest.raises(InputError, match="empty"):
        load_mesh(tmp_path / "e.off")
    (tmp_path / "g.off").write_text("this is not an OFF file\n")
    with pytest.raises(InputError):
        load_mesh(tmp_path / "g.off")


_TRIANGLE_PLY_HEAD = ("ply\nformat {fmt} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")


def test_ply_counts_beyond_the_file_are_refused_before_allocating(tmp_path):
    # plyfile allocates each element before reading it: 4e9 rows would be a 45 GiB array
    p = tmp_path / "b.ply"
    p.write_bytes(_TRIANGLE_PLY_HEAD.format(fmt="binary_little_endian", n=4_000_000_000).encode() + bytes(13))
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == ("PLY header declares 4000000000 vertex rows and 1 face row "
                                 "(at least 48000000001 bytes), but only 13 bytes follow it")
    p = tmp_path / "a.ply"
    p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n=4_000_000_000) + "0 0 0\n")
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == ("PLY header declares 4000000000 vertex rows and 1 face row, "
                                 "but only 1 line follows it (one per row)")
    # past Python's 4300 digits for reading an integer: an internal error, exit 3
    p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n="9" * 5000) + "0 0 0\n")
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == "PLY header declares a count of more than 20 digits for its 'vertex' rows"
    for zeros in (30, 5000):  # leading zeros are no digits of the count (int() counts them)
        p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n="0" * zeros + "3") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
        assert len(load_mesh(p, clean=False).F) == 1


def test_ascii_ply_text_after_the_declared_rows_is_refused(tmp_path):
    rows = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    p = tmp_path / "t.ply"
    p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n=3) + rows + "GARBAGE\n")
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == ("PLY header declares 3 vertex rows and 1 face row, but 5 non-empty lines "
                                 "follow it (one per row): data after the declared rows")
    p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n=3) + rows + "\n  \t\r\n\n")  # blank lines are fine
    assert len(load_mesh(p, clean=False).F) == 1
    # a row written over two lines has no data after the rows: plyfile names the row
    p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n=3) + rows.replace("1 0 0\n", "1 0\n0\n"))
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == "unparseable PLY: element 'vertex': row 1: property 'z': early end-of-line"
    # a header that undercounts its rows is still named as such (plyfile blamed the face row),
    # also when the row left over reads as a list that ends early ("3 1 0": three indices)
    for extra in ("1 1 0", "3 1 0"):
        p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n=3) + f"0 0 0\n1 0 0\n0 1 0\n{extra}\n3 0 1 2\n")
        with pytest.raises(InputError) as err:
            load_mesh(p)
        assert err.value.problem.endswith("5 non-empty lines follow it (one per row): data after the declared rows")


@pytest.mark.parametrize("last", [-100, -3])
def test_binary_ply_list_with_a_negative_count_is_refused(tmp_path, last):
    # plyfile read a negative count as "the rest of the file": a last face row of
    # count -100 followed by four indices came back as a quad, fanned into two triangles
    import struct

    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement face 2\nproperty list int int vertex_indices\nend_header\n")
    V = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0)
    p = tmp_path / "n.ply"
    p.write_bytes(head.encode() + V + struct.pack("<4i", 3, 0, 1, 2) + struct.pack("<5i", last, 0, 2, 3, 1))
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == "unparseable PLY: a binary list row has a negative count"
    p.write_bytes(head.encode() + V + struct.pack("<4i", 3, 0, 1, 2) + struct.pack("<5i", 4, 0, 2, 3, 1))
    assert len(load_mesh(p, clean=False).F) == 3  # the same file with a count of 4: one triangle and a quad


def test_ply_rows_that_fit_the_counts_keep_plyfiles_message(tmp_path):
    p = tmp_path / "t.ply"
    p.write_text(_TRIANGLE_PLY_HEAD.format(fmt="ascii", n=3) + "0 0 0\n1 0 0\n0 a 0\n3 0 1 2\n")
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == "unparseable PLY: element 'vertex': row 2: property 'y': malformed input"


def test_out_of_range_in_ply_and_off(tmp_path):
    ply = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n")
    (tmp_path / "o.ply").write_text(ply)
    with pytest.raises(InputError, match="face index out of range: face 0 references vertex 3"):
        load_mesh(tmp_path / "o.ply")
    (tmp_path / "o.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(InputError, match="out of range"):
        load_mesh(tmp_path / "o.off")


def test_a_zip_archive_on_standard_input_is_named_as_an_animation():
    # an .npz's bytes can match the OBJ test ('v ' at a line start): the zip signature comes first
    from geoproc.errors import InputError

    with pytest.raises(InputError, match="looks like a .npz animation"):
        sniff_format(b"PK\x03\x04garbage\nv 1 2 3\nf 1 2 3\n")


@pytest.mark.parametrize("fmt,lines", [("off", 80), ("obj", 80), ("obj", 1000)])
def test_sniffing_reads_past_leading_comments_of_any_length(sphere, fmt, lines):
    # 5.6 KB of comments before OFF had cut one at byte 4096 and read it as the first token, and an
    # OBJ's first keyword after 64 KB was not found: "cannot tell the mesh format", read fine by name
    pad = b"".join(b"# comment line %05d with some padding text to make it longer........\n" % i
                   for i in range(lines))
    data = pad + mesh_to_bytes(sphere, fmt)
    assert sniff_format(data) == fmt
    assert len(read_mesh_bytes(data, fmt, "-").F) == len(sphere.F)


@pytest.mark.parametrize("name,data,quoted", [
    ("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 \u00d7\nf 1 2 3\n".encode(), "'v 1 1 \u00d7'"),
    ("m.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 \xe9\n3 0 1 2\n", "'0 1 \\xe9'"),
])
def test_file_text_in_messages_is_quoted_as_written(tmp_path, name, data, quoted):
    # UTF-8 had been decoded as Latin-1 ('\u00d7' shown as '\u00c3\u0097'); a byte that is no UTF-8 is escaped
    (tmp_path / name).write_bytes(data)
    with pytest.raises(InputError) as err:
        load_mesh(tmp_path / name)
    assert quoted in str(err.value)


@pytest.mark.parametrize("fmt", ["ply", "obj", "off", "stl"])
def test_sniffing_standard_input(sphere, fmt):
    data = mesh_to_bytes(sphere, fmt)
    assert sniff_format(data) == fmt
    m = read_mesh_bytes(data, fmt, "-")
    assert len(m.F) == len(sphere.F)
    if fmt == "stl":  # an ASCII STL in upper case, read by name, was not told apart on standard input
        text = (b"SOLID T\n FACET NORMAL 0 0 1\n  OUTER LOOP\n   VERTEX 0 0 0\n   VERTEX 1 0 0\n"
                b"   VERTEX 0 1 0\n  ENDLOOP\n ENDFACET\nENDSOLID T\n")
        assert sniff_format(text) == "stl" and len(read_mesh_bytes(text, "stl", "-").F) == 1


def test_ascii_stl_of_several_solids_keeps_its_corners_as_stored():
    def solid(name, tris):
        facets = "".join(" facet normal 0 0 1\n  outer loop\n" + "".join(f"   vertex {x} {y} {z}\n" for x, y, z in t)
                         + "  endloop\n endfacet\n" for t in tris)
        return f"solid {name}\n{facets}endsolid {name}\n"
    a = [[(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(1, 0, 0), (1, 1, 0), (0, 1, 0)]]
    b = [[(2, 0, 0), (3, 0, 0), (2, 1, 0)], [(3, 0, 0), (3, 1, 0), (2, 1, 0)]]
    data = (solid("a", a) + solid("b", b)).encode()
    m = read_mesh_bytes(data, "stl", "two.stl", clean=False)
    # as stored: three corners per facet in file order (each solid's corners were merged before)
    assert m.V.tolist() == [list(p) for t in a + b for p in t]
    assert m.F.tolist() == [[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11]]
    assert len(read_mesh_bytes(data, "stl", "two.stl").V) == 8


@pytest.mark.parametrize("header", [b"3 1\n", b"ply export by tool", b"OFF writer 2.1", b"\xef\xbb\xbfsolid x"])
def test_binary_stl_whose_header_starts_like_another_format_is_sniffed_as_stl(sphere, header):
    # the header is free text: '3 1' and a newline had read as an OFF without its keyword,
    # and 'ply ...' or 'OFF ...' (an exporter's name) as a PLY or an OFF
    data = mesh_to_bytes(sphere, "stl")
    data = header.ljust(80, b" ") + data[80:]
    assert sniff_format(data) == "stl"
    assert len(read_mesh_bytes(data, "stl", "-").F) == len(sphere.F)


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    def boom():
        raise RuntimeError("boom")

    target = tmp_path / "out.ply"
    with pytest.raises(RuntimeError):
        write_files_atomic([(target, b"partial")], before_rename=boom)
    assert list(tmp_path.iterdir()) == []
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        write_files_atomic([(target, b"new")], before_rename=boom)
    assert target.read_bytes() == b"old" and len(list(tmp_path.iterdir())) == 1


@pytest.mark.parametrize("existing", [True, False])
def test_atomic_write_puts_back_what_a_failed_later_rename_replaced(tmp_path, monkeypatch, existing):
    # a report bind-mounted or immutable cannot be renamed onto (EBUSY, EPERM): the mesh
    # renamed before it had already replaced the old one, with no report to match it
    import errno
    import os

    import geoproc.fileio as fileio

    mesh, report = tmp_path / "o.ply", tmp_path / "r.json"
    if existing:
        mesh.write_bytes(b"old mesh")
    report.write_bytes(b"old report")
    real_replace = os.replace

    def busy(src, dst):
        if os.fspath(dst) == str(report) and str(src).endswith(".tmp"):
            raise OSError(errno.EBUSY, "Device or resource busy")
        real_replace(src, dst)

    monkeypatch.setattr(fileio.os, "replace", busy)
    with pytest.raises(OSError, match="busy") as failed:
        write_files_atomic([(mesh, b"new mesh"), (report, b"new report")])
    assert failed.value.filename == str(report)  # the destination, as given
    assert report.read_bytes() == b"old report"
    assert (mesh.read_bytes() == b"old mesh") if existing else not mesh.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["r.json"] + (["o.ply"] if existing else []))
    monkeypatch.setattr(fileio.os, "replace", real_replace)
    write_files_atomic([(mesh, b"new mesh"), (report, b"new report")])  # no second names left behind
    assert mesh.read_bytes() == b"new mesh" and sorted(p.name for p in tmp_path.iterdir()) == ["o.ply", "r.json"]


def test_an_interruption_as_a_temporary_file_is_made_leaves_none(tmp_path, monkeypatch):
    # a signal between tempfile.mkstemp's creating the file and its name being recorded left
    # a stray .out.ply.*.tmp beside the output
    import os

    real_open = os.open

    def interrupted(path, flags, mode=0o777, *args, **kw):
        fd = real_open(path, flags, mode, *args, **kw)
        if os.fsdecode(path).endswith(".tmp"):
            os.close(fd)
            raise KeyboardInterrupt
        return fd

    monkeypatch.setattr(os, "open", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_files_atomic([(tmp_path / "out.ply", b"data")])
    monkeypatch.setattr(os, "open", real_open)
    assert list(tmp_path.iterdir()) == []


def test_an_interruption_after_the_renames_leaves_no_second_names(tmp_path, monkeypatch):
    # the old files' hard links were removed only on the way out of the renames: a signal as
    # they were removed left them beside the new outputs
    import os

    import geoproc.fileio as fileio

    (tmp_path / "o.ply").write_bytes(b"old")
    (tmp_path / "r.json").write_bytes(b"old report")
    real_unlink = os.unlink
    calls = []

    def interrupted(path, *args, **kw):
        calls.append(path)
        if len(calls) == 1:
            raise KeyboardInterrupt
        return real_unlink(path, *args, **kw)

    monkeypatch.setattr(fileio.os, "unlink", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_files_atomic([(tmp_path / "o.ply", b"new"), (tmp_path / "r.json", b"new report")])
    monkeypatch.setattr(fileio.os, "unlink", real_unlink)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.ply", "r.json"]


def test_a_temporary_file_that_cannot_be_made_names_the_destination(tmp_path, monkeypatch):
    # on a read-only file system the temporary name had stayed recorded, and removing it
    # (EROFS, not 'no such file') replaced the error with one naming that temporary file
    import errno

    import geoproc.fileio as fileio

    def read_only(path, *args, **kw):
        raise OSError(errno.EROFS, "Read-only file system", path)

    monkeypatch.setattr(fileio.os, "open", read_only)
    monkeypatch.setattr(fileio.os, "unlink", read_only)
    with pytest.raises(OSError) as failed:
        write_files_atomic([(tmp_path / "out.ply", b"data")])
    assert failed.value.filename == str(tmp_path / "out.ply") and failed.value.errno == errno.EROFS


def test_obj_relative_indices_count_back_from_the_line():
    # -1 is the last vertex defined above the face line, not the file's last vertex
    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -1 -2\nf 2 4 3\n"
    m = read_mesh_bytes(data, "obj", clean=False)
    assert m.F.tolist() == [[0, 1, 2], [1, 3, 2], [1, 3, 2]]


def test_utf8_byte_order_mark_is_skipped():
    body = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"
    m = read_mesh_bytes(b"\xef\xbb\xbf" + body, "obj", clean=False)
    assert len(m.V) == 4 and m.F.tolist() == read_mesh_bytes(body, "obj", clean=False).F.tolist()
    # the report's hash is of the file as stored (sha256sum's), mark included: it had been the text's
    assert m.log.sha256 == hashlib.sha256(b"\xef\xbb\xbf" + body).hexdigest()


def test_off_mixing_triangles_and_polygons(tmp_path):
    # a triangle then a pentagon: trimesh could not stack the two face lengths
    path = tmp_path / "tp.off"
    path.write_text("OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 2 0\n3 0 1 2\n5 0 1 2 4 3\n")
    mesh = load_mesh(path, clean=False)
    assert mesh.log.triangulated_polygons == 1
    assert np.array_equal(mesh.F, [[0, 1, 2], [0, 1, 2], [0, 2, 4], [0, 4, 3]])


def test_off_values_wrapped_over_lines_match_meshlab(tmp_path, sphere):
    # the format asks only for the vertex values in order: seven to a line here, as MeshLab reads them
    import pymeshlab

    values = [repr(float(x)) for x in sphere.V.reshape(-1)]
    body = [" ".join(values[i: i + 7]) for i in range(0, len(values), 7)]
    faces = [f"3 {a} {b} {c}" for a, b, c in sphere.F]
    path = tmp_path / "w.off"
    path.write_text("\n".join(["OFF", f"{len(sphere.V)} {len(sphere.F)} 0", *body, *faces]) + "\n")
    mesh = load_mesh(path, clean=False)
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    assert np.array_equal(mesh.V, ms.current_mesh().vertex_matrix())
    assert np.array_equal(mesh.F, ms.current_mesh().face_matrix())
    assert np.array_equal(mesh.V, sphere.V) and np.array_equal(mesh.F, sphere.F)
    # a face's corners may wrap too (MeshLab refuses that); its colour ends its line
    wrapped = [f"3 {a} {b}\n{c} 255 0 0" for a, b, c in sphere.F]
    path.write_text("\n".join(["OFF", f"{len(sphere.V)} {len(sphere.F)} 0", *body, *wrapped]) + "\n")
    mesh = load_mesh(path, clean=False)
    assert np.array_equal(mesh.V, sphere.V) and np.array_equal(mesh.F, sphere.F)


@pytest.mark.parametrize("text, V, F", [
    # everything on the line of the counts; 4OFF; normals and texture coordinates (8 values a vertex)
    (b"OFF 3 1 0 0 0 0 1 0 0 0 1 0 3 0 1 2 1 1 1\n", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]),
    (b"4OFF\n3 1 0\n0 0 0 1 2 0 0\n2 0 4 0 2\n3 0 1 2\n", [[0, 0, 0], [1, 0, 0], [0, 2, 0]], [[0, 1, 2]]),
    (b"STNOFF\n3 1 0\n0 0 0 0 0 1 0.5 0.5\n1 0 0 0 0 1 0 0 0 1 0 0 0 1 0 0\n3 0 1 2\n",
     [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]),
    (b"OFF\n4 1 0\n0 0 0 1 0\n0 0 1 0 1 1 0\n4 0 1\n3 2 # a comment\n", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
     [[0, 1, 3], [0, 3, 2]]),
])
def test_off_free_form(text, V, F):
    m = read_mesh_bytes(text, "off", "w.off", clean=False)
    assert m.V.tolist() == V and m.F.tolist() == F


@pytest.mark.parametrize("text, fragment", [
    # per-vertex colours: 3 or 4 values, which only the line end tells
    (b"COFF\n3 1 0\n0 0 0 1 1\n1 1 1 0 0 1 0 1 1 1 0 1 0 1 1 1\n3 0 1 2\n", "but only 3 lines follow"),
    (b"OFF\n3 1 0\n0 0 0 1 0 0 0 1 0\n4 0 1 2\n", "but only 2 lines follow"),  # a face short of corners
    (b"OFF\n3 1 0\n0 0 0 1 0 0 0 1\n3 0 1 2\n", "but only 2 lines follow"),  # a value short
    (b"OFF\n3 1 0\n0 0 0 1 0 0 0 1 0 2 0 1\n", "but only 1 lines follow"),  # a face of two corners
    (b"OFF\n-3 1 0\n0 0 0 1 0 0 0 1 0 3 0 1 2\n", "declares -3 vertices and 1 face: counts cannot be negative"),
    # face lines beyond the count (a closed tetrahedron read as an open one before), by lines and wrapped
    (b"OFF\n4 3 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
     "but 8 non-empty lines follow it (one per vertex, then one per face): data after the declared faces"),
    (b"OFF\n3 1 0\n0 0 0 1\n0 0 0 1\n0\n3 0 1 2\n3 0 2 1\n", "but 5 non-empty lines follow it"),
])
def test_off_free_form_refused(text, fragment):
    with pytest.raises(InputError) as err:
        read_mesh_bytes(text, "off", "w.off")
    assert fragment in err.value.problem, err.value.problem


def test_off_colours_and_comments_match_libigl(tmp_path, sphere):
    import igl

    lines = ["COFF", f"{len(sphere.V)} {len(sphere.F)} 0"]
    lines += [" ".join(map(repr, map(float, v))) + " 255 0 0 255" for v in sphere.V]
    lines += [f"3 {a} {b} {c} 0 255 0" for a, b, c in sphere.F]
    path = tmp_path / "c.off"
    path.write_text("\n".join(lines) + "\n")
    mesh = load_mesh(path, clean=False)
    V, F = igl.read_triangle_mesh(str(path))
    assert np.array_equal(mesh.V, V) and np.array_equal(mesh.F, F)
    # a leading comment (which libigl does not read) changes nothing and does
    # not hide the format on standard input
    commented = b"# written by hand\n" + path.read_bytes()
    assert sniff_format(commented) == "off"
    again = read_mesh_bytes(commented, "off", "-", clean=False)
    assert np.array_equal(again.V, V) and np.array_equal(again.F, F)


def test_obj_reader_matches_libigl_on_shared_meshes(shared_data):
    import igl

    paths = sorted((shared_data / "meshes").glob("*.obj")) + sorted((shared_data / "denoise").glob("*/*.obj"))
    assert len(paths) >= 5
    for path in paths:
        mesh = load_mesh(path, clean=False)
        V, F = igl.read_triangle_mesh(str(path))
        assert np.array_equal(mesh.V, V) and np.array_equal(mesh.F, F), path.name


def test_obj_vertex_extras_and_malformed_lines(tmp_path):
    # a weight or a colour after the position is ignored; quads become fans
    data = b"v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\nv 0 1 0\nvn 0 0 1\ng part\nf 1//1 2//1 3//1 4//1\n"
    m = read_mesh_bytes(data, "obj", clean=False)
    assert m.V.tolist() == [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert m.F.tolist() == [[0, 1, 2], [0, 2, 3]] and m.log.triangulated_polygons == 1
    for text, fragment in [
        (b"v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "OBJ vertex 1 (1-based): 'v 0 0' does not hold three numbers"),
        (b"v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n", "OBJ vertex 2 (1-based): 'v 1 x 0' does not hold three numbers"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n", "a face corner is not an integer"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", "face 0 references vertex -4, but the file has 3"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "face 0 references vertex 0, but the file has 3"),
        (b"vt 0 0\n", "no vertex or face lines"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n", "beyond 64-bit integers"),
        # a short line beside a long one once passed the total count (the w became a coordinate)
        (b"v 0 0 0 1\nv 1 0\nv 0 1 0\nf 1 2 3\n", "OBJ vertex 2 (1-based): 'v 1 0' does not hold three numbers"),
        (b"v 0 0 0\nv\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "OBJ vertex 2 (1-based): 'v ' does not hold three numbers"),
        (b"v 0 0 0\nv 1_0 0 0\nv 0 1 0\nf 1 2 3\n", "'_' inside a number"),
    ]:
        with pytest.raises(InputError) as err:
            read_mesh_bytes(text, "obj", "m.obj")
        assert fragment in err.value.problem, (text, err.value.problem)


def test_ply_triangle_strips_are_read():
    # strips over a 2 x 3 grid of vertices: one with a restart (-1), one that
    # starts with a degenerate (stitching) triangle; orientation alternates along a strip
    header = ("ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
              "element tristrips 2\nproperty list int int vertex_indices\nend_header\n")
    verts = "0 0 0\n0 1 0\n1 0 0\n1 1 0\n2 0 0\n2 1 0\n"
    m = read_mesh_bytes((header + verts + "9 0 1 2 3 -1 2 3 4 5\n4 3 3 4 5\n").encode(), "ply", clean=False)
    assert m.F.tolist() == [[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 5], [4, 3, 5]]
    N = np.cross(m.V[m.F[:, 1]] - m.V[m.F[:, 0]], m.V[m.F[:, 2]] - m.V[m.F[:, 0]])
    assert (N[:, 2] < 0).all()  # one orientation throughout


def test_obj_backslash_continues_a_line():
    m = read_mesh_bytes(b"v 0 0 \\\n0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\r\n3\n", "obj", clean=False)
    assert m.V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]] and m.F.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize("text, V", [
    # 4OFF: homogeneous coordinates, divided by w (trimesh dropped w)
    (b"4OFF\n3 1 0\n0 0 0 1\n2 0 0 2\n0 4 0 2\n3 0 1 2\n", [[0, 0, 0], [1, 0, 0], [0, 2, 0]]),
    (b"CNOFF\n3 1 0\n0 0 0 0 0 1 1 0 0 1\n1 0 0 0 0 1 0 1 0 1\n0 1 0 0 0 1 0 0 1 1\n3 0 1 2\n",
     [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
    # MeshLab's order for a mesh with normals and colours: NCOFF, each vertex x y z r g b a nx ny nz
    (b"NCOFF\n3 1 0\n0 0 0 255 0 0 255 0 0 1\n1 0 0 0 255 0 255 0 0 1\n0 1 0 0 0 255 255 0 0 1\n3 0 1 2\n",
     [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
    (b"nOFF\n3\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
    (b"off\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),
    (b"3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", [[0, 0, 0], [1, 0, 0], [0, 1, 0]]),  # no keyword
])
def test_off_variants(text, V):
    m = read_mesh_bytes(text, "off", "v.off", clean=False)
    assert m.V.tolist() == V and m.F.tolist() == [[0, 1, 2]]
    # the format is told on standard input too, keyword or not
    assert sniff_format(text) == sniff_format(b"\xef\xbb\xbf" + text) == "off"


@pytest.mark.parametrize("text, fragment", [
    (b"OFF BINARY\n\x00\x00\x00\x03", "binary OFF is not supported"),
    (b"nOFF\n4\n3 1 0\n0 0 0 0\n1 0 0 0\n0 1 0 0\n3 0 1 2\n", "nOFF of dimension 4"),
    (b"4OFF\n3 1 0\n0 0 0 0\n1 0 0 1\n0 1 0 1\n3 0 1 2\n", "4OFF vertex 0 has w = 0"),
    (b"OFF\n3 1 0\n0 0 0\n1_0 0 0\n0 1 0\n3 0 1 2\n", "'_' inside a number"),
])
def test_off_variants_refused(text, fragment):
    with pytest.raises(InputError) as err:
        read_mesh_bytes(text, "off", "v.off")
    assert fragment in err.value.problem


def test_obj_sniffed_behind_a_long_preamble():
    data = b"vt 0.5 0.5\n" * 7000 + b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/2 3/3\n"
    assert sniff_format(data) == "obj"


def test_ply_index_lists_that_are_not_integers():
    head = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element {el} 1\nproperty list int double vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
    for el, row, fragment in [("tristrips", "4 0 1 2 inf", "tristrips row 0 has a non-integer vertex index inf"),
                              ("face", "3 0 1 1e30", "face 0 has an out-of-range vertex index 1e+30")]:
        with pytest.raises(InputError) as err:
            read_mesh_bytes((head.format(el=el) + row + "\n").encode(), "ply", "p.ply")
        assert fragment in err.value.problem


def test_ply_unsigned_strip_restart_marker():
    # -1 stored as an unsigned 32-bit integer is 4294967295
    head = ("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
            "element tristrips 1\nproperty list int uint vertex_indices\nend_header\n")
    body = "0 0 0\n0 1 0\n1 0 0\n1 1 0\n2 0 0\n7 0 1 2 4294967295 1 3 2\n"
    m = read_mesh_bytes((head + body).encode(), "ply", clean=False)
    assert m.F.tolist() == [[0, 1, 2], [1, 3, 2]]


def test_obj_vertical_tab_and_form_feed_are_blanks():
    m = read_mesh_bytes(b"v\x0b0 0 0\nv 1\x0c0 0\nv 0 1 0\nf 1 2 3\n", "obj", clean=False)
    assert m.V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


_PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "element {el} {n}\n{prop}\nend_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n")


@pytest.mark.parametrize("element", ["face", "tristrips"])
def test_ply_index_property_that_is_not_a_list_is_an_input_error(element):
    data = _PLY_HEAD.format(el=element, n=2, prop="property int vertex_indices") + "0\n1\n"
    with pytest.raises(InputError, match=f"PLY {element} property 'vertex_indices' is a single int32"):
        read_mesh_bytes(data.encode(), "ply", "s.ply")


def test_ply_polygon_face_properties_follow_their_fan_triangles():
    data = _PLY_HEAD.format(el="face", n=2, prop="property list uchar int vertex_indices\nproperty float region")
    data = data.replace("element face 2", "element face 2").replace("1 1 0\n", "1 1 0\n0 0 1\n")
    data = data.replace("element vertex 4", "element vertex 5") + "4 0 1 3 2 7\n3 0 2 4 9\n"
    m = read_mesh_bytes(data.encode(), "ply", "q.ply", clean=False)
    assert len(m.F) == 3 and m.log.triangulated_polygons == 1
    assert m.face_fields["region"].tolist() == [7.0, 7.0, 9.0]


def test_ply_list_properties_are_named_as_unread():
    head = _PLY_HEAD.format(el="face", n=1, prop="property list uchar int vertex_indices\n"
                            "property list uchar float texcoord\nproperty float w")
    head = head.replace("property float z\n", "property float z\nproperty list uchar int nbrs\nproperty float q\n")
    rows = head.split("end_header\n")
    body = "".join(line + f" 2 {i} {i + 1} {i}.5\n" for i, line in enumerate(rows[1].splitlines()))
    data = rows[0] + "end_header\n" + body + "3 0 1 2 6 0 0 1 0 0 1 7\n"
    m = read_mesh_bytes(data.encode(), "ply", "l.ply", clean=False)
    assert sorted(m.vertex_fields) == ["q"] and m.vertex_fields["q"].tolist() == [0.5, 1.5, 2.5, 3.5]
    assert sorted(m.face_fields) == ["w"] and m.face_fields["w"].tolist() == [7.0]
    assert m.log.unread_properties == ["vertex nbrs", "face texcoord"]
    assert read_mesh_bytes(_PLY_HEAD.format(el="face", n=1, prop="property list uchar int vertex_indices").encode()
                           + b"3 0 1 2\n", "ply", "t.ply").log.unread_properties == []
    # another element (MeshLab and Open3D write 'edge'): dropped, so named too
    with_edges = data.replace("end_header", "element edge 2\nproperty int vertex1\nproperty int vertex2\nend_header")
    m = read_mesh_bytes((with_edges + "0 1\n1 2\n").encode(), "ply", "e.ply", clean=False)
    assert m.log.unread_properties == ["vertex nbrs", "face texcoord", "element edge"] and len(m.F) == 1


def test_float32_property_beyond_its_range_reads_as_inf_without_a_warning():
    import warnings

    data = _PLY_HEAD.format(el="face", n=1, prop="property list uchar int vertex_indices")
    data = data.replace("property float z\n", "property float z\nproperty float q\n")
    rows = data.split("end_header\n")
    body = "".join(line + (" 1e39\n" if i == 0 else " 1\n") for i, line in enumerate(rows[1].splitlines()))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = read_mesh_bytes((rows[0] + "end_header\n" + body + "3 0 1 2\n").encode(), "ply", "f.ply", clean=False)
    assert m.vertex_fields["q"].tolist() == [np.inf, 1.0, 1.0, 1.0]


def test_signalling_nan_is_refused_without_a_warning():
    import struct
    import warnings

    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4")
    V.view("<u4")[1, 0] = 0x7FA00000  # a signalling NaN
    body = V.tobytes() + bytes([3]) + struct.pack("<3i", 0, 1, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match="non-finite coordinates"):
            read_mesh_bytes(head + body, "ply", "snan.ply")


def test_keywordless_off_with_a_comment_on_its_counts_line_is_sniffed():
    data = b"4 4 6 # counts\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    assert sniff_format(data) == "off"


def test_the_log_carries_the_hash_of_the_bytes_parsed(fixture_dir):
    path = fixture_dir / "icosphere.ply"
    assert load_mesh(path).log.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()


def test_atomic_write_to_a_name_near_the_length_limit(tmp_path):
    target = tmp_path / ("c" * 251 + ".ply")  # 255 bytes: the temporary name must not be longer
    write_files_atomic([(target, b"data")])
    assert target.read_bytes() == b"data" and [p.name for p in tmp_path.iterdir()] == [target.name]


@pytest.mark.parametrize(("name", "text", "problem"), [
    ("s.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 -\n", "not all integers"),
    ("s.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
              "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
              "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 +\n", "malformed input"),
    ("s.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 -\n", "not an integer vertex index"),
])
def test_a_sign_alone_is_not_an_index(tmp_path, name, text, problem):
    # the block reader had taken a final '+' or '-' for 0: the face read as (0, 1, 0)
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError, match=problem):
        load_mesh(path)


def test_unique_rows_match_numpy():
    rng = np.random.default_rng(4)
    P = rng.integers(-3, 4, (5000, 3)).astype(np.float64) * 0.5  # many repeated rows
    P[::7] = rng.standard_normal((len(P[::7]), 3))
    U, inverse = unique_rows(P)
    Un, inv_n = np.unique(P, axis=0, return_inverse=True)
    assert np.array_equal(U, Un) and np.array_equal(inverse, inv_n.ravel())
    assert np.array_equal(U[inverse], P)
    assert unique_rows(np.zeros((0, 3)))[0].shape == (0, 3)


def test_an_output_without_extension_says_so():
    # 'out' was refused as "cannot write '.'"
    from geoproc.errors import UsageError
    from geoproc.mesh.write import write_format

    with pytest.raises(UsageError, match="out: no file extension to choose the format by"):
        write_format("folder.d/out")
    assert write_format("a.b/out.PLY") == "ply"


@pytest.mark.parametrize("data", [b"solid x\nendsolid x\n", b" " * 80 + b"\0\0\0\0"])
def test_stl_of_no_facets_has_no_vertices(tmp_path, data):
    # a well-formed STL with no facet was called unparseable
    path = tmp_path / "e.stl"
    path.write_bytes(data)
    with pytest.raises(InputError, match=r"mesh has no vertices \(an STL of no facets\)"):
        load_mesh(path)
    with pytest.raises(InputError, match="unparseable STL"):  # not an STL at all
        read_mesh_bytes(b"solid x\nfacet normal 0 0 1\n", "stl", "bad.stl")


def _binary_stl(facets: int, declared: int | None = None) -> bytes:
    tri = np.zeros(12, dtype="<f4")
    tri[3:] = [0, 0, 0, 1, 0, 0, 0, 1, 0]
    body = (tri.tobytes() + b"\0\0") * facets
    return b" " * 80 + np.array([facets if declared is None else declared], dtype="<u4").tobytes() + body


@pytest.mark.parametrize("data, problem", [
    # trimesh's messages were numpy's ("cannot reshape array of size 2 into shape (3)")
    # or "no vertices could be read" for any broken STL
    (b"solid a\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid a\n",
     "an ASCII STL of 1 facet lists 2 vertices; each facet has 3"),
    (b"solid a\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n",
     "an ASCII STL without 'endsolid' (cut short?)"),
    (_binary_stl(1) + bytes(5), "a binary STL that declares 1 facet takes 134 bytes, but the file has 139"),
    (_binary_stl(4)[:-20], "a binary STL that declares 4 facets takes 284 bytes, but the file has 264"),
    (_binary_stl(4, declared=1000), "a binary STL that declares 1000 facets takes 50084 bytes, but the file has 284"),
    (bytes(70), "a binary STL has an 84-byte header, but the file has only 70 bytes"),
])
def test_broken_stl_says_what_is_wrong(data, problem):
    with pytest.raises(InputError) as err:
        read_mesh_bytes(data, "stl", "b.stl")
    assert err.value.problem == f"unparseable STL: {problem}"
    assert len(read_mesh_bytes(_binary_stl(4), "stl", "b.stl", clean=False).F) == 4


def test_vertex_fields_follow_their_vertices_through_the_clean_up(tmp_path):
    # a copy of vertex 0 stored at index 2 (merged into 0) and an unreferenced vertex 5
    # (removed): each field value must stay with its own vertex, which the stored index
    # carried as a field tells; worked by hand, the kept vertices are 0, 1, 3, 4
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 1, 0], [1, 1, 0], [5, 5, 5]], dtype=float)
    F = np.array([[0, 1, 4], [2, 4, 3]])
    save_mesh(tmp_path / "d.ply", Mesh(V, F, {"label": np.arange(6, dtype=float)}))
    m = load_mesh(tmp_path / "d.ply")
    label = m.vertex_fields["label"]
    assert label.tolist() == [0, 1, 3, 4]
    assert np.array_equal(m.V, V[label.astype(int)])
    assert np.array_equal(m.V[m.F], V[F])  # every face keeps its corners' positions


def test_binary_ply_rows_after_the_declared_ones_are_refused(tmp_path):
    # plyfile stops at the declared rows: a tetrahedron whose header said 2 faces of its 4 was
    # read as an open mesh of 2 faces without a word (the ASCII twin was refused)
    import struct

    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n")
    V = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1)
    F = b"".join(struct.pack("<B3i", 3, *f) for f in ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)))
    p = tmp_path / "t.ply"
    p.write_bytes(head.encode() + V + F)
    with pytest.raises(InputError) as err:
        load_mesh(p)
    assert err.value.problem == ("PLY header declares 4 vertex rows and 2 face rows, but 26 more bytes follow "
                                 "them: data after the declared rows")
    p.write_bytes(head.encode() + V + F[:26] + b"\n")  # a newline after the rows is harmless
    assert len(load_mesh(p, clean=False).F) == 2


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_ply_headers_other_readers_take(tmp_path, fmt):
    # a UTF-8 comment and trailing spaces on 'ply' and 'end_header' (MeshLab and trimesh read
    # them; plyfile had refused them), and blank lines among ASCII rows
    mesh = Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    data = mesh_to_bytes(mesh, "ply", binary=fmt != "ascii")
    end = data.index(b"end_header\n")
    data = (data[:end].replace(b"ply\n", "ply \ncomment Author: Jos\u00e9 M\u00fcller\n".encode(), 1)
            + b"end_header \n" + data[end + len(b"end_header\n"):])
    if fmt == "ascii":
        body = data.index(b"end_header \n") + len(b"end_header \n")
        data = data[:body] + b"\n" + data[body:].replace(b"\n", b"\n\n", 3)
    got = read_mesh_bytes(data, "ply", clean=False)
    assert np.array_equal(got.V, mesh.V) and np.array_equal(got.F, mesh.F)


def test_binary_ply_bodies_are_never_read_as_text(tmp_path):
    # a comment mentioning "format ascii" had made the blank-line clean-up rewrite a binary body
    # whose bytes held newlines (a vertex coordinate of bytes 0x0a); zero padding after the rows
    # is no row either
    import struct

    head = (b"ply\nformat binary_little_endian 1.0\ncomment converted from format ascii\nelement vertex 3\n"
            b"property float x\nproperty float y\nproperty float z\nelement face 1\n"
            b"property list uchar int vertex_indices\nend_header\n")
    x = struct.unpack("<f", b"\n\n\n\n")[0]
    V = struct.pack("<9f", x, 0, 0, 1, 0, 0, 0, 1, 0)
    F = struct.pack("<B3i", 3, 0, 1, 2)
    for tail in (b"", b"\x00", b"\n\x00\x00"):
        m = read_mesh_bytes(head + V + F + tail, "ply", clean=False)
        assert m.V[0, 0] == np.float32(x) and m.F.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize("fmt, data, fragment", [
    # x / w overflows: numpy's warning had come before the error line (three lines in all)
    ("off", b"4OFF\n3 1 0\n0 0 0 1\n1 0 0 1e-320\n0 1 0 1\n3 0 1 2\n", "non-finite coordinates"),
    ("off", b"4OFF 3 1 0 0 0 0 1 1 0 0 1e-320 0 1 0 1 3 0 1 2\n", "non-finite coordinates"),
    # trimesh's face normals of an infinite corner: six lines of numpy warnings
    ("stl", b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 1e400 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
            b"endloop\nendfacet\nendsolid t\n", "non-finite coordinates"),
    # a list count of a float type: plyfile read a count of 3.99 as 3
    ("ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list float int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
            b"3.99 0 2 1\n", "has a count of type float"),
])
def test_malformed_numbers_are_one_error_without_warnings(fmt, data, fragment):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError) as err:
            read_mesh_bytes(data, fmt, f"m.{fmt}")
    assert fragment in err.value.problem


@pytest.mark.parametrize("binary", [True, False])
def test_ply_fields_keep_their_stored_types(tmp_path, sphere, binary):
    # uchar colours had been written back as double, which MeshLab and trimesh do not read as colours
    import plyfile
    import pymeshlab

    n, m = len(sphere.V), len(sphere.F)
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    sphere.vertex_fields = {"red": rgb[:, 0], "green": rgb[:, 1], "blue": rgb[:, 2],
                            "label": rng.integers(-5, 5, n).astype(np.int32),
                            "quality": rng.random(n).astype(np.float32), "distance": rng.random(n),
                            "flag": rng.random(n) > 0.5, "big": np.arange(n, dtype=np.int64)}
    sphere.face_fields = {"red": np.full(m, 7, np.uint8), "part": np.arange(m, dtype=np.uint16)}
    path = tmp_path / "c.ply"
    save_mesh(path, sphere, binary=binary)
    ply = plyfile.PlyData.read(str(path))
    types = {p.name: p.val_dtype for p in ply["vertex"].properties}
    assert [types[k] for k in ("x", "red", "label", "quality", "distance", "flag", "big")] == \
        ["f8", "u1", "i4", "f4", "f8", "u1", "f8"]
    assert {p.name: p.val_dtype for p in ply["face"].properties if p.name != "vertex_indices"} == \
        {"red": "u1", "part": "u2"}
    back = load_mesh(path, clean=False)
    for k, v in sphere.vertex_fields.items():
        assert np.array_equal(back.vertex_fields[k], v), k
    assert back.vertex_fields["red"].dtype == np.uint8 and back.vertex_fields["quality"].dtype == np.float32
    assert np.array_equal(back.face_fields["part"], sphere.face_fields["part"])
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    assert ms.current_mesh().has_vertex_color()
    assert np.allclose(ms.current_mesh().vertex_color_matrix()[:, :3] * 255, rgb, atol=0.5)


def test_obj_and_off_name_what_they_do_not_carry(tmp_path):
    obj = b"mtllib a.mtl\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nl 1 2\n"
    assert read_mesh_bytes(obj, "obj", "a.obj").log.unread_properties == [
        "texture coordinates (vt)", "vertex normals (vn)", "colours after x y z on v lines",
        "materials (usemtl, mtllib)", "polylines or points (l, p)"]
    # lines ending in CR alone are lines too
    cr = b"v 0 0 0\rv 1 0 0\rv 0 1 0\rvt 0 0\rvn 0 0 1\rf 1 2 3\r"
    assert read_mesh_bytes(cr, "obj").log.unread_properties == ["texture coordinates (vt)", "vertex normals (vn)"]
    # a weight w after x y z is not a colour; nothing else, nothing named
    assert read_mesh_bytes(b"v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n", "obj").log.unread_properties == []
    coff = b"COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2 9 9 9\n"
    assert read_mesh_bytes(coff, "off", "c.off").log.unread_properties == ["vertex colours (C)", "face colours"]
    noff = b"NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n"
    assert read_mesh_bytes(noff, "off", "n.off").log.unread_properties == ["vertex normals (N)"]
    # colours after the normals the keyword names, and a colour on one face line of several
    noff_rgb = b"NOFF\n3 2 0\n0 0 0 0 0 1 9 9 9\n1 0 0 0 0 1 9 9 9\n0 1 0 0 0 1 9 9 9\n3 0 1 2\n3 0 2 1 7 7 7\n"
    assert read_mesh_bytes(noff_rgb, "off", "n.off", clean=False).log.unread_properties == [
        "vertex normals (N)", "values on vertex lines beyond those the keyword names (colours)", "face colours"]
    plain = b"OFF\n3 1 0\n0 0 0 9 9 9\n1 0 0 9 9 9\n0 1 0 9 9 9\n3 0 1 2\n"
    assert read_mesh_bytes(plain, "off", "p.off").log.unread_properties == [
        "values on vertex lines beyond those the keyword names (colours)"]
    assert read_mesh_bytes(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "off").log.unread_properties == []
    # values wrapped over lines (read as a stream): no colour there, a face colour where one ends a face line
    free = b"OFF\n3 3 0\n0 0 0 1 0 0 0 1 0\n3 0 1 2\n3 0 2 1\n3 1 0 2\n"
    assert read_mesh_bytes(free, "off", "f.off", clean=False).log.unread_properties == []
    free_c = b"OFF\n3 2 0\n0 0 0 1 0 0 0 1 0\n3 0 1 2\n3 0 2 1 5 5 5\n"
    assert read_mesh_bytes(free_c, "off", "f.off", clean=False).log.unread_properties == ["face colours"]


def test_reader_cases_found_by_fuzzing():
    def read(data, fmt):
        return read_mesh_bytes(data, fmt, f"f.{fmt}", clean=False)

    # an ASCII PLY element of no properties: an internal error (exit 3), now the missing x
    with pytest.raises(InputError, match="PLY vertex element has no 'x' property"):
        read(b"ply\nformat ascii 1.0\nelement vertex 1\nend_header\n\n", "ply")
    # lines ending in CR alone: '1_0' had been read as 10, and a continued face line refused
    with pytest.raises(InputError, match="'_' inside a number"):
        read(b"v 0 0 0\rv 1_0 0 0\rv 0 1 0\rf 1 2 3\r", "obj")
    assert read(b"v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 \\\r3\r", "obj").F.tolist() == [[0, 1, 2]]
    # so too an ASCII PLY read by plyfile (a list property besides the faces' sends it there)
    ply = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
           b"element face 1\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\n"
           b"end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 2 0 0\n")
    assert read(ply, "ply").F.tolist() == [[0, 1, 2]]
    with pytest.raises(InputError, match="'_' inside a number"):
        read(ply.replace(b"\n1 0 0\n", b"\n1_0 0 0\n"), "ply")
    # an ASCII STL facet of four corners had shifted the next facet's corners
    stl = (b"solid a\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n"
           b"   vertex 5 5 5\n  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 1 1 0\n"
           b"   vertex 1 0 0\n  endloop\n endfacet\nendsolid a\n")
    with pytest.raises(InputError, match="ASCII facet 0 lists 4 vertices; each facet has 3"):
        read(stl, "stl")
    # NOFF lines shorter than the keyword's six values: read as the stream they are
    m = read(b"NOFF\n3 1 0\n0 0 0 0 0 1 2 0 0\n0 0 1 0 2 0\n0 0 1\n3 0 1 2\n", "off")
    assert m.V.tolist() == [[0, 0, 0], [2, 0, 0], [0, 2, 0]] and m.log.unread_properties == ["vertex normals (N)"]
    # a tristrips element's own other properties are named as not read
    strips = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
              b"element tristrips 1\nproperty list int int vertex_indices\nproperty uchar q\nend_header\n"
              b"0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3 7\n")
    assert read(strips, "ply").log.unread_properties == ["tristrips q"]
    # ... and what those fixes first got wrong: a corner on the 'outer loop' line is a corner; an
    # 'end_header' among a comment's words is not the header's end; an OFF of no vertices says so
    loopline = stl.replace(b"   vertex 5 5 5\n", b"")
    loopline = loopline.replace(b"  outer loop\n   vertex 1 1 0", b"  outer loop vertex 1 1 0")
    assert read(loopline.replace(b"   vertex 1 0 0\n  endloop\n endfacet\nendsolid",
                                 b"   vertex 1 0 0\n   vertex 0 0 1\n  endloop\n endfacet\nendsolid"),
                "stl").F.shape == (2, 3)
    commented = ply.replace(b"format ascii 1.0\n", b"format ascii 1.0\ncomment all up to end_header is text\n")
    assert read(commented, "ply").F.tolist() == [[0, 1, 2]]
    with pytest.raises(InputError, match="mesh has no vertices"):
        read(b"COFF\n0 0 0\n", "off")
    # a header line naming a solid 'solid_1 facet', an endsolid's name after endfacet on one line
    one = (b"solid_1 facet 2\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
           b"   vertex 0 1 0\n  endloop\n endfacet endsolid a facet\n")
    assert read(one, "stl").F.shape == (1, 3)
    # an ASCII PLY whose lines end in CR alone: '1_0' had still been read as 10
    with pytest.raises(InputError, match="'_' inside a number"):
        read(ply.replace(b"\n1 0 0\n", b"\n1_0 0 0\n").replace(b"\n", b"\r"), "ply")
