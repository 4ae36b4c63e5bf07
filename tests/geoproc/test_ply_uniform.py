"""The vectorized PLY reader and writer against plyfile, the reference."""

from __future__ import annotations

import io

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from geoproc.errors import InputError
from geoproc.mesh import Mesh, mesh_to_bytes, read_mesh_bytes
from geoproc.mesh import read as read_module
from geoproc.mesh.ply_uniform import read_uniform_ply
from geoproc.mesh.write import _scalar_columns

FORMATS = [("binary", "<"), ("binary", ">"), ("ascii", "=")]


def _plyfile_bytes(elements: list, fmt: str, order: str) -> bytes:
    buf = io.BytesIO()
    PlyData(elements, text=fmt == "ascii", byte_order=order, comments=["test"]).write(buf)
    return buf.getvalue()


def _plyfile_read(data: bytes) -> dict:
    return {e.name: e.data for e in PlyData.read(io.BytesIO(data)).elements}


def _faces(rng, m: int, k: int, n: int, index_type: str, extra: bool) -> PlyElement:
    """A face element: index lists of length k, scalars before and after the list when ``extra``."""
    fields = ([("flag", "u1")] if extra else []) + [("vertex_indices", index_type, (k,))]
    fields += [("quality", "f4"), ("label", "i2")] if extra else []
    rows = np.empty(m, dtype=fields)
    rows["vertex_indices"] = rng.integers(0, n, size=(m, k))
    if extra:
        rows["flag"] = rng.integers(0, 256, m)
        rows["quality"] = rng.normal(size=m)
        rows["label"] = rng.integers(-300, 300, m)
    return PlyElement.describe(rows, "face", len_types={"vertex_indices": "u1" if extra else "i4"})


def _vertices(rng, n: int) -> PlyElement:
    rows = np.empty(n, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("red", "u1"), ("t", "f8"), ("id", "u4"),
                              ("label", "i1")])  # plyfile writes i1 as "char": signed
    for c in ("x", "y", "z", "t"):
        rows[c] = rng.normal(size=n) * 1e3
    rows["red"] = rng.integers(0, 256, n)
    rows["label"] = rng.integers(-128, 128, n)
    rows["id"] = rng.integers(0, 2**32 - 1, n, dtype=np.uint64)
    return PlyElement.describe(rows, "vertex")


def _same_elements(fast: dict, ref: dict) -> None:
    assert list(fast) == list(ref)
    for name, ref_rows in ref.items():
        rows = fast[name]
        assert rows.dtype.names == ref_rows.dtype.names, name
        for field in ref_rows.dtype.names:
            want = ref_rows[field]
            if want.dtype == object:  # plyfile's lists
                want = np.stack(list(want)) if len(want) else np.zeros((0, 0))
            got = np.asarray(rows[field])
            assert got.dtype.kind == want.dtype.kind and got.dtype.itemsize == want.dtype.itemsize, field
            assert np.array_equal(got, want, equal_nan=True), (name, field)


@pytest.mark.parametrize("fmt,order", FORMATS)
@pytest.mark.parametrize("k,index_type,extra", [(3, "i4", False), (3, "u4", True), (4, "i4", True),
                                                (3, "f4", False), (3, "u2", True)])
def test_uniform_layouts_read_as_plyfile_reads_them(fmt, order, k, index_type, extra):
    rng = np.random.default_rng(k)
    n = 40
    elements = [_vertices(rng, n), _faces(rng, 70, k, n, index_type, extra)]
    if extra:  # an element of scalars after the faces (as MeshLab writes 'edge' or a camera)
        cam = np.zeros(2, dtype=[("view_px", "f4"), ("view_py", "f4")])
        cam["view_px"] = [1.5, -2.0]
        elements.append(PlyElement.describe(cam, "camera"))
    data = _plyfile_bytes(elements, fmt, order)
    fast = read_uniform_ply(data)
    assert fast is not None
    _same_elements(fast, _plyfile_read(data))


