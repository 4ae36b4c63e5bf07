"""Closest-point queries on 2D segments through a uniform grid of candidate lists.

Each grid cell stores the segments that can be closest to *some* point of the
cell: with ``c`` the cell center, ``h`` its half diagonal and ``d*`` the
distance from ``c`` to the nearest segment, a segment farther than ``d* + 2h``
from ``c`` is farther than ``d* + h`` from every point of the cell, while the
nearest segment is within ``d* + h``. The lists are exact, so a query scans
only its cell's few candidates.

A cell with more than :data:`BVH_ABOVE` candidates ("crowded": the middle of
a disk bounded by 100,000 segments has them all; near a boundary of tens of
thousands of segments a cell lists thousands) stores none. Its queries, and
those of points outside the grid, go to a bounding-volume hierarchy over the
segments (:mod:`geoproc.wos.segment_bvh`), which also finds ``d*`` and the
lists while the grid is built, without testing every cell against every
segment. A crowded cell keeps ``d*``: from a point p well inside it,
``d* - |p - c|`` bounds the distance from below at once (distance to a set is
1-Lipschitz). The benchmark and fixture domains have at most 256 candidates
in a cell and never use the hierarchy for a query.

A single-precision copy of the candidates (relative to the grid origin) serves
:func:`distance_lower_bound`, the cheap query walks use for steps that do not
end the walk.

The grid is a tuple ``(ox, oy, inv_cs, nx, ny, start, items, coords,
coords32, margin, far, nodes, leaf)`` accepted by :func:`closest_point`:
``far`` holds ``d*`` for crowded cells and -1 for the others, ``nodes`` and
``leaf`` are the hierarchy; ``coords`` (k, 5) repeats each candidate's start,
direction and inverse squared length (``ax, ay, ex, ey, 1/|e|^2``) so a query
reads one contiguous block and divides nothing.

The grid is built from the hierarchy: ``d*`` of every cell is one nearest
query, and its list one range query that stops past :data:`BVH_ABOVE`. The
lists equal those of testing every cell against every segment (same
arithmetic, ascending order), which the build did before; it took 7.3 s on a
disk of 100,000 segments (32 x 32 cells) and takes about 1.2 s (256 x 256).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from geoproc.wos.segment_bvh import build_segment_bvh, bvh_closest_point, bvh_segments_within, offset_segment_d2


@numba.njit(cache=True, nogil=True, inline="always")
def point_segment_d2(px, py, ax, ay, bx, by):
    """Squared distance from p to segment [a, b] and the parameter t of the closest point."""
    ex = bx - ax
    ey = by - ay
    return offset_segment_d2(px - ax, py - ay, ex, ey, ex * ex + ey * ey)


BVH_ABOVE = 256
"""Cells with more candidates ("crowded") list none: their queries go to the
segment hierarchy, and they keep ``d*`` for :func:`distance_lower_bound`."""

MAX_RESOLUTION = 256
"""Grid cells along the longer side, at most."""

MAX_GRID_ITEMS = 2_000_000
"""Candidate entries of all cells together, at most (68 bytes each): beyond, the
cells with the longest lists count as crowded."""


@numba.njit(cache=True)
def _cell_candidates(ox, oy, cs, nx, ny, crowded, start, items, dstar, nodes, leaf):
    """Per cell: ``d*`` (from the hierarchy) and the number of segments within
    ``d* + 2h`` of its centre (``BVH_ABOVE + 1`` for more than :data:`BVH_ABOVE`);
    with ``crowded`` given ((cells,) bool, else an empty array), also those
    segments, in ascending order, into ``items`` from ``start`` for the cells
    that are not crowded."""
    half = 0.5 * cs * math.sqrt(2.0)
    n_cells = nx * ny
    counts = np.zeros(n_cells, dtype=np.int64)
    for c in range(n_cells):
        if crowded.shape[0] and crowded[c]:  # counted before, lists nothing
            continue
        i = c % nx
        j = c // nx
        cx = ox + (i + 0.5) * cs
        cy = oy + (j + 0.5) * cs
        d2, s, t = bvh_closest_point(cx, cy, nodes, leaf)
        best = math.sqrt(d2)
        dstar[c] = best
        lim = best + 2.0 * half + 1e-12 * (1.0 + best)
        found = np.empty(BVH_ABOVE + 1, dtype=np.int64)
        n = bvh_segments_within(cx, cy, lim, nodes, leaf, found, BVH_ABOVE)
        if crowded.shape[0]:
            items[start[c]:start[c] + n] = np.sort(found[:n])
        counts[c] = n
    return counts


def build_segment_grid(A: np.ndarray, B: np.ndarray, seg_ids: np.ndarray | None = None,
                       resolution: int | None = None):
    """Build the candidate grid over segments ``seg_ids`` of ``A -> B`` (S, 2).

    Parameters
    ----------
    A, B : (S, 2) float64
        Segment endpoints.
    seg_ids : (k,) int64, optional
        Which segments to index (default: all).
    resolution : int, optional
        Cells along the longer side (default ``clip(8 sqrt(k), 32, MAX_RESOLUTION)``).
        ``seg_ids`` are taken in ascending order.

    Returns
    -------
    tuple
        ``(ox, oy, inv_cs, nx, ny, start, items, coords, coords32, margin, far, nodes, leaf)``
        for :func:`closest_point` and :func:`distance_lower_bound`.
    """
    A = np.ascontiguousarray(A, dtype=np.float64)
    B = np.ascontiguousarray(B, dtype=np.float64)
    seg_ids = np.arange(len(A), dtype=np.int64) if seg_ids is None else np.unique(np.asarray(seg_ids, np.int64))
    P = np.concatenate([A[seg_ids], B[seg_ids]])
    lo, hi = P.min(axis=0), P.max(axis=0)
    span = float(max(hi - lo))
    span = span if span > 0 else 1.0
    lo = lo - 1e-6 * span
    span *= 1 + 2e-6
    k = len(seg_ids)
    n = resolution or int(np.clip(8 * np.sqrt(k), 32, MAX_RESOLUTION))
    cs = span / n
    nx = max(1, int(np.ceil((hi[0] - lo[0]) / cs + 1e-9)))
    ny = max(1, int(np.ceil((hi[1] - lo[1]) / cs + 1e-9)))
    bvh = build_segment_bvh(A, B, seg_ids)
    empty = np.zeros(0, dtype=np.int64)
    dstar = np.empty(nx * ny)
    counts = _cell_candidates(lo[0], lo[1], cs, nx, ny, empty.astype(bool), empty, empty, dstar, *bvh)
    crowded = counts > BVH_ABOVE
    counts[crowded] = 0
    excess = int(counts.sum()) - MAX_GRID_ITEMS
    if excess > 0:  # the longest lists go too
        by_size = np.argsort(-counts, kind="stable")
        crowded[by_size[:int(np.searchsorted(np.cumsum(counts[by_size]), excess)) + 1]] = True
        counts[crowded] = 0
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    items = np.empty(int(start[-1]), dtype=np.int64)
    _cell_candidates(lo[0], lo[1], cs, nx, ny, crowded, start, items, dstar, *bvh)
    far = np.where(crowded, dstar, -1.0)
    E = B[items] - A[items]
    ee = (E**2).sum(axis=1)
    inv = np.divide(1.0, ee, out=np.zeros_like(ee), where=ee > 0)
    coords = np.ascontiguousarray(np.hstack([A[items], E, inv[:, None]]))
    rel = coords.copy()
    rel[:, 0] -= lo[0]
    rel[:, 1] -= lo[1]
    with np.errstate(over="ignore"):  # 1 / |E|^2 of a segment shorter than 1e-19 is inf in float32
        coords32 = np.ascontiguousarray(rel.astype(np.float32))
    # float32 rounding within the grid, plus the float64 rounding of p - origin far from 0 (eps|lo|)
    margin = 1e-6 * span + 1e-12 * float(np.abs(lo).max())
    return (float(lo[0]), float(lo[1]), 1.0 / cs, nx, ny, start, items, coords, coords32, margin,
            far) + bvh


@numba.njit(cache=True, nogil=True)
def closest_point(px, py, A, B, grid):
    """Closest point on the indexed segments to ``(px, py)`` (``A``, ``B``: the
    segments the grid was built on; the grid holds what the query reads).

    Returns
    -------
    d2 : float
        Squared distance.
    seg : int
        Segment index (into A, B).
    t : float
        Parameter of the closest point on the segment, in [0, 1].
    """
    ox, oy, inv_cs, nx, ny, start, items, coords, coords32, margin, far, nodes, leaf = grid
    fi = (px - ox) * inv_cs
    fj = (py - oy) * inv_cs
    if not (0.0 <= fi < nx and 0.0 <= fj < ny):
        return bvh_closest_point(px, py, nodes, leaf)
    c = int(fj) * nx + int(fi)
    if far[c] >= 0.0:  # crowded
        return bvh_closest_point(px, py, nodes, leaf)
    best = np.inf
    best_k = start[c]
    best_t = 0.0
    for k in range(start[c], start[c + 1]):
        wx = px - coords[k, 0]
        wy = py - coords[k, 1]
        ex = coords[k, 2]
        ey = coords[k, 3]
        t = min(max((wx * ex + wy * ey) * coords[k, 4], 0.0), 1.0)
        dx = wx - t * ex
        dy = wy - t * ey
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
            best_k = k
            best_t = t
    return best, items[best_k], best_t


@numba.njit(cache=True, nogil=True)
def distance_lower_bound(px, py, grid):
    """A lower bound of the distance from p to the segments, in float32 arithmetic.

    Scans the cell's candidates in single precision (coordinates relative to the
    grid origin) and subtracts ``margin``, which exceeds the rounding error, so
    the disk (p, result) is free of segments; in a crowded cell (see the module
    docstring) a point within ``d*/2`` of the cell's centre ``c`` gets
    ``d* - |p - c| - margin`` without a query, and another point the exact
    distance from the hierarchy less ``margin``. Returns -1 outside the grid. Walks
    use it for every step that does not end the walk; :func:`closest_point` gives
    the exact (double precision) closest point.
    """
    ox, oy, inv_cs, nx, ny, start, items, coords, coords32, margin, far, nodes, leaf = grid
    fi = (px - ox) * inv_cs
    fj = (py - oy) * inv_cs
    if not (0.0 <= fi < nx and 0.0 <= fj < ny):
        return -1.0
    i = int(fi)
    j = int(fj)
    c = j * nx + i
    if far[c] > 0.0:  # crowded: d* - |p - c| when p is well inside the cell's free disk
        r = far[c] - math.hypot(px - (ox + (i + 0.5) / inv_cs), py - (oy + (j + 0.5) / inv_cs))
        if r > 0.5 * far[c]:
            return r - margin
    if far[c] >= 0.0:  # crowded: the exact distance, from the hierarchy
        d2, _s, _t = bvh_closest_point(px, py, nodes, leaf)
        return math.sqrt(d2) - margin
    x = np.float32(px - ox)
    y = np.float32(py - oy)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    best = np.float32(np.inf)
    for k in range(start[c], start[c + 1]):
        wx = x - coords32[k, 0]
        wy = y - coords32[k, 1]
        ex = coords32[k, 2]
        ey = coords32[k, 3]
        t = min(max((wx * ex + wy * ey) * coords32[k, 4], zero), one)
        dx = wx - t * ex
        dy = wy - t * ey
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
    return math.sqrt(np.float64(best)) - margin


@numba.njit(cache=True, parallel=True)
def closest_points(P, A, B, grid):
    """Batch version of :func:`closest_point`: (n, 2) points -> (d (n,), seg (n,), t (n,))."""
    n = P.shape[0]
    d = np.empty(n)
    seg = np.empty(n, dtype=np.int64)
    tt = np.empty(n)
    for k in prange(n):
        d2, s, t = closest_point(P[k, 0], P[k, 1], A, B, grid)
        d[k] = math.sqrt(d2)
        seg[k] = s
        tt[k] = t
    return d, seg, tt
