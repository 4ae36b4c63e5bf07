"""Walk on Stars (Sawhney, Miller et al. 2023) for mixed Dirichlet/Neumann Laplace problems.

Each step uses the star-shaped region ``St(x, R)`` with ``R`` the smaller of the
distance to the Dirichlet boundary and the distance to the closest *silhouette*
point of the Neumann boundary (a Neumann vertex whose two segments face ``x``
from opposite sides). The walk shoots a uniformly random ray (over the half
plane when ``x`` lies on the Neumann boundary) and moves to its first hit on
the Neumann boundary within ``R``, or to the circle of radius ``R``. The flux
``h = du/dn`` (outward normal) enters through

    u(x) = E[u(next)] + k * |Gamma_N cap B(x, R)| * G_R(x, z) * h(z) * [x sees z],

``z`` uniform on the Neumann boundary inside the ball (counted only where ``x``
sees it: the star's boundary is the visible part), ``G_R(x, z) =
log(R / |x - z|) / 2 pi`` and ``k = 2`` on the boundary, 1 inside. A start
point on a Neumann segment is first moved just inside the domain. Walks stop
within ``eps`` of the Dirichlet boundary. With a control variate ``c`` the walk
solves for the residual: Dirichlet data ``g - c``, Neumann data ``h - dc/dn``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from geoproc.wos.closest import closest_point, point_segment_d2
from geoproc.wos.domain import loop_offsets
from geoproc.wos.kernels import cv_gradient
from geoproc.wos.program import eval_program
from geoproc.wos.rng import next_uniform, stream_state
from geoproc.wos.segment_bvh import (
    BVH_LEAF,
    STACK,
    box_d2,
    build_segment_bvh,
    bvh_segments_within,
    push_children_nearer_last,
)
from geoproc.wos.walk import walk_mean_variance, walk_score

TWO_PI = 2.0 * math.pi


def silhouette_candidates(A: np.ndarray, B: np.ndarray, neumann: np.ndarray,
                          loop_of: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices joining two Neumann segments: (U, V, Wn) each (k, 2).

    ``V`` is the shared vertex, ``U`` the start of the segment ending at ``V`` and
    ``Wn`` the end of the segment starting there. ``loop_of`` numbers the
    loops in the order their segments are stored (as :class:`geoproc.wos.domain.Domain` does).
    """
    _, nxt = loop_offsets(np.bincount(loop_of))
    sel = np.flatnonzero(neumann & neumann[nxt])
    return (np.ascontiguousarray(A[sel]), np.ascontiguousarray(B[sel]),
            np.ascontiguousarray(B[nxt[sel]]))


NEAR_LIMIT = 1024
"""Neumann segments within a step's ball that are gathered from the tree of
:func:`neumann_index` (for the flux sample and the start off a wall) at
most; with more, the step scans them all."""

INDEX_ABOVE = 32
"""Below this many Neumann segments (or silhouette candidates) every step scans
them all: the trees do not pay."""


def neumann_index(A: np.ndarray, B: np.ndarray, nseg: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, ...]:
    """Bounding-volume hierarchies (:mod:`geoproc.wos.segment_bvh`) over the
    Neumann segments ``nseg`` of ``A -> B`` and over the silhouette candidate
    vertices ``V`` (k, 2) (as zero-length segments numbered 0..k-1):
    ``(nodes_n, leaf_n, nodes_s, leaf_s)``. Every query of a step is local to
    the step's ball, and scanning every Neumann segment in every step made a
    walk's cost grow with their number (37,500 segments: 105 s for an
    annulus that 1,250 solve in 4.3 s)."""
    nodes_n, leaf_n = build_segment_bvh(A, B, nseg) if len(nseg) else (np.zeros((1, 6)), np.zeros((0, 6)))
    ids = np.arange(len(V), dtype=np.int64)
    nodes_s, leaf_s = build_segment_bvh(V, V, ids) if len(V) else (np.zeros((1, 6)), np.zeros((0, 6)))
    return nodes_n, leaf_n, nodes_s, leaf_s