@pytest.mark.parametrize("fmt,order", FORMATS)
def test_point_cloud_and_empty_faces(fmt, order):
    rng = np.random.default_rng(1)
    empty = np.zeros(0, dtype=[("vertex_indices", "i4", (3,))])
    for elements in ([_vertices(rng, 5)],
                     [_vertices(rng, 5), PlyElement.describe(empty, "face", len_types={"vertex_indices": "u1"})]):
        data = _plyfile_bytes(elements, fmt, order)
        fast = read_uniform_ply(data)
        assert fast is not None
        assert len(fast["vertex"]) == 5 and len(fast.get("face", [])) == 0


def _mixed_faces(n: int) -> PlyElement:
    rows = np.empty(2, dtype=[("vertex_indices", object)])
    rows["vertex_indices"] = [np.array([0, 1, 2], "i4"), np.array([0, 1, 2, 3], "i4")]
    return PlyElement.describe(rows, "face")


@pytest.mark.parametrize("fmt,order", FORMATS)
def test_layouts_left_to_plyfile(fmt, order):
    rng = np.random.default_rng(2)
    v = _vertices(rng, 6)
    # faces of mixed lengths (a triangle and a quad)
    mixed = _plyfile_bytes([v, _mixed_faces(6)], fmt, order)
    assert read_uniform_ply(mixed) is None
    # a list property outside the face element
    lists = np.empty(6, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("nb", "i4", (2,))])
    lists["nb"] = 0
    listed = _plyfile_bytes([PlyElement.describe(lists, "vertex")], fmt, order)
    assert read_uniform_ply(listed) is None
    # a file cut short, and one with bytes past its last element
    good = _plyfile_bytes([v, _faces(rng, 4, 3, 6, "i4", False)], fmt, order)
    assert read_uniform_ply(good) is not None
    assert read_uniform_ply(good[:-3]) is None
    assert read_uniform_ply(good + (b"9 9 9 9\n" if fmt == "ascii" else b"\0")) is None


def test_ascii_rows_must_be_single_lines_of_integers():
    text = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert read_uniform_ply(text) is not None
    assert read_uniform_ply(text.replace(b"3 0 1 2", b"3 0 1\n2")) is None  # a row over two lines
    assert read_uniform_ply(text.replace(b"3 0 1 2", b"3 0 1.0 2")) is None  # plyfile refuses 1.0 as int
    assert read_uniform_ply(text.replace(b"ascii 1.0", b"ascii 2.0")) is None
    assert read_uniform_ply(text.replace(b"\n", b"\r\n")) is None


def test_quads_become_the_fans_plyfile_path_gives(monkeypatch):
    rng = np.random.default_rng(3)
    data = _plyfile_bytes([_vertices(rng, 30), _faces(rng, 20, 4, 30, "i4", True)], "binary", "<")
    fast = read_mesh_bytes(data, "ply", "q.ply", clean=False)
    monkeypatch.setattr(read_module, "read_uniform_ply", lambda data: None)
    slow = read_mesh_bytes(data, "ply", "q.ply", clean=False)
    assert fast.F.shape == (40, 3) and np.array_equal(fast.F, slow.F) and np.array_equal(fast.V, slow.V)
    assert fast.log.triangulated_polygons == slow.log.triangulated_polygons == 20
    assert fast.vertex_fields.keys() == slow.vertex_fields.keys()
    for name in ("flag", "quality", "label"):
        assert np.array_equal(fast.face_fields[name], slow.face_fields[name])


def test_float_index_lists_are_checked_on_the_fast_path():
    rows = np.zeros(1, dtype=[("vertex_indices", "f4", (3,))])
    rows["vertex_indices"] = [[0, 1, 1.5]]
    vert = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    data = _plyfile_bytes([PlyElement.describe(vert, "vertex"), PlyElement.describe(rows, "face")], "binary", "<")
    assert read_uniform_ply(data) is not None
    with pytest.raises(InputError, match="face 0 has a non-integer vertex index 1.5"):
        read_mesh_bytes(data, "ply", "f.ply")


