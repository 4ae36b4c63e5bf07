"""Reading animations: ``.npz`` members and frame folders (geoproc/animation.py)."""

from __future__ import annotations

import io
import re
import zipfile

import numpy as np
import pytest

from geoproc.animation import load_animation
from geoproc.errors import InputError
from geoproc.mesh import Mesh, save_mesh
from tests.conftest import load_fixture_module


@pytest.fixture(scope="module")
def wave():
    return load_fixture_module("denoise_fixtures").wave_animation(4)


def _npz(path, extra_members=(), **arrays):
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())
    with zipfile.ZipFile(path, "a") as z:
        for name, data in extra_members:
            z.writestr(name, data)
    return path


def test_members_that_are_not_numeric_arrays_are_left_out(wave, tmp_path):
    V, F = wave
    p = _npz(tmp_path / "a.npz", [("README.txt", "exported by X\n")], vertices=V, faces=F,
             meta=np.array([{"units": "m"}], dtype=object), tag=np.ones(V.shape[:2]))
    anim = load_animation(p)
    assert np.array_equal(anim.V, V) and np.array_equal(anim.F, F) and sorted(anim.fields) == ["tag"]
    # what is left out is named (it was dropped without a word), so the command line can say so
    assert sorted(anim.unread) == ["README.txt (not a .npy array)", "meta (an object array (pickled Python objects))"]
    p = _npz(tmp_path / "b.npz", vertices=V, faces=F, scale=np.arange(3.0), names=np.array(["a", "b"]))
    assert sorted(load_animation(p).unread) == ["names (2,)", "scale (3,)"]
    # a complex array shaped as a field was left out as "not carried" (the outlier flags with it)
    p = _npz(tmp_path / "c.npz", vertices=V, faces=F, outlier=np.zeros(V.shape[:2], complex))
    with pytest.raises(InputError, match="'outlier' must hold real numbers, got dtype complex128"):
        load_animation(p)
    # any other complex field is left out and named, as other members that do not travel
    p = _npz(tmp_path / "d.npz", vertices=V, faces=F, phase=np.zeros(V.shape[:2], complex))
    assert load_animation(p).unread == [f"phase {V.shape[:2]} complex"]


@pytest.mark.parametrize("case,message", [
    ("object", "'vertices' is an object array (pickled Python objects)"),
    ("text", "'faces' is not a .npy array"),
    ("empty", "file is empty"),
    ("npy", "not a .npz archive (a single array"),
])
def test_unreadable_geometry_is_named(wave, tmp_path, case, message):
    V, F = wave
    p = tmp_path / "b.npz"
    if case == "object":
        _npz(p, vertices=V.astype(object), faces=F)
    elif case == "text":
        _npz(p, [("faces", "0 1 2\n")], vertices=V)
    elif case == "empty":
        p.write_bytes(b"")
    else:
        buf = io.BytesIO()
        np.save(buf, V)
        p.write_bytes(buf.getvalue())
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_animation(p)


