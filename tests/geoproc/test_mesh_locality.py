"""Z-order (Morton) renumbering of points (geoproc.mesh.locality)."""

from __future__ import annotations

import numpy as np

from geoproc.mesh.locality import MORTON_BITS, inverse_permutation, morton_order


def _morton_key_by_bits(q: np.ndarray) -> int:
    """The Z-order key of one integer cell (3,), bit by bit: bit b of axis a goes to bit 3b + a."""
    return sum(((int(q[a]) >> b) & 1) << (3 * b + a) for b in range(MORTON_BITS) for a in range(3))


def test_morton_order_sorts_by_the_interleaved_cell_bits():
    rng = np.random.default_rng(4)
    P = rng.random((300, 3)) * [2.0, 1.0, 0.5] - 7.0
    order = morton_order(P)
    lo, span = P.min(axis=0), (P.max(axis=0) - P.min(axis=0)).max()
    Q = np.clip(((P - lo) * ((2**MORTON_BITS - 1) / span)).astype(np.int64), 0, 2**MORTON_BITS - 1)
    keys = [_morton_key_by_bits(q) for q in Q]
    assert sorted(order.tolist()) == list(range(len(P)))
    assert [keys[i] for i in order] == sorted(keys)


def test_morton_order_of_a_grid_visits_each_octant_in_turn():
    # the 8 corners of a cube: x is the lowest bit, then y, then z
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    perm = np.random.default_rng(0).permutation(8)
    order = morton_order(corners[perm])
    assert np.array_equal(corners[perm][order], corners)


def test_equal_points_keep_their_order_and_the_inverse_undoes_it():
    P = np.zeros((5, 3))
    assert morton_order(P).tolist() == [0, 1, 2, 3, 4]
    assert len(morton_order(np.zeros((0, 3)))) == 0
    order = np.array([3, 0, 4, 1, 2])
    inv = inverse_permutation(order)
    assert np.array_equal(order[inv], np.arange(5)) and np.array_equal(inv[order], np.arange(5))
