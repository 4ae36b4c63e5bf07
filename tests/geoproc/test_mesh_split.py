"""Splitting non-manifold vertices, one vertex per fan of faces."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.mesh.clean import split_nonmanifold_vertices
from geoproc.mesh.topology import nonmanifold_edges, vertex_fans


def _same_corners(Fa: np.ndarray, Fb: np.ndarray) -> bool:
    """Whether two face lists put the same corners into the same vertices
    (a one-to-one map between their vertex ids)."""
    pairs = set(zip(Fa.reshape(-1).tolist(), Fb.reshape(-1).tolist(), strict=True))
    return len(pairs) == len(np.unique(Fa)) == len(np.unique(Fb))


def _meshlab_split(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MeshLab's split, run until the vertex count stops changing (one run
    leaves part of a vertex with three or more fans joined)."""
    pymeshlab = pytest.importorskip("pymeshlab")
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(V, F))
    count = -1
    while ms.current_mesh().vertex_number() != count:
        count = ms.current_mesh().vertex_number()
        ms.meshing_repair_non_manifold_vertices(vertdispratio=0)
    m = ms.current_mesh()
    return m.vertex_matrix(), m.face_matrix()


def test_fans_get_their_own_vertices_as_meshlab_splits_them(make_fixtures):
    V, F = make_fixtures.icosphere(1)
    n = len(V)
    # a second sphere sharing vertex 0 (two fans there), and a fan of two
    # triangles pinned at vertex 5 by a third, separate triangle
    V2 = np.concatenate([V, V + [0.0, 0.0, -2.0]])
    V2[n] = V[0]
    F2 = np.concatenate([F, np.where(F == 0, 0, F + n)])
    extra = len(V2)
    V2 = np.concatenate([V2, V[5] + np.array([[3.0, 0, 0], [3.0, 1.0, 0]])])
    F2 = np.concatenate([F2, [[5, extra, extra + 1]]])
    assert (vertex_fans(F2, len(V2)) > 1).sum() == 2
    SV, SF, source = split_nonmanifold_vertices(V2, F2)
    assert len(SV) == len(V2) + 2 and (vertex_fans(SF, len(SV)) <= 1).all()  # (vertex n is unused)
    assert np.array_equal(source[: len(V2)], np.arange(len(V2)))  # one-fan vertices keep their ids
    assert sorted(source[len(V2):].tolist()) == [0, 5]
    assert np.array_equal(source[SF], F2) and np.array_equal(SV, V2[source])
    assert len(SF) == len(F2)
    MV, MF = _meshlab_split(V2, F2)
    assert len(MV) == len(SV) and _same_corners(SF, MF)
    np.testing.assert_array_equal(MV[MF], SV[SF])


def test_a_manifold_mesh_and_a_non_manifold_edge_stay_as_they_are(make_fixtures):
    V, F = make_fixtures.icosphere(2)
    F[0] = F[0, ::-1]  # an inconsistent orientation is not a reason to split (igl's split_nonmanifold would)
    SV, SF, source = split_nonmanifold_vertices(V, F)
    assert np.array_equal(SF, F) and np.array_equal(source, np.arange(len(V)))
    fin = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    SV, SF, source = split_nonmanifold_vertices(np.eye(5, 3), fin)
    assert np.array_equal(SF, fin) and len(nonmanifold_edges(SF)) == 1


def test_real_scans_split_as_meshlab_splits_them(shared_data):
    from geoproc.mesh import load_mesh

    # the teapot as stored (its UV seams not merged) has vertices with up to four fans
    for name, clean in (("meshes/cow.obj", True), ("denoise/real-scans/angel.obj", True),
                        ("meshes/teapot.obj", False)):
        m = load_mesh(shared_data / name, clean=clean)
        bad = int((vertex_fans(m.F, len(m.V)) > 1).sum())
        SV, SF, source = split_nonmanifold_vertices(m.V, m.F)
        assert bad > 0 and len(SV) > len(m.V) and (vertex_fans(SF, len(SV)) == 1).all()
        MV, MF = _meshlab_split(m.V, m.F)
        assert len(MV) == len(SV) and _same_corners(SF, MF), name
