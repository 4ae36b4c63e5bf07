"""Consistent face orientation (geoproc.mesh.orientation) against libigl's
bfs_orient and the directed-edge rule."""

from __future__ import annotations

import igl
import numpy as np

from geoproc.mesh.orientation import consistent_orientation


def _directed_edge_repeats(F):
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return len(E) - len(np.unique(E, axis=0))


def test_consistent_faces_come_back_as_they_are(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    Fo, flip = consistent_orientation(F)
    assert np.array_equal(Fo, F) and not flip.any()
    assert np.array_equal(np.asarray(igl.bfs_orient(F)[0]), F)  # what the search would give


def test_reversed_faces_are_turned_back(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    turn = np.random.default_rng(1).random(len(F)) < 0.3
    turn[0] = False
    G = F.copy()
    G[turn] = G[turn][:, ::-1]
    Fo, flip = consistent_orientation(G)
    assert _directed_edge_repeats(G) > 0 and _directed_edge_repeats(Fo) == 0
    assert np.array_equal(flip, turn)
    assert np.allclose(igl.doublearea(V, Fo), igl.doublearea(V, F))
    # with the first face among them, the search kept its orientation and counted all the
    # other faces as turned (70 % instead of 30 %): each patch keeps its majority's
    turn[0] = True
    G = F.copy()
    G[turn] = G[turn][:, ::-1]
    Fo, flip = consistent_orientation(G)
    assert np.array_equal(flip, turn) and np.allclose(igl.doublearea(V, Fo), igl.doublearea(V, F))
    assert _directed_edge_repeats(Fo) == 0


def test_an_edge_of_three_faces_is_searched_without_error():
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # a fin: edge (0, 1) in three faces
    Fo, flip = consistent_orientation(F)
    assert Fo.shape == F.shape and flip.shape == (3,)
    assert consistent_orientation(np.zeros((0, 3), dtype=np.int64))[0].shape == (0, 3)
