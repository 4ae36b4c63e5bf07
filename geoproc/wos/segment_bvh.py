"""A bounding-volume hierarchy over 2D segments, for closest-point queries
where a grid cell lists too many candidates to scan.

The tree is a complete binary tree in heap order: node m covers a range of
the segments (in leaf order), its children 2m + 1 and 2m + 2 the first
``k // 2`` and the other ``k - k // 2`` of its k segments, split at the
median of their midpoints along the longer side of the midpoints' bounding
box; a node of at most :data:`BVH_LEAF` segments is a leaf. A query descends
nearer child first and skips any box farther than the best distance found so
far: near a boundary of 100,000 segments it tests about 40 boxes and 10
segments.

The tree is two float64 arrays. ``nodes`` (m, 6): for node m its box ``x0, y0,
x1, y1`` (length units), the first of its segments in leaf order and their
count (0 for a slot the tree does not use). ``leaf`` (k, 6): per segment in
leaf order its start, direction, squared length and index into the caller's
A, B (integers are exact in float64). Node 0 is the root.
"""

from __future__ import annotations

import math

import numba
import numpy as np

BVH_LEAF = 4
"""Segments in a leaf, at most."""


def build_segment_bvh(A: np.ndarray, B: np.ndarray, seg_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(nodes, leaf)`` of the tree over segments ``seg_ids`` of ``A -> B``
    ((S, 2) float64 each); see the module docstring. Built level by level
    with numpy sorts (a stable sort per level: the same tree every time)."""
    order = np.asarray(seg_ids, dtype=np.int64).copy()
    n = len(order)
    depth = 0
    while (n >> depth) > BVH_LEAF:  # levels until every range holds at most BVH_LEAF
        depth += 1
    depth += 1  # ranges of k // 2 and k - k // 2 can differ by one
    nodes = np.zeros((2 ** (depth + 1) - 1, 6))
    first, count = np.array([0]), np.array([n])
    for level in range(depth + 1):
        ids = 2 ** level - 1 + np.arange(len(first))
        nodes[ids, 4], nodes[ids, 5] = first, count
        split = count > BVH_LEAF
        if not split.any():
            break
        f, k = first[split], count[split]
        owner = np.repeat(np.arange(len(f)), k)  # the splitting node of each segment in these ranges
        pos = np.repeat(f - np.cumsum(np.r_[0, k[:-1]]), k) + np.arange(k.sum())
        mid = 0.5 * (A[order[pos]] + B[order[pos]])
        starts = np.r_[0, np.cumsum(k)[:-1]]
        span = np.maximum.reduceat(mid, starts) - np.minimum.reduceat(mid, starts)
        axis = (span[:, 1] > span[:, 0]).astype(np.int64)
        key = mid[np.arange(len(pos)), axis[owner]]
        order[pos] = order[pos][np.lexsort((key, owner))]
        child_first = np.full(2 * len(first), 0)
        child_count = np.zeros(2 * len(first), dtype=np.int64)
        half = count // 2
        child_first[0::2], child_count[0::2] = first, np.where(split, half, 0)
        child_first[1::2], child_count[1::2] = first + half, np.where(split, count - half, 0)
        first, count = child_first, child_count
    E = B[order] - A[order]
    leaf = np.column_stack([A[order], E, E[:, 0] * E[:, 0] + E[:, 1] * E[:, 1], order.astype(np.float64)])
    _node_boxes(nodes, leaf)
    return nodes, leaf


@numba.njit(cache=True)
def _node_boxes(nodes, leaf):
    """Fill the boxes of ``nodes`` from the segments they hold, leaves first."""
    for m in range(nodes.shape[0] - 1, -1, -1):
        a = int(nodes[m, 4])
        k = int(nodes[m, 5])
        x0 = np.inf
        y0 = np.inf
        x1 = -np.inf
        y1 = -np.inf
        if k > BVH_LEAF:  # children are done
            for c in (2 * m + 1, 2 * m + 2):
                x0 = min(x0, nodes[c, 0])
                y0 = min(y0, nodes[c, 1])
                x1 = max(x1, nodes[c, 2])
                y1 = max(y1, nodes[c, 3])
        else:
            for r in range(a, a + k):
                ax = leaf[r, 0]
                ay = leaf[r, 1]
                bx = ax + leaf[r, 2]
                by = ay + leaf[r, 3]
                x0 = min(x0, ax, bx)
                y0 = min(y0, ay, by)
                x1 = max(x1, ax, bx)
                y1 = max(y1, ay, by)
        nodes[m, 0] = x0
        nodes[m, 1] = y0
        nodes[m, 2] = x1
        nodes[m, 3] = y1


@numba.njit(cache=True, nogil=True)
def box_d2(px, py, nodes, m):
    """Squared distance from ``(px, py)`` to node m's box (0 inside)."""
    dx = max(nodes[m, 0] - px, 0.0, px - nodes[m, 2])
    dy = max(nodes[m, 1] - py, 0.0, py - nodes[m, 3])
    return dx * dx + dy * dy


@numba.njit(cache=True, nogil=True)
def _segment_d2(px, py, leaf, r):
    """Squared distance from p to leaf-ordered segment r and the parameter of its closest point."""
    return offset_segment_d2(px - leaf[r, 0], py - leaf[r, 1], leaf[r, 2], leaf[r, 3], leaf[r, 4])


@numba.njit(cache=True, nogil=True)
def offset_segment_d2(wx, wy, ex, ey, ee):
    """Squared distance from a point at offset ``(wx, wy)`` from a segment's
    start to the segment of direction ``(ex, ey)`` and squared length ``ee``,
    and the parameter t in [0, 1] of the closest point (the arithmetic every
    exact query and the grid's lists share)."""
    t = (wx * ex + wy * ey) / ee if ee > 0.0 else 0.0
    if t < 0.0:
        t = 0.0
    elif t > 1.0:
        t = 1.0
    dx = wx - t * ex
    dy = wy - t * ey
    return dx * dx + dy * dy, t


STACK = 128
"""Traversal stack size: a depth-first walk of the tree holds at most its depth
plus one nodes, and the tree over any int64 count of segments is shallower."""


@numba.njit(cache=True, nogil=True)
def bvh_closest_point(px, py, nodes, leaf):
    """Closest point on the tree's segments to ``(px, py)``: (squared distance,
    segment index into the caller's A and B, parameter t in [0, 1] along it).
    Ties go to the lowest segment index."""
    best = np.inf
    best_s = -1
    best_t = 0.0
    stack = np.empty(STACK, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        m = stack[top]
        if box_d2(px, py, nodes, m) > best:  # (equal: a tie with a lower index may be inside)
            continue
        k = int(nodes[m, 5])
        if k <= BVH_LEAF:
            a = int(nodes[m, 4])
            for r in range(a, a + k):
                d2, t = _segment_d2(px, py, leaf, r)
                s = int(leaf[r, 5])
                if d2 < best or (d2 == best and s < best_s):
                    best = d2
                    best_s = s
                    best_t = t
            continue
        top = push_children_nearer_last(stack, top, px, py, nodes, m)
    return best, best_s, best_t


@numba.njit(cache=True, nogil=True, inline="always")
def push_children_nearer_last(stack, top, px, py, nodes, m):
    """Push node m's two children onto ``stack`` (``top`` entries), the nearer
    box to ``(px, py)`` last so that it is popped first; the new ``top``."""
    c = 2 * m + 1
    if box_d2(px, py, nodes, c) <= box_d2(px, py, nodes, c + 1):
        stack[top] = c + 1
        stack[top + 1] = c
    else:
        stack[top] = c
        stack[top + 1] = c + 1
    return top + 2


@numba.njit(cache=True, nogil=True)
def bvh_segments_within(px, py, r, nodes, leaf, out, limit):
    """Segments whose distance to ``(px, py)`` (``sqrt`` of the squared distance
    as :func:`bvh_closest_point` computes it) is at most ``r`` (length units).

    Writes their indices into ``out`` (unordered) and returns how many there
    are, or ``limit + 1`` as soon as there are more than ``limit`` (``out``
    needs room for ``limit + 1``).
    """
    n = 0
    reach = r * r * (1.0 + 1e-9) + 1e-300  # boxes: a margin over the rounding of the segment test
    stack = np.empty(STACK, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        m = stack[top]
        if box_d2(px, py, nodes, m) > reach:
            continue
        k = int(nodes[m, 5])
        if k <= BVH_LEAF:
            a = int(nodes[m, 4])
            for q in range(a, a + k):
                d2, t = _segment_d2(px, py, leaf, q)
                if math.sqrt(d2) <= r:
                    out[n] = int(leaf[q, 5])
                    n += 1
                    if n > limit:
                        return n
            continue
        stack[top] = 2 * m + 1
        stack[top + 1] = 2 * m + 2
        top += 2
    return n