def test_hidden_files_and_subfolders_are_not_frames(wave, tmp_path):
    V, F = wave
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, Vk in enumerate(V):
        save_mesh(folder / f"frame{k}.ply", Mesh(Vk, F))
    save_mesh(folder / ".frame3.ply.bak.ply", Mesh(V[3] + 5.0, F))  # an editor's backup
    (folder / "._frame2.ply").write_bytes(b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X        ")
    (folder / "zz.ply").mkdir()
    anim = load_animation(folder)
    assert np.array_equal(anim.V, V)
    assert [f.rsplit("/", 1)[-1] for f in anim.frame_files] == [f"frame{k}.ply" for k in range(len(V))]


def test_frame_properties_a_folder_does_not_carry_are_named(wave, tmp_path):
    # face properties, vertex properties missing from a frame (an OBJ frame has none) and
    # list properties were dropped without a word: an outlier flag could vanish that way
    V, F = wave
    folder = tmp_path / "frames"
    folder.mkdir()
    n, m = V.shape[1], len(F)
    for k, Vk in enumerate(V):
        fields = {"outlier": np.zeros(n), "tag": np.full(n, float(k))} | ({"only0": np.ones(n)} if k == 0 else {})
        save_mesh(folder / f"frame{k}.ply", Mesh(Vk, F, fields, {"quality": np.ones(m)}))
    anim = load_animation(folder)
    assert sorted(anim.fields) == ["outlier", "tag"]
    assert anim.unread == ["vertex only0 (not in every frame)", "face quality"]
    save_mesh(folder / "frame1.obj", Mesh(V[1], F))
    (folder / "frame1.ply").unlink()
    anim = load_animation(folder)
    assert anim.fields == {} and anim.unread[:3] == ["vertex outlier (not in every frame)",
                                                      "vertex tag (not in every frame)",
                                                      "vertex only0 (not in every frame)"]
    for k in range(len(V)):  # the same fields in every frame, nothing else: nothing to name
        (folder / f"frame{k}.obj").unlink(missing_ok=True)
        save_mesh(folder / f"frame{k}.ply", Mesh(V[k], F, {"outlier": np.zeros(n)}))
    assert load_animation(folder).unread == []


@pytest.mark.parametrize("bad", [lambda n: n, lambda n: -1])
def test_npz_face_index_just_out_of_range_is_refused(wave, tmp_path, bad):
    V, F = wave
    n = V.shape[1]
    F = F.copy()
    F[-1] = [0, 1, bad(n)]  # n is one past the last vertex
    p = _npz(tmp_path / "f.npz", vertices=V, faces=F)
    message = (f"face index out of range: face {len(F) - 1} references vertex {bad(n)}, "
               f"but there are {n} vertices (0-based)")
    with pytest.raises(InputError, match=re.escape(message)):
        load_animation(p)


def test_a_moving_cloud_may_store_its_empty_faces_as_floats(wave, tmp_path):
    # np.zeros((0, 3)), the plain way to write "no faces", is float64: it had been refused
    V, _ = wave
    anim = load_animation(_npz(tmp_path / "c.npz", vertices=V, faces=np.zeros((0, 3))))
    assert anim.F.shape == (0, 3) and anim.F.dtype.kind == "i" and np.array_equal(anim.V, V)
    with pytest.raises(InputError, match=re.escape("'faces' has shape (1, 3) (float64); expected (m, 3) integers")):
        load_animation(_npz(tmp_path / "f.npz", vertices=V, faces=np.zeros((1, 3))))


@pytest.mark.parametrize("member", ["vertices", "outlier"])
def test_a_damaged_member_is_refused(wave, tmp_path, member):
    # a .npy member cut short had been called an object array, and a cut 'outlier' member
    # was left out: the outlier scores then had no precision, recall or F1, with exit 0
    V, F = wave
    arrays = {"vertices": V, "faces": F, "outlier": np.zeros(V.shape[:2])}
    buf = io.BytesIO()
    np.save(buf, arrays[member])
    p = _npz(tmp_path / "a.npz", [(f"{member}.npy", buf.getvalue()[:-40])],
             **{k: v for k, v in arrays.items() if k != member})
    with pytest.raises(InputError, match=f"member '{member}' is damaged"):
        load_animation(p)


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="needs named pipes")
def test_a_frame_that_is_not_a_regular_file_is_refused(wave, tmp_path):
    # a pipe named like a frame had blocked the read until killed
    import os

    V, F = wave
    for t in range(2):
        save_mesh(tmp_path / f"f{t}.ply", Mesh(V[t], F))
    os.mkfifo(tmp_path / "f9.ply")
    with pytest.raises(InputError, match="f9.ply: is not a regular file"):
        load_animation(tmp_path)
    os.remove(tmp_path / "f9.ply")
    os.symlink(tmp_path / "gone.ply", tmp_path / "f8.ply")  # a dangling link: named by the read, as before
    with pytest.raises(InputError, match="f8.ply"):
        load_animation(tmp_path)


