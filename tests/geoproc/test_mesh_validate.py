"""Array checks shared by the library's entry points (geoproc.mesh.validate.mesh_arrays)
and the Mesh container's shape checks."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.errors import InputError
from geoproc.mesh import Mesh
from geoproc.mesh.validate import mesh_arrays

V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
F = np.array([[0, 1, 2], [1, 3, 2]])


def test_lists_dtypes_and_layouts_give_float64_and_int64_rows():
    for Vin, Fin in ((V.tolist(), F.tolist()), (V.astype(np.float32), F.astype(np.uint16)),
                     (np.asfortranarray(V), F.T.copy().T), (np.c_[V, V][:, :3], F)):
        Vo, Fo = mesh_arrays(Vin, Fin)
        assert Vo.dtype == np.float64 and Fo.dtype == np.int64
        assert Vo.flags.c_contiguous and Fo.flags.c_contiguous
        assert np.array_equal(Fo, F) and np.allclose(Vo, V)
    Vo, Fo = mesh_arrays(V, [], allow_point_cloud=True)
    assert Fo.shape == (0, 3)


@pytest.mark.parametrize("Vin, Fin, message", [
    (V[:, :2], F, "shape (n, 3), not (4, 2)"),
    (V + 1j, F, "real numbers"),
    (np.where(np.arange(12).reshape(4, 3) == 4, np.nan, V), F,
     "1 vertices have non-finite coordinates (first: vertex 1)"),
    (V, F.astype(float), "integers, not float64"),
    (V, np.c_[F, F[:, :1]], "shape (m, 3) (triangles), not (2, 4)"),
    (V, np.r_[F, [[0, 1, -1]]], "face 2 references vertex -1"),
    (V, np.r_[F, [[0, 1, 4]]], "face 2 references vertex 4, but there are 4 vertices"),
    (V, [], "mesh has no faces (vertices only; store a point cloud as PLY)"),
])
def test_bad_arrays_are_named(Vin, Fin, message):
    with pytest.raises(InputError) as exc:
        mesh_arrays(Vin, Fin)
    assert message in str(exc.value)


def test_mesh_container_refuses_other_shapes_instead_of_reshaping():
    with pytest.raises(ValueError, match="shape"):
        Mesh(np.arange(12.0).reshape(6, 2), F)
    with pytest.raises(ValueError, match="shape"):
        Mesh(np.zeros((20, 3)), np.arange(12).reshape(3, 4))
    with pytest.raises(ValueError, match="integer"):
        Mesh(V, [[0, 1, 2.7]])
    assert Mesh(V, [[0.0, 1.0, 2.0]]).F.dtype == np.int64  # integral floats are indices
    assert Mesh(np.zeros((0, 3)), []).F.shape == (0, 3)


@pytest.mark.parametrize("face", [[3, 4, 3], [3, 3, 4], [3, 4, 4]])
def test_a_face_repeating_a_vertex_anywhere_is_refused(face):
    from geoproc.mesh.validate import require_edge_manifold

    with pytest.raises(InputError, match=r"1 face repeats a vertex \(first: face 1, vertices "):
        require_edge_manifold(np.array([[0, 1, 2], face]), "m.obj")


def test_faces_that_merging_collapses_are_counted_and_named_in_the_refusal():
    import trimesh

    from geoproc.mesh.clean import clean_mesh
    from geoproc.mesh.validate import require_edge_manifold

    ico = trimesh.creation.icosphere(1)
    Vs, Fs = ico.vertices.copy(), ico.faces.copy()
    a, b = Fs[3, 0], Fs[3, 1]
    Vs[b] = Vs[a]  # an edge of length zero: its two faces collapse once its ends merge
    Fs = np.vstack([Fs, [[a, a, b]]])  # and one face the file itself stores with a repeated vertex
    m = clean_mesh(Mesh(Vs, Fs))
    both = np.flatnonzero(((Fs == a) | (Fs == b)).sum(axis=1) >= 2)[:-1]
    assert m.log.merged_vertices == 1 and m.log.collapsed_faces == 2
    k = int(both[0])
    assert len(both) == 2 and m.log.first_collapsed_face == k
    with pytest.raises(InputError, match=rf"^m.ply: 3 faces repeat a vertex \(first: face {k}, vertices .*\); merging "
                                         rf"coincident positions on loading made 2 of them \(first: face {k}\) "
                                         r"\(--no-clean keeps the stored vertices\); x$"):
        require_edge_manifold(m.F, "m.ply", "; x", m.log)
    alone = clean_mesh(Mesh(Vs, Fs[:-1]))
    with pytest.raises(InputError, match=rf"2 faces repeat a vertex \(first: face {k}, vertices .*\); merging "
                                         r"coincident positions on loading made all of them \(--no-clean"):
        require_edge_manifold(alone.F, "m.ply", "", alone.log)
    stored = clean_mesh(Mesh(ico.vertices, np.vstack([ico.faces, [[a, a, b]]])))  # nothing merged
    assert stored.log.collapsed_faces == 0 and stored.log.first_collapsed_face == -1
    with pytest.raises(InputError, match=r"1 face repeats a vertex \(first: face 80, vertices \d+ \d+ \d+\)$"):
        require_edge_manifold(stored.F, "m.ply", "", stored.log)