def _plyfile_written(mesh: Mesh, binary: bool) -> bytes:
    """The bytes plyfile writes for the layout geoproc writes (doubles, uchar/int face lists)."""
    cols = [("x", mesh.V[:, 0]), ("y", mesh.V[:, 1]), ("z", mesh.V[:, 2])]
    cols += _scalar_columns(mesh.vertex_fields, len(mesh.V))
    vdata = np.empty(len(mesh.V), dtype=[(name, "f8") for name, _ in cols])
    for name, values in cols:
        vdata[name] = values
    elements = [PlyElement.describe(vdata, "vertex")]
    if len(mesh.F):
        fcols = _scalar_columns(mesh.face_fields, len(mesh.F))
        fdata = np.empty(len(mesh.F), dtype=[("vertex_indices", "i4", (3,))] + [(c, "f8") for c, _ in fcols])
        fdata["vertex_indices"] = mesh.F
        for name, values in fcols:
            fdata[name] = values
        elements.append(PlyElement.describe(fdata, "face", len_types={"vertex_indices": "u1"}))
    buf = io.BytesIO()
    PlyData(elements, text=not binary, byte_order="<", comments=["geoproc"]).write(buf)
    return buf.getvalue()


@pytest.mark.parametrize("binary", [True, False])
def test_writer_gives_the_bytes_plyfile_writes(binary):
    rng = np.random.default_rng(4)
    V = rng.normal(size=(50, 3)) * 10.0 ** rng.integers(-300, 300, size=(50, 3))
    V[0, 0] = np.nan
    F = rng.integers(0, 50, size=(90, 3))
    fields = {"d": rng.normal(size=50), "vec": rng.normal(size=(50, 2))}
    fields["d"][1] = -np.inf
    mesh = Mesh(V, F, fields, {"q": rng.normal(size=90)})
    assert mesh_to_bytes(mesh, "ply", binary=binary) == _plyfile_written(mesh, binary)
    cloud = Mesh(V[1:], np.zeros((0, 3), dtype=np.int64), {}, {})
    assert mesh_to_bytes(cloud, "ply", binary=binary) == _plyfile_written(cloud, binary)


@pytest.mark.parametrize("writer", ["meshlab binary", "meshlab ascii", "libigl", "trimesh binary", "trimesh ascii"])
def test_peer_written_files_take_the_vectorized_path(tmp_path, make_fixtures, writer):
    import igl
    import pymeshlab
    import trimesh

    V, F = make_fixtures.icosphere(2)
    path = tmp_path / "peer.ply"
    if writer.startswith("meshlab"):
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(V, F))
        ms.save_current_mesh(str(path), binary=writer.endswith("binary"))
    elif writer == "libigl":
        igl.write_triangle_mesh(str(path), V, F)
    else:
        trimesh.Trimesh(V, F, process=False).export(path, encoding=writer.split()[1])
    data = path.read_bytes()
    fast = read_uniform_ply(data)
    assert fast is not None
    _same_elements(fast, _plyfile_read(data))
    mesh = read_mesh_bytes(data, "ply", str(path), clean=False)
    assert np.array_equal(mesh.F, F) and np.allclose(mesh.V, V, atol=1e-6)


def test_fields_read_without_clean_up_are_writable_arrays(tmp_path, make_fixtures):
    V, F = make_fixtures.icosphere(1)
    path = tmp_path / "f.ply"
    path.write_bytes(mesh_to_bytes(Mesh(V, F, {"d": np.arange(len(V), dtype=float)}, {"q": np.ones(len(F))}), "ply"))
    mesh = read_mesh_bytes(path.read_bytes(), "ply", str(path), clean=False)
    for values in (mesh.V, mesh.F, mesh.vertex_fields["d"], mesh.face_fields["q"]):
        assert values.flags.writeable and values.flags.c_contiguous
    mesh.vertex_fields["d"][0] = -1.0