@numba.njit(cache=True, nogil=True)
def _near(px, py, r, all_ids, nodes, leaf, buf):
    """The entries of ``all_ids`` (increasing ids) within distance ``r`` of p, in
    increasing order (so that every loop over them runs as over ``all_ids``):
    gathered from the tree into ``buf`` (room for ``NEAR_LIMIT + 1``), or
    ``all_ids`` itself when it is short or more than ``NEAR_LIMIT`` are near."""
    if all_ids.shape[0] < INDEX_ABOVE:
        return all_ids
    # a margin over the clip's rounding (:func:`_clip_to_disk`: 1e-16 of |a - c| / R, relative)
    n = bvh_segments_within(px, py, r * (1.0 + 1e-6), nodes, leaf, buf, NEAR_LIMIT)
    if n > NEAR_LIMIT:
        return all_ids
    out = buf[:n]
    out.sort()
    return out


@numba.njit(cache=True, nogil=True)
def _silhouette_d2(px, py, U, V, Wn, k):
    """Squared distance from p to candidate ``k`` if it is a silhouette seen from
    p (:func:`closest_silhouette_d2`), else inf."""
    dx = V[k, 0] - px
    dy = V[k, 1] - py
    d2 = dx * dx + dy * dy
    ex1 = V[k, 0] - U[k, 0]
    ey1 = V[k, 1] - U[k, 1]
    ex2 = Wn[k, 0] - V[k, 0]
    ey2 = Wn[k, 1] - V[k, 1]
    o1 = ex1 * (py - U[k, 1]) - ey1 * (px - U[k, 0])
    o2 = ex2 * (py - V[k, 1]) - ey2 * (px - V[k, 0])
    if (o1 > 0.0 and o2 < 0.0) or (o1 < 0.0 and o2 > 0.0):
        return d2
    tol = 1e-9 * (abs(ex1) + abs(ey1) + abs(ex2) + abs(ey2)) * (math.sqrt(d2) + abs(ex1) + abs(ey1))
    reflex = ex1 * ey2 - ey1 * ex2 < 0.0
    if reflex and (abs(o1) <= tol or abs(o2) <= tol):
        return d2
    return np.inf