def test_frames_read_back_as_the_animation(wave, tmp_path):
    from geoproc.animation import Animation, animation_to_frames

    V, F = wave
    flags = (np.arange(V.shape[0] * V.shape[1]).reshape(V.shape[:2]) % 7 == 0).astype(np.float64)
    anim = Animation(V, F, {"outlier": flags, "speed": np.linspace(0, 1, flags.size).reshape(flags.shape)})
    folder = tmp_path / "frames"
    folder.mkdir()
    for name, data in animation_to_frames(anim):
        (folder / name).write_bytes(data)
    back = load_animation(folder)
    assert [p.rsplit("/", 1)[1] for p in back.frame_files] == [f"frame_{t:04d}.ply" for t in range(len(V))]
    assert np.array_equal(back.V, V) and np.array_equal(back.F, F) and back.unread == []
    assert sorted(back.fields) == ["outlier", "speed"]
    assert all(np.array_equal(back.fields[k], anim.fields[k]) for k in anim.fields)


def test_frame_names_sort_in_frame_order():
    from geoproc.animation import frame_file_names, natural_key

    assert frame_file_names(3) == ["frame_0000.ply", "frame_0001.ply", "frame_0002.ply"]
    names = frame_file_names(10001)
    assert names[-1] == "frame_10000.ply" and names[9999] == "frame_09999.ply"
    assert sorted(names) == names == sorted(names, key=natural_key)


def test_a_moving_cloud_has_frames_without_faces(tmp_path):
    from geoproc.animation import Animation, animation_to_frames

    V = np.random.default_rng(0).normal(size=(3, 20, 3))
    for name, data in animation_to_frames(Animation(V, np.zeros((0, 3), dtype=np.int64))):
        (tmp_path / name).write_bytes(data)
    back = load_animation(tmp_path)
    assert np.array_equal(back.V, V) and back.F.shape == (0, 3)


def test_fields_no_ply_property_can_name_are_refused(wave, tmp_path):
    from geoproc.animation import Animation, animation_to_frames, unwritable_frame_fields

    V, F = wave
    fields = {k: np.zeros(V.shape[:2]) for k in ("ok_1", "x", "two words", "1st", "a-b", "é", "", "end_header")}
    anim = Animation(V, F, fields)
    assert unwritable_frame_fields(anim) == ["x", "two words", "é", "", "end_header"]
    with pytest.raises(ValueError, match="'x' cannot be a PLY vertex property"):
        animation_to_frames(anim)
    # words a PLY header takes round-trip through a frame (only identifiers had been taken)
    fields = {k: np.arange(V.shape[0] * V.shape[1], dtype=float).reshape(V.shape[:2]) + i
              for i, k in enumerate(("1st", "a-b", "w.2"))}
    tmp = tmp_path / "frames"
    tmp.mkdir()
    for name, data in animation_to_frames(Animation(V, F, fields)):
        (tmp / name).write_bytes(data)
    back = load_animation(tmp)
    assert sorted(back.fields) == ["1st", "a-b", "w.2"]
    assert all(np.array_equal(back.fields[k], v) for k, v in fields.items())


def test_foreign_and_stale_frame_files(tmp_path):
    from geoproc.animation import foreign_frame_files, stale_frame_files

    for name in ("frame_0000.ply", "frame_0001.ply", "frame_12.ply", "notes.txt", ".hidden.obj", "a.OBJ",
                 "frame_0000.obj"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "sub.ply").mkdir()
    assert foreign_frame_files(str(tmp_path)) == ["a.OBJ", "frame_0000.obj"]
    assert foreign_frame_files(str(tmp_path / "missing")) == []
    assert stale_frame_files(str(tmp_path), ["frame_0000.ply"]) == ["frame_0001.ply", "frame_12.ply"]


def test_faces_per_frame_must_be_one_per_frame(wave, tmp_path):
    V, F = wave
    # (frames, m, 3) faces, the same for every frame, read as F
    assert np.array_equal(load_animation(_npz(tmp_path / "a.npz", vertices=V, faces=np.stack([F] * len(V)))).F, F)
    # one copy fewer than the frames had passed without a word
    with pytest.raises(InputError, match=re.escape(f"{len(V) - 1} frames of faces for {len(V)} of vertices")):
        load_animation(_npz(tmp_path / "b.npz", vertices=V, faces=np.stack([F] * (len(V) - 1))))