@pytest.mark.parametrize("count", [-1, 200, 2**31 - 1])
def test_a_first_face_count_that_cannot_fit_goes_to_plyfile(count):
    vert = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    rows = np.zeros(1, dtype=[("vertex_indices", "i4", (3,))])
    data = _plyfile_bytes([PlyElement.describe(vert, "vertex"),
                           PlyElement.describe(rows, "face", len_types={"vertex_indices": "i4"})], "binary", "<")
    head = data.index(b"end_header\n") + len(b"end_header\n") + 3 * 12
    bad = data[:head] + np.array([count], "<i4").tobytes() + data[head + 4:]
    assert read_uniform_ply(bad) is None  # plyfile reads it (a count of -1 takes what is left)
    if count > 0:
        with pytest.raises(InputError, match="unparseable PLY: element 'face': row 0"):
            read_mesh_bytes(bad, "ply", "c.ply")


_ASCII_HEAD = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty double y\n"
               b"property uchar red\nproperty float z\nelement face 1\n"
               b"property list uchar int vertex_indices\nend_header\n")
_ASCII_BODY = b"0 0 7 0\n1 0 8 0\n0 1 9 0\n3 0 1 2\n"


@pytest.mark.parametrize("body", [
    _ASCII_BODY.replace(b" ", b"\t"),
    b"  0  0 7 0  \n1 0   8 0\n0 1 9 0\n 3 0 1 2 \n",
    _ASCII_BODY.replace(b"\n", b"\r\n"),
    _ASCII_BODY.replace(b"0 0 7 0", b"0\x0b0 7 0"),
    _ASCII_BODY[:-1],  # no newline after the last row
    b"nan -inf 7 1e3\n.5 5. 8 +2\nInfinity -0 9 1E-3\n3 +0 1 2\n",
], ids=["tabs", "spaces", "crlf", "vertical tab", "no final newline", "number spellings"])
def test_ascii_separators_and_number_spellings_read_as_plyfile_reads_them(body):
    data = _ASCII_HEAD + body
    _same_elements(read_uniform_ply(data), _plyfile_read(data))


@pytest.mark.parametrize("old,new", [
    (b"0 0 7 0", b"0 0 7.0 0"),  # an integer column holding 7.0
    (b"0 0 7 0", b"0 0 1e1 0"),
    (b"3 0 1 2", b"3 0 1_0 2"),  # Python's int() reads 1_0, plyfile does not
    (b"0 0 7 0", b"0x1p3 0 7 0"),  # C's strtod reads hexadecimal floats, plyfile does not
    (b"0 0 7 0", b"nan(1) 0 7 0"),
    (b"0 0 7 0", b"infin 0 7 0"),
    (b"0 0 7 0", b"--1 0 7 0"),
    (b"0 0 7 0", b"0 0 256 0"),  # beyond uchar
    (b"3 0 1 2", b"3 0 1 99999999999999999999"),  # beyond int64, where the integer reading saturates
    (b"0 0 7 0", b"0\x1c0 7 0"),  # a control character that Python's split treats as a space
    (b"0 0 7 0", b"0 0 7 0\xc2\xa0"),  # not ASCII
    (b"3 0 1 2\n", b"3 0 1 2\nx\n"),  # text after the last row
])
def test_ascii_values_outside_the_plain_spellings_go_to_plyfile(old, new):
    assert read_uniform_ply(_ASCII_HEAD + _ASCII_BODY) is not None
    assert read_uniform_ply(_ASCII_HEAD + _ASCII_BODY.replace(old, new)) is None


def test_blank_lines_after_the_last_ascii_row_are_read_as_plyfile_reads_them():
    # they sent an 18.6 MB file to plyfile (0.6 s -> 8 s)

    for tail in (b"\n", b"\n \t\r\n\n"):
        data = _ASCII_HEAD + _ASCII_BODY + tail
        got = read_uniform_ply(data)
        ref = PlyData.read(io.BytesIO(data))
        assert got is not None
        for name in ("vertex", "face"):
            for prop in got[name].dtype.names:
                assert np.array_equal(np.asarray(got[name][prop]).tolist(),
                                      np.array(ref[name].data[prop].tolist()).tolist())