@numba.njit(cache=True, nogil=True)
def _bvh_closest_silhouette_d2(px, py, U, V, Wn, limit2, nodes, leaf):
    """:func:`closest_silhouette_d2` through the tree over the candidates
    (:func:`neumann_index`): nearer boxes first, boxes farther than the best
    silhouette so far skipped. The same minimum as the scan."""
    best = limit2
    stack = np.empty(STACK, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        m = stack[top]
        if box_d2(px, py, nodes, m) > best * (1.0 + 1e-9):
            continue
        k = int(nodes[m, 5])
        if k <= BVH_LEAF:
            a = int(nodes[m, 4])
            for r in range(a, a + k):
                d2 = _silhouette_d2(px, py, U, V, Wn, int(leaf[r, 5]))
                if d2 < best:
                    best = d2
            continue
        top = push_children_nearer_last(stack, top, px, py, nodes, m)
    return best


@numba.njit(cache=True, nogil=True)
def _ray_box_entry(ox, oy, dx, dy, nodes, m, tiny):
    """Ray parameter s >= 0 at which ``o + s d`` enters node m's box, widened by
    ``tiny`` plus 1e-9 of its coordinates (a margin over the rounding of the
    segment test), or inf if it never does."""
    lo = 0.0
    hi = np.inf
    for ax in range(2):
        o = ox if ax == 0 else oy
        dd = dx if ax == 0 else dy
        pad = tiny + 1e-9 * (abs(nodes[m, ax]) + abs(nodes[m, ax + 2]))
        b0 = nodes[m, ax] - pad
        b1 = nodes[m, ax + 2] + pad
        if dd == 0.0:
            if o < b0 or o > b1:
                return np.inf
            continue
        t0 = (b0 - o) / dd
        t1 = (b1 - o) / dd
        if t0 > t1:
            t0, t1 = t1, t0
        lo = max(lo, t0)
        hi = min(hi, t1)
    return lo if lo <= hi else np.inf


@numba.njit(cache=True, nogil=True)
def _bvh_ray_hit(ox, oy, dx, dy, rmax, A, B, skip, tiny, nodes, leaf):
    """:func:`ray_hit` through the tree over the Neumann segments: the same
    arithmetic per segment and the same answer (ties to the lowest index, as
    the scan in increasing order keeps the first)."""
    best = rmax
    best_s = -1
    stack = np.empty(STACK, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        m = stack[top]
        if _ray_box_entry(ox, oy, dx, dy, nodes, m, tiny) > best:
            continue
        k = int(nodes[m, 5])
        if k <= BVH_LEAF:
            a = int(nodes[m, 4])
            for r in range(a, a + k):
                i = int(leaf[r, 5])
                if i == skip:
                    continue
                s, u = _ray_meets_segment(ox, oy, dx, dy, A, B, i)
                if 0.0 <= u <= 1.0 and tiny < s and (s < best or (s == best and 0 <= best_s and i < best_s)):
                    best = s
                    best_s = i
            continue
        c = 2 * m + 1
        stack[top] = c + 1
        stack[top + 1] = c
        top += 2
    return best, best_s


@numba.njit(cache=True, nogil=True)
def closest_silhouette_d2(px, py, U, V, Wn, limit2):
    """Squared distance to the closest silhouette vertex (or ``limit2`` if none is closer).

    A vertex is a silhouette when ``p`` lies strictly on opposite sides of its two
    segments' lines, or on one of those lines (up to round-off) at a reflex vertex:
    from a point on a Neumann segment the line through a reflex end of that segment
    bounds what the point sees, inside the domain.
    """
    best = limit2
    for k in range(V.shape[0]):
        d2 = _silhouette_d2(px, py, U, V, Wn, k)
        if d2 < best:
            best = d2
    return best


@numba.njit(cache=True, nogil=True)
def ray_hit(ox, oy, dx, dy, rmax, A, B, nseg, skip, tiny):
    """First hit of the ray ``o + s d`` (``tiny < s < rmax``) on the segments ``nseg``
    other than ``skip``; (s, seg) or (rmax, -1). ``tiny`` (length units, a tiny
    fraction of the domain's size) ignores the segments that meet the one ``o``
    lies on at ``o`` itself."""
    best = rmax
    best_s = -1
    for k in range(nseg.shape[0]):
        i = nseg[k]
        if i == skip:
            continue
        s, u = _ray_meets_segment(ox, oy, dx, dy, A, B, i)
        if 0.0 <= u <= 1.0 and tiny < s < best:
            best = s
            best_s = i
    return best, best_s


@numba.njit(cache=True, nogil=True, inline="always")
def _ray_meets_segment(ox, oy, dx, dy, A, B, i):
    """(s, u): the ray ``o + s d`` meets the line of segment i at its parameter
    u (inside the segment for 0 <= u <= 1); (inf, -1) when parallel."""
    ex = B[i, 0] - A[i, 0]
    ey = B[i, 1] - A[i, 1]
    den = dx * ey - dy * ex
    if den == 0.0:
        return np.inf, -1.0
    wx = A[i, 0] - ox
    wy = A[i, 1] - oy
    return (wx * ey - wy * ex) / den, (wx * dy - wy * dx) / den


CLIP_FAR = 1e6
"""Above this ratio of a segment start's squared distance from the disk's
centre to R², :func:`_clip_to_disk` solves from the line's closest point."""


@numba.njit(cache=True, nogil=True)
def _clip_to_disk(ax, ay, bx, by, cx, cy, R):
    """Parameter interval [u0, u1] of segment a->b inside the disk (c, R); u0 > u1 if none.

    The quadratic in u has the constant ``|a - c|^2 - R^2``, which loses R^2 to
    rounding when a is far from c compared with R (a long wall beside a small
    ball): a segment that misses the disk by 1e-9 R got a piece of 0.1 R. Past
    :data:`CLIP_FAR` the interval is taken about the line's closest point to c
    instead, whose distance is accurate to rounding of |a - c| (1e-16 |a - c|)."""
    ex = bx - ax
    ey = by - ay
    fx = ax - cx
    fy = ay - cy
    qa = ex * ex + ey * ey
    if qa == 0.0:
        return 1.0, 0.0
    ff = fx * fx + fy * fy
    if ff > CLIP_FAR * R * R:
        tc = -(fx * ex + fy * ey) / qa  # the closest point of the line
        gx = fx + tc * ex
        gy = fy + tc * ey
        h2 = R * R - (gx * gx + gy * gy)
        if h2 <= 0.0:
            return 1.0, 0.0
        hw = math.sqrt(h2 / qa)
        return max(tc - hw, 0.0), min(tc + hw, 1.0)
    qb = 2.0 * (fx * ex + fy * ey)
    qc = ff - R * R
    disc = qb * qb - 4.0 * qa * qc
    if disc <= 0.0:
        return 1.0, 0.0
    sq = math.sqrt(disc)
    u0 = max((-qb - sq) / (2.0 * qa), 0.0)
    u1 = min((-qb + sq) / (2.0 * qa), 1.0)
    return u0, u1


@numba.njit(cache=True, nogil=True)
def _sees(px, py, zx, zy, on_seg, nxn, nyn, seg, A, B, nseg, tiny):
    """Whether the point ``z`` on Neumann segment ``seg`` is visible from ``p``: no
    other Neumann segment crosses the segment p-z (the Dirichlet boundary is
    farther than the ball), and, when ``p`` lies on segment ``on_seg`` (inward
    normal ``(nxn, nyn)``), ``z`` is on the domain's side of it.

    A segment blocks only when its two ends lie strictly on opposite sides of
    the line p-z and p and z strictly on opposite sides of its own line (each
    farther than ``tiny`` from it): the pieces of a straight wall, collinear
    with p and z, never block, where a ray's intersection with them is
    rounding noise that fell inside them for most samples."""
    if seg == on_seg:
        return True
    ex = zx - px
    ey = zy - py
    dist = math.sqrt(ex * ex + ey * ey)
    if dist <= 2.0 * tiny:
        return True
    # behind p's own wall is hidden; along it (the next segment of a straight wall) is seen
    if on_seg >= 0 and ex * nxn + ey * nyn < -tiny:
        return False
    near = tiny * dist  # |cross(z - p, a - p)| / dist is a's distance to the line p-z
    for k in range(nseg.shape[0]):
        i = nseg[k]
        if i == seg or i == on_seg:
            continue
        o1 = ex * (A[i, 1] - py) - ey * (A[i, 0] - px)
        o2 = ex * (B[i, 1] - py) - ey * (B[i, 0] - px)
        if not ((o1 > near and o2 < -near) or (o1 < -near and o2 > near)):
            continue
        sx = B[i, 0] - A[i, 0]
        sy = B[i, 1] - A[i, 1]
        far = tiny * math.sqrt(sx * sx + sy * sy)
        o3 = sx * (py - A[i, 1]) - sy * (px - A[i, 0])
        o4 = sx * (zy - A[i, 1]) - sy * (zx - A[i, 0])
        if (o3 > far and o4 < -far) or (o3 < -far and o4 > far):
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _flux_term(px, py, R, on_seg, nxn, nyn, tiny, A, B, nseg, hkind, hcode, hconsts, ckind, KP, KQ,
               W, ARC, state):
    """One-sample estimate of ``int G_R h`` over the Neumann boundary that ``p``
    sees inside the ball (``on_seg``, ``nxn, nyn`` as in :func:`_sees`): a point
    drawn uniformly on the Neumann segments inside the ball, scored 0 when hidden;
    returns (value, state)."""
    total = 0.0
    for k in range(nseg.shape[0]):
        i = nseg[k]
        u0, u1 = _clip_to_disk(A[i, 0], A[i, 1], B[i, 0], B[i, 1], px, py, R)
        if u1 > u0:
            total += (u1 - u0) * math.sqrt((B[i, 0] - A[i, 0]) ** 2 + (B[i, 1] - A[i, 1]) ** 2)
    if total <= 0.0:
        return 0.0, state
    state, r = next_uniform(state)
    target = r * total
    acc = 0.0
    for k in range(nseg.shape[0]):
        i = nseg[k]
        u0, u1 = _clip_to_disk(A[i, 0], A[i, 1], B[i, 0], B[i, 1], px, py, R)
        if u1 <= u0:
            continue
        ln = math.sqrt((B[i, 0] - A[i, 0]) ** 2 + (B[i, 1] - A[i, 1]) ** 2)
        piece = (u1 - u0) * ln
        if acc + piece >= target or k == nseg.shape[0] - 1:
            u = u0 + (target - acc) / ln if ln > 0.0 else u0
            u = min(max(u, u0), u1)
            zx = A[i, 0] + u * (B[i, 0] - A[i, 0])
            zy = A[i, 1] + u * (B[i, 1] - A[i, 1])
            r2 = (zx - px) ** 2 + (zy - py) ** 2
            if r2 <= 0.0 or not _sees(px, py, zx, zy, on_seg, nxn, nyn, i, A, B, nseg, tiny):
                return 0.0, state
            G = (math.log(R) - 0.5 * math.log(r2)) / TWO_PI
            # outward normal = right of the directed segment (domain on the left)
            nx = (B[i, 1] - A[i, 1]) / ln if ln > 0.0 else 0.0
            ny = -(B[i, 0] - A[i, 0]) / ln if ln > 0.0 else 0.0
            h = eval_program(hcode, hconsts, zx, zy, nx, ny) if hkind == 0 else 0.0
            if ckind != 0:
                gx, gy = cv_gradient(zx, zy, ckind, KP, KQ, W, ARC)
                h -= gx * nx + gy * ny
            return total * G * h, state
        acc += piece
    return 0.0, state


@numba.njit(cache=True, nogil=True)
def off_neumann_walls(x, y, A, B, nseg, tiny):
    """``(x, y)`` moved ``1000 tiny`` into the domain when it lies on a Neumann segment
    (within that distance; along the sum of the inward normals of every such
    segment, which at a corner points into the domain), else unchanged. A walk
    started on a wall would shoot half its rays through it; the move changes
    ``u`` by ``1000 tiny |grad u|``."""
    close = 1000.0 * tiny
    mx = 0.0
    my = 0.0
    for k in range(nseg.shape[0]):
        i = nseg[k]
        ex = B[i, 0] - A[i, 0]
        ey = B[i, 1] - A[i, 1]
        ln = math.sqrt(ex * ex + ey * ey)
        if ln > 0.0 and point_segment_d2(x, y, A[i, 0], A[i, 1], B[i, 0], B[i, 1])[0] <= close * close:
            mx -= ey / ln  # inward normal: left of the directed segment
            my += ex / ln
    m = math.sqrt(mx * mx + my * my)
    if m == 0.0:
        return x, y
    return x + close * mx / m, y + close * my / m


@numba.njit(cache=True, nogil=True)
def wost_point(x0, y0, state, walks, eps, tiny, max_steps, A, B, dgrid, nseg, U, V, Wn, NIDX,
               bkind, code, consts, Vals, hkind, hcode, hconsts, ckind, KP, KQ, W, ARC, BOX):
    """Walks on stars from one point: (mean score + c(x0), sample variance, steps).
    ``tiny`` is a length far below any feature of the domain (1e-12 of its size);
    ``NIDX`` is :func:`neumann_index`: each step looks only at the Neumann
    segments and silhouette vertices within its ball, in the order of ``nseg``,
    with the same numbers as a scan of them all."""
    use_flux = hkind == 0 or ckind != 0
    nodes_n, leaf_n, nodes_s, leaf_s = NIDX
    buf = np.empty(NEAR_LIMIT + 1, dtype=np.int64)
    sx, sy = off_neumann_walls(x0, y0, A, B, _near(x0, y0, 1000.0 * tiny, nseg, nodes_n, leaf_n, buf), tiny)
    s1 = 0.0
    q1 = 0.0
    q2 = 0.0
    k = 0.0
    nsteps = 0
    for _w in range(walks):
        px = sx
        py = sy
        on_seg = -1
        nxn = 0.0
        nyn = 0.0
        score = 0.0
        taken = 0
        while True:
            d2, seg, t = closest_point(px, py, A, B, dgrid)
            d = math.sqrt(d2)
            if d < eps or taken >= max_steps:
                break
            if V.shape[0] < INDEX_ABOVE:
                R2 = closest_silhouette_d2(px, py, U, V, Wn, d2)
            else:
                R2 = _bvh_closest_silhouette_d2(px, py, U, V, Wn, d2, nodes_s, leaf_s)
            R = max(math.sqrt(R2), 1e-3 * eps)
            if use_flux:
                f, state = _flux_term(px, py, R, on_seg, nxn, nyn, tiny, A, B,
                                      _near(px, py, R, nseg, nodes_n, leaf_n, buf), hkind, hcode,
                                      hconsts, ckind, KP, KQ, W, ARC, state)
                score += (2.0 if on_seg >= 0 else 1.0) * f
            state, u = next_uniform(state)
            if on_seg >= 0:
                # uniform direction in the half plane around the inward normal
                th = math.atan2(nyn, nxn) + math.pi * (u - 0.5)
            else:
                th = TWO_PI * u
            dx = math.cos(th)
            dy = math.sin(th)
            if nseg.shape[0] < INDEX_ABOVE:
                s, hit = ray_hit(px, py, dx, dy, R, A, B, nseg, on_seg, tiny)
            else:
                s, hit = _bvh_ray_hit(px, py, dx, dy, R, A, B, on_seg, tiny, nodes_n, leaf_n)
            px += s * dx
            py += s * dy
            if hit >= 0:
                on_seg = hit
                ln = math.sqrt((B[hit, 0] - A[hit, 0]) ** 2 + (B[hit, 1] - A[hit, 1]) ** 2)
                nxn = -(B[hit, 1] - A[hit, 1]) / ln
                nyn = (B[hit, 0] - A[hit, 0]) / ln
            else:
                on_seg = -1
            taken += 1
        nsteps += taken
        score = walk_score(score, px, py, seg, t, A, B, bkind, code, consts, Vals, ckind, KP, KQ, W, ARC, BOX)
        if _w == 0:
            k = score
        s1 += score
        q1 += score - k
        q2 += (score - k) * (score - k)
    m, var = walk_mean_variance(s1, q1, q2, walks, x0, y0, ckind, KP, KQ, W, ARC, BOX)
    return m, var, nsteps


@numba.njit(cache=True, parallel=True)
def wost_mixed(X, index0, walks, eps, tiny, max_steps, stream_seed, A, B, dgrid, nseg, U, V, Wn, NIDX,
               bkind, code, consts, Vals, hkind, hcode, hconsts, ckind, KP, KQ, W, ARC, BOX):
    """Walk on Stars estimates of ``u`` at X (n, 2) for a mixed problem.

    Parameters as :func:`geoproc.wos.walk.wos_dirichlet`, plus ``tiny`` (a length
    far below any feature of the domain, e.g. 1e-12 of its bounding-box
    diagonal: ray hits closer than that are ignored), ``dgrid`` (the
    closest-point grid over the Dirichlet segments only), ``nseg`` (Neumann
    segment indices, increasing), ``U, V, Wn`` (:func:`silhouette_candidates`),
    ``NIDX`` (:func:`neumann_index` of those) and the flux
    ``hkind`` (0: expression ``hcode, hconsts``; 1: zero flux).

    Returns
    -------
    mean, var : (n,) float64
    steps : (n,) int64
    """
    n = X.shape[0]
    mean = np.empty(n)
    var = np.empty(n)
    steps = np.zeros(n, dtype=np.int64)
    for k in prange(n):
        mean[k], var[k], steps[k] = wost_point(
            X[k, 0], X[k, 1], stream_state(stream_seed, index0 + k), walks, eps, tiny, max_steps, A, B,
            dgrid, nseg, U, V, Wn, NIDX, bkind, code, consts, Vals, hkind, hcode, hconsts, ckind, KP, KQ,
            W, ARC, BOX)
    return mean, var, steps


@numba.njit(cache=True)
def wost_mixed_serial(X, index0, walks, eps, tiny, max_steps, stream_seed, A, B, dgrid, nseg, U, V, Wn, NIDX,
                      bkind, code, consts, Vals, hkind, hcode, hconsts, ckind, KP, KQ, W, ARC, BOX):
    """:func:`wost_mixed` on one thread (same numbers; for small batches)."""
    n = X.shape[0]
    mean = np.empty(n)
    var = np.empty(n)
    steps = np.zeros(n, dtype=np.int64)
    for k in range(n):
        mean[k], var[k], steps[k] = wost_point(
            X[k, 0], X[k, 1], stream_state(stream_seed, index0 + k), walks, eps, tiny, max_steps, A, B,
            dgrid, nseg, U, V, Wn, NIDX, bkind, code, consts, Vals, hkind, hcode, hconsts, ckind, KP, KQ,
            W, ARC, BOX)
    return mean, var, steps
