"""2D polygonal domains: closed loops (outer boundaries and holes).

A :class:`Domain` stores its boundary as directed segments ``A[i] -> B[i]``
oriented so that the domain lies on the left of every segment (outer loops
counter-clockwise, holes clockwise), a Neumann flag per segment and optional
per-vertex boundary values.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace

import numba
import numpy as np
from matplotlib.path import Path as MplPath

from geoproc.errors import InputError
from geoproc.fileio import read_input_bytes


@dataclass
class Domain:
    """A polygonal domain with holes.

    Attributes
    ----------
    loops : list of (n_i, 2) float64
        Closed loops, first vertex not repeated, oriented with the domain on the left.
    A, B : (S, 2) float64
        Segment start and end points (all loops concatenated).
    loop_of : (S,) int64
        Loop index of each segment.
    neumann : (S,) bool
        True for segments carrying Neumann (flux) data.
    values : (S, 2) float64 or None
        Boundary values at each segment's start and end (linear in between), when
        the input gave per-vertex values.
    source : str
        Where the domain came from (file name), for messages.
    traced : bool
        True when the loops were traced from a mask image (pixel units).
    part_of : (L,) int64
        Connected part of the domain each loop bounds, named by the index of
        its outer loop (an outer loop is its own; a hole belongs to the loop
        right around it; an island in a hole starts a part of its own).
    offset : (2,) float64
        What :meth:`translated` subtracted from the input's coordinates (0 as
        read): added back to a point a message names.
    """

    loops: list[np.ndarray]
    A: np.ndarray
    B: np.ndarray
    loop_of: np.ndarray
    neumann: np.ndarray
    values: np.ndarray | None = None
    source: str = "<domain>"
    traced: bool = False
    part_of: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(2))
    _bands: SegmentBands | None = field(default=None, repr=False)

    @property
    def n_segments(self) -> int:
        return int(self.A.shape[0])

    @property
    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi): (2,) corners of the axis-aligned bounding box."""
        P = np.concatenate(self.loops)
        return P.min(axis=0), P.max(axis=0)

    @property
    def area(self) -> float:
        """Signed area sum of the oriented loops (= area of the domain)."""
        return float(loop_signed_areas(self.loops).sum())

    @property
    def perimeter(self) -> float:
        return float(np.linalg.norm(self.B - self.A, axis=1).sum())

    @property
    def perimeter_neumann(self) -> float:
        return float(np.linalg.norm(self.B - self.A, axis=1)[self.neumann].sum())

    @property
    def outward_normals(self) -> np.ndarray:
        """(S, 2) unit normal of each segment, pointing out of the domain: to the
        right of the directed segment, the domain lying on its left."""
        E = self.B - self.A
        return np.stack([E[:, 1], -E[:, 0]], axis=1) / np.linalg.norm(E, axis=1)[:, None]

    @property
    def has_neumann(self) -> bool:
        return bool(self.neumann.any())

    def translated(self, shift: np.ndarray) -> Domain:
        """The same domain with every point moved by ``-shift`` (2,) (its segment
        bands built again on first use)."""
        shift = np.asarray(shift, dtype=np.float64)
        return replace(self, loops=[L - shift for L in self.loops], A=self.A - shift, B=self.B - shift,
                       offset=self.offset + shift, _bands=None)

    def contains(self, P: np.ndarray) -> np.ndarray:
        """(n,) bool: points ``P`` (n, 2) inside (even-odd rule over all the
        segments; points on the boundary may fall either way)."""
        if self._bands is None:
            self._bands = segment_bands(self.A, self.B)
        bands = self._bands
        P = np.ascontiguousarray(np.asarray(P, dtype=np.float64).reshape(-1, 2)[:, bands.cols])
        return _inside_even_odd(P, bands.A, bands.B, bands.y0, bands.y1, bands.height, bands.ptr, bands.seg)


@dataclass
class SegmentBands:
    """Segments sorted into bands of equal width across one axis (:func:`segment_bands`).

    Attributes
    ----------
    cols : (2,) int64
        The coordinate order of ``A`` and ``B`` below: ``[0, 1]`` for horizontal
        bands (across y), ``[1, 0]`` for vertical ones; "y" below is the second
        of those coordinates.
    A, B : (S, 2) float64
        The segments with their coordinates in that order.
    y0, y1, height : float
        Band ``b`` covers ``[y0 + b height, y0 + (b + 1) height]``; the
        segments span ``[y0, y1]``.
    ptr, seg : (count + 1,) and (copies,) int64
        Band ``b`` holds the segments ``seg[ptr[b]:ptr[b + 1]]`` whose y-range
        meets it, in increasing index.
    first : (S,) int64
        The first band of each segment.
    """

    cols: np.ndarray
    A: np.ndarray
    B: np.ndarray
    y0: float
    y1: float
    height: float
    ptr: np.ndarray
    seg: np.ndarray
    first: np.ndarray


BAND_COPIES = 8
"""A segment is listed in every band its extent meets; the bands are made
coarser until the lists hold at most this many entries per segment."""


def segment_bands(A: np.ndarray, B: np.ndarray) -> SegmentBands:
    """The segments ``A[i] -> B[i]`` (S, 2) sorted into bands, for
    :meth:`Domain.contains` and the crossing test of :func:`build_domain`.

    About one band per four segments, so that a point meets a few segments of
    its band plus those that cross it, instead of every segment (matplotlib's
    test per loop took 100 s for a 256² grid in 1.25 million segments). Bands
    run across y or across x, whichever leaves fewer segments per band, and
    are made coarser until they list at most :data:`BAND_COPIES` entries per
    segment, so that segments spanning most of the domain (the teeth of a
    comb) are not listed in every band: that grows as the square of their
    number (2.5 GB for 24,000 segments).
    """
    S = len(A)
    best = None
    for cols in ([0, 1], [1, 0]):
        lo = np.minimum(A[:, cols[1]], B[:, cols[1]])
        hi = np.maximum(A[:, cols[1]], B[:, cols[1]])
        y0, y1 = float(lo.min()), float(hi.max())
        count = int(min(max(S // 4, 1), 1 << 20))
        while True:
            height = (y1 - y0) / count if y1 > y0 else 1.0
            first = np.clip(((lo - y0) / height).astype(np.int64), 0, count - 1)
            last = np.clip(((hi - y0) / height).astype(np.int64), 0, count - 1)
            copies = int((last - first + 1).sum())
            if copies <= BAND_COPIES * S or count == 1:
                break
            count = max(1, count // 4)
        per_band = copies / count
        if best is None or per_band < best[0]:
            best = (per_band, cols, y0, y1, height, count, first, last)
    _, cols, y0, y1, height, count, first, last = best
    span = last - first + 1
    seg = np.repeat(np.arange(S, dtype=np.int64), span)
    band = np.arange(len(seg), dtype=np.int64) - np.repeat(np.cumsum(span) - span, span) + np.repeat(first, span)
    order = np.argsort(band, kind="stable")
    ptr = np.zeros(count + 1, dtype=np.int64)
    np.cumsum(np.bincount(band, minlength=count), out=ptr[1:])
    cols = np.array(cols, dtype=np.int64)
    return SegmentBands(cols, np.ascontiguousarray(A[:, cols]), np.ascontiguousarray(B[:, cols]),
                        y0, y1, height, ptr, seg[order], first)


@numba.njit(cache=True, parallel=True)
def _inside_even_odd(P, A, B, y0, y1, height, ptr, seg):
    """(n,) bool: an odd number of the segments crossed by the ray from each point
    of ``P`` towards +x (half-open in y, so a ray through a vertex counts it
    once), among the segments of the point's band. Which side of a segment the
    point lies on is the sign of a cross product, not a comparison with the
    ray's intersection, whose rounding decided points within an ulp of the
    boundary far from the origin."""
    n = P.shape[0]
    count = ptr.shape[0] - 1
    out = np.zeros(n, dtype=np.bool_)
    for p in numba.prange(n):
        px, py = P[p, 0], P[p, 1]
        if not (py >= y0 and py <= y1):  # below or above every segment (or NaN), before any integer
            continue
        b = min(int((py - y0) / height), count - 1)
        odd = False
        for k in range(ptr[b], ptr[b + 1]):
            i = seg[k]
            ay, by = A[i, 1], B[i, 1]
            if (ay > py) != (by > py):
                o = (B[i, 0] - A[i, 0]) * (py - ay) - (by - ay) * (px - A[i, 0])
                if (o > 0.0) if by > ay else (o < 0.0):  # p left of the upward segment: the ray crosses it
                    odd = not odd
        out[p] = odd
    return out


def loop_signed_area(L: np.ndarray) -> float:
    """Shoelace signed area of a closed loop (n, 2); positive when counter-clockwise.

    Summed about the loop's first vertex, so that a loop far from the origin
    (a unit square offset by 1e8) does not lose its area to cancellation.
    """
    x, y = L[:, 0] - L[0, 0], L[:, 1] - L[0, 1]
    # the two terms of the closing segment hold x[0] = y[0] = 0
    return 0.5 * float(np.dot(x[:-1], y[1:]) - np.dot(x[1:], y[:-1]))


def loop_signed_areas(loops: list[np.ndarray]) -> np.ndarray:
    """(L,) :func:`loop_signed_area` of every loop, in one pass over all their
    vertices (equal to it up to the order of the summation)."""
    P = np.concatenate(loops)
    count = np.array([len(L) for L in loops], dtype=np.int64)
    start, nxt = loop_offsets(count)
    R = P - np.repeat(P[start], count, axis=0)
    x, y = R[:, 0], R[:, 1]
    return 0.5 * np.add.reduceat(x * y[nxt] - x[nxt] * y, start)


def loop_offsets(count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(start, nxt)`` for loops of ``count`` (L,) vertices stored one after
    another: (L,) the index of each loop's first vertex, and (S,) the index of
    the vertex after each one in its own loop (the last wraps to the first)."""
    count = np.asarray(count, dtype=np.int64)
    start = np.zeros(len(count), dtype=np.int64)
    np.cumsum(count[:-1], out=start[1:])
    nxt = np.arange(1, int(count.sum()) + 1, dtype=np.int64)
    nxt[start + count - 1] = start
    return start, nxt


def _collinear(C: np.ndarray, span: float) -> bool:
    """Whether the centred points ``C`` (n, 2) lie on a line: their smaller
    singular value is at most 1e-12 of ``span`` times sqrt(n).

    The SVD is taken only when the smaller eigenvalue of ``C^T C``, in closed
    form, is below 1e-8 of its trace: above that, rounding (1e-15 of the trace)
    cannot hide a singular value of 1e-4 of the root trace, which is at least
    the span over sqrt(8), far above the threshold."""
    a, b, c = float(C[:, 0] @ C[:, 0]), float(C[:, 0] @ C[:, 1]), float(C[:, 1] @ C[:, 1])
    if 0.5 * (a + c) - float(np.hypot(0.5 * (a - c), b)) > 1e-8 * (a + c):
        return False
    return bool(np.linalg.svd(C, compute_uv=False)[-1] <= 1e-12 * max(span, 1e-300) * np.sqrt(len(C)))


def build_domain(loops: list, neumann_segments: list[np.ndarray] | None = None,
                 values: list | None = None, source: str = "<domain>") -> Domain:
    """Validate loops and build an oriented :class:`Domain`.

    Parameters
    ----------
    loops : list of (n_i, 2) array-like
        Closed loops; a repeated first vertex at the end is dropped.
    neumann_segments : list of (n_i,) bool, optional
        Per loop, whether segment ``j`` (vertex ``j`` to ``j+1``) is Neumann.
    values : list of (n_i,) array-like, optional
        Per-vertex boundary values, linear along each segment. A vertex
        repeated with another value is a jump in the data: the segment before
        it ends at its first copy's value, the one after starts at its last
        copy's (the closing copy of a loop's first vertex ends the last segment).
    source : str
        File name for error messages.

    Raises
    ------
    InputError
        Open loops (fewer than 3 distinct vertices), non-finite coordinates,
        self-intersecting or mutually crossing loops, zero-area domains.
    """
    if not loops:
        raise InputError(source, "no boundary loops")
    clean, flags, vals = [], [], []
    for k, raw in enumerate(loops):
        L = np.array(raw, dtype=np.float64)  # a copy: the domain must not share the caller's array
        if L.ndim != 2 or L.shape[1] != 2:
            raise InputError(source, f"loop {k} is not a list of [x, y] points")
        if not np.isfinite(L).all():
            raise InputError(source, f"loop {k} has non-finite coordinates")
        _require_extent_in_range(L, k, source)
        nf = np.zeros(len(L), dtype=bool) if neumann_segments is None else np.asarray(neumann_segments[k], bool)
        v = None if values is None else np.asarray(values[k], dtype=np.float64)
        if v is not None and (v.shape != (len(L),) or not np.isfinite(v).all()):
            raise InputError(source, f"loop {k}: values must be {len(L)} finite numbers, one per vertex")
        # values at the end of each vertex's incoming segment and at the start of
        # its outgoing one: equal, except where a repeated vertex carries two
        # values (a jump in the boundary data)
        v_in = v_out = v
        if len(L) > 1 and np.array_equal(L[0], L[-1]):
            L, nf = L[:-1], nf[:-1]
            if v is not None:
                v_in, v_out = np.concatenate((v[-1:], v[1:-1])), v[:-1]
        # drop repeated consecutive vertices (zero-length segments); a kept
        # vertex takes the flag of the segment that leaves its last copy (the
        # one of non-zero length), not that of the zero-length one, and the
        # value that leaves it; its first copy's value ends the segment before
        keep = np.ones(len(L), bool)
        if len(L) > 1:  # a vertex equal to the one before it (cyclically) is a repeat
            np.any(L[1:] != L[:-1], axis=1, out=keep[1:])
            keep[0] = bool(np.any(L[0] != L[-1])) or not keep[1:].any()
        kept = np.flatnonzero(keep)
        if len(kept) < len(L):
            last_copy = np.concatenate((kept[1:], kept[:1])) - 1
            L, nf = L[kept], nf[last_copy]
            if v is not None:
                v_in, v_out = v_in[kept], v_out[last_copy]
        if len(L) < 3:
            raise InputError(source, f"loop {k} is open or degenerate: a closed loop needs at least "
                             f"3 distinct vertices, got {len(L)}")
        if _collinear(L - L.mean(axis=0), float(np.linalg.norm(L.max(axis=0) - L.min(axis=0)))):
            raise InputError(source, f"loop {k} encloses zero area (its vertices are collinear)")
        clean.append(L)
        flags.append(nf)
        vals.append(None if v is None else (v_in, v_out))
    _check_simple(clean, source)
    # orientation: depth = number of other loops containing the loop; even -> CCW
    outer, inner = _enclosing_pairs(clean)  # loop outer[i] encloses loop inner[i]
    depth = np.bincount(inner, minlength=len(clean))
    signed = loop_signed_areas(clean)
    flip = (signed > 0) != (depth % 2 == 0)
    for k in np.flatnonzero(flip).tolist():
        # reversing a loop: vertex order reverses, segment j (v_j -> v_j+1) becomes
        # segment n-2-j in the new order; keep flags attached to the same edge
        clean[k] = clean[k][::-1].copy()
        flags[k] = np.roll(flags[k][::-1], -1)
        # and each segment is walked from its other end: the values swap roles
        vals[k] = None if vals[k] is None else (vals[k][1][::-1].copy(), vals[k][0][::-1].copy())
    area = float(np.where(flip, -signed, signed).sum())
    lo = np.concatenate(clean).min(axis=0)
    hi = np.concatenate(clean).max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    if not area > 1e-12 * max(diag, 1e-300) ** 2:
        raise InputError(source, f"domain has zero area (area {area:.3g}, at most 1e-12 times its "
                                 f"bounding-box diagonal {diag:.3g} squared)")
    A = np.concatenate(clean)
    count = np.array([len(L) for L in clean], dtype=np.int64)
    _, nxt = loop_offsets(count)
    B = A[nxt]
    loop_of = np.repeat(np.arange(len(clean), dtype=np.int64), count)
    seg_vals = None
    if values is not None:
        v_in = np.concatenate([vi for vi, _ in vals])
        v_out = np.concatenate([vo for _, vo in vals])
        seg_vals = np.ascontiguousarray(np.stack([v_out, v_in[nxt]], axis=1))
    return Domain(clean, np.ascontiguousarray(A), np.ascontiguousarray(B), loop_of,
                  np.concatenate(flags), seg_vals, source, part_of=_parts(outer, inner, depth))


def _enclosing_pairs(loops: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (j, k) of loops with loop k's first vertex inside loop j (the
    loops do not cross, so then all of loop k is), as two (p,) arrays. Only
    the first vertices inside loop j's bounding box are tested against it, so
    tens of thousands of small holes cost a test each, not one per pair; they
    are found along x or along y, whichever axis of the box holds fewer (along
    x alone, every slot of a comb spanning its width met every other slot's
    first vertex: 3.5 s at 32,000 slots)."""
    firsts = np.array([L[0] for L in loops])
    orders = [np.argsort(firsts[:, a], kind="stable") for a in (0, 1)]
    sorted_at = [firsts[orders[a], a] for a in (0, 1)]
    outer, inner = [], []
    for j, L in enumerate(loops):
        lo, hi = L.min(axis=0), L.max(axis=0)
        spans = [(np.searchsorted(sorted_at[a], lo[a], "left"), np.searchsorted(sorted_at[a], hi[a], "right"))
                 for a in (0, 1)]
        a = int(spans[1][1] - spans[1][0] < spans[0][1] - spans[0][0])
        b = 1 - a
        cand = np.sort(orders[a][spans[a][0]: spans[a][1]])
        cand = cand[(firsts[cand, b] >= lo[b]) & (firsts[cand, b] <= hi[b]) & (cand != j)]
        if len(cand):
            k = cand[MplPath(L).contains_points(firsts[cand])]
            outer.append(np.full(len(k), j, dtype=np.int64))
            inner.append(k.astype(np.int64))
    if not outer:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(outer), np.concatenate(inner)


def _parts(outer: np.ndarray, inner: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(L,) the outer loop of each loop's connected part: itself at even depth,
    else the loop right around it (the one enclosing it one level up)."""
    part = np.arange(len(depth), dtype=np.int64)
    odd = depth[inner] % 2 == 1
    parent = odd & (depth[outer] == depth[inner] - 1)
    part[inner[parent]] = outer[parent]
    return part


MAX_COORDINATE = 1e15  # the closest-point scan squares distances in float32 (overflow near 1.8e19)
MIN_EXTENT = 1e-15  # and below, its squared distances underflow


def _require_extent_in_range(L: np.ndarray, k: int, source: str) -> None:
    """Refuse loop ``k`` when a coordinate exceeds :data:`MAX_COORDINATE` or
    the loop spans less than :data:`MIN_EXTENT` (rescale such domains)."""
    big = float(np.abs(L).max())
    if big > MAX_COORDINATE:
        raise InputError(source, f"loop {k} has coordinates as large as {big:.3g}; they must stay within "
                         f"+-{MAX_COORDINATE:.0e} (rescale the domain)")
    span = float(np.hypot(*(L.max(axis=0) - L.min(axis=0))))  # a norm's squares underflow below 1e-154
    if 0.0 < span < MIN_EXTENT:
        raise InputError(source, f"loop {k} spans only {span:.3g}, below {MIN_EXTENT:.0e} (rescale the domain)")


def _check_simple(loops: list[np.ndarray], source: str) -> None:
    A = np.concatenate(loops)
    count = np.array([len(L) for L in loops], dtype=np.int64)
    start, nxt = loop_offsets(count)
    B = A[nxt]
    loop_of = np.repeat(np.arange(len(loops), dtype=np.int64), count)
    i, j = _first_crossing(A, B, loop_of, start, count)
    if i >= 0:
        li, lj = loop_of[i], loop_of[j]
        si, sj = i - start[li], j - start[lj]
        if li == lj:
            raise InputError(source, f"loop {li} intersects itself (segments {si} and {sj})")
        raise InputError(source, f"loops {li} and {lj} intersect (segment {si} of loop {li} "
                         f"and segment {sj} of loop {lj})")


@numba.njit(cache=True)
def _orient(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@numba.njit(cache=True)
def _on_seg(ax, ay, bx, by, cx, cy):
    return min(ax, bx) <= cx <= max(ax, bx) and min(ay, by) <= cy <= max(ay, by)


@numba.njit(cache=True)
def _segments_touch(a, b, c, d):
    o1 = _orient(a[0], a[1], b[0], b[1], c[0], c[1])
    o2 = _orient(a[0], a[1], b[0], b[1], d[0], d[1])
    o3 = _orient(c[0], c[1], d[0], d[1], a[0], a[1])
    o4 = _orient(c[0], c[1], d[0], d[1], b[0], b[1])
    if ((o1 > 0 and o2 < 0) or (o1 < 0 and o2 > 0)) and ((o3 > 0 and o4 < 0) or (o3 < 0 and o4 > 0)):
        return True
    if o1 == 0 and _on_seg(a[0], a[1], b[0], b[1], c[0], c[1]):
        return True
    if o2 == 0 and _on_seg(a[0], a[1], b[0], b[1], d[0], d[1]):
        return True
    if o3 == 0 and _on_seg(c[0], c[1], d[0], d[1], a[0], a[1]):
        return True
    if o4 == 0 and _on_seg(c[0], c[1], d[0], d[1], b[0], b[1]):
        return True
    return False


def _first_crossing(A, B, loop_of, start, count):
    """First pair (i, j) of non-adjacent segments that touch or cross; (-1, -1) if none.

    Adjacent segments of a loop (sharing a vertex) only count when they overlap
    beyond the shared vertex (a fold back). "First" in a sweep along x: the
    segments ranked by their smallest x (ties to the lower index), the pair
    whose lower rank is lowest, then the lowest other rank. The pairs whose
    boxes overlap are found in the bands of :func:`segment_bands`, each pair in
    the first band both meet, by a sweep across the bands: a sweep along x
    alone compared every segment that spans a comb's width with nearly every
    other (128,000 segments: 19.7 s).
    """
    rank = np.empty(len(A), dtype=np.int64)
    rank[np.argsort(np.minimum(A[:, 0], B[:, 0]), kind="stable")] = np.arange(len(A))
    bands = segment_bands(A, B)
    band = np.repeat(np.arange(len(bands.ptr) - 1), np.diff(bands.ptr))
    along = np.minimum(bands.A[:, 0], bands.B[:, 0])  # the sweep's coordinate, across the bands
    seg = np.ascontiguousarray(bands.seg[np.lexsort((along[bands.seg], band))])
    i, j = _first_crossing_in_bands(bands.A, bands.B, loop_of, count, rank, bands.ptr, seg, bands.first)
    return (min(i, j), max(i, j)) if i >= 0 else (-1, -1)


@numba.njit(cache=True)
def _first_crossing_in_bands(A, B, loop_of, count, rank, ptr, seg, first_band):
    """The crossing pair of lowest ranks (the lower first) among the pairs of
    segments of one band whose boxes overlap, each pair tested in the first
    band both meet; (-1, -1) if none (:func:`_first_crossing`). Each band lists
    its segments by their smallest first coordinate."""
    lo = np.minimum(A, B)
    hi = np.maximum(A, B)
    best_a = -1
    best_b = -1
    best_i = -1
    best_j = -1
    for b in range(ptr.shape[0] - 1):
        for oi in range(ptr[b], ptr[b + 1]):
            i = seg[oi]
            for oj in range(oi + 1, ptr[b + 1]):
                j = seg[oj]
                if lo[j, 0] > hi[i, 0]:
                    break
                if lo[j, 1] > hi[i, 1] or hi[j, 1] < lo[i, 1]:
                    continue
                if max(first_band[i], first_band[j]) != b:
                    continue  # tested in an earlier band
                ra = min(rank[i], rank[j])
                rb = max(rank[i], rank[j])
                if best_a >= 0 and (ra > best_a or (ra == best_a and rb > best_b)):
                    continue
                if _crossing(A, B, loop_of, count, i, j):
                    best_a = ra
                    best_b = rb
                    best_i = i
                    best_j = j
    return best_i, best_j


@numba.njit(cache=True)
def _crossing(A, B, loop_of, count, i, j):
    """Whether segments i and j touch or cross (adjacent ones of a loop: only when
    they fold back over each other)."""
    if loop_of[i] == loop_of[j]:
        n = count[loop_of[i]]
        di = (j - i) % n
        if di == 1 or di == n - 1:
            # adjacent: shared vertex; fold back when collinear and opposite
            if di == 1:
                p, q, r = A[i], B[i], B[j]
            else:
                p, q, r = A[j], B[j], B[i]
            o = _orient(p[0], p[1], q[0], q[1], r[0], r[1])
            dot = (p[0] - q[0]) * (r[0] - q[0]) + (p[1] - q[1]) * (r[1] - q[1])
            return o == 0 and dot > 0
    return _segments_touch(A[i], B[i], A[j], B[j])


class _RepeatedKey(ValueError):
    """A JSON object names the same key twice (the key in ``args[0]``)."""


def _object_without_repeated_keys(pairs: list[tuple[str, object]]) -> dict:
    """``json.loads`` hook: the object of ``pairs`` (key, value), refusing a key given twice."""
    doc = {}
    for key, value in pairs:
        if key in doc:
            raise _RepeatedKey(key)
        doc[key] = value
    return doc


def load_domain_json(path: str, data: bytes | None = None) -> Domain:
    """Read ``{"loops": [[[x, y], ...], ...], "neumann": [...], "values": [[...], ...]}``.

    ``neumann`` lists loop indices (the whole loop is Neumann) or ``[loop, segment]``
    pairs (segment ``j`` runs from vertex ``j`` to vertex ``j+1`` of that loop as
    written). ``values`` (optional) gives one boundary value per vertex.
    """
    raw = data if data is not None else read_input_bytes(path, "domain file")
    try:
        doc = json.loads(raw, object_pairs_hook=_object_without_repeated_keys)
    except _RepeatedKey as exc:  # json.loads would keep the last copy without a word
        raise InputError(path, f"the key {exc.args[0]!r} is given twice") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid JSON ({exc})") from None
    except ValueError as exc:  # an integer past Python's 4300-digit limit for reading one
        raise InputError(path, f"a number in it is too long to read ({str(exc).split(':')[0]})") from None
    except RecursionError:
        raise InputError(path, "JSON nested too deeply") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("loops"), list):
        raise InputError(path, "expected an object with a 'loops' list of closed loops [[x, y], ...]")
    unknown = sorted(set(doc) - {"loops", "neumann", "values"})
    if unknown:  # a misspelt "Neumann" would otherwise give a Dirichlet problem without a word
        raise InputError(path, f"unknown key{'s' * (len(unknown) > 1)} {', '.join(repr(k) for k in unknown)} "
                               "(the keys are 'loops', 'neumann' and 'values')")
    loops = doc["loops"]
    for k, L in enumerate(loops):
        if not isinstance(L, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(c, int | float) and not isinstance(c, bool)
                                                       for c in p) for p in L):
            raise InputError(path, f"loop {k} is not a list of [x, y] number pairs")
        try:
            np.asarray(L, dtype=np.float64)
        except OverflowError:
            raise InputError(path, f"loop {k} has a coordinate too large for a float") from None
    flags = [np.zeros(len(L), dtype=bool) for L in loops]
    neumann = doc.get("neumann")
    if neumann is None:  # absent, or null
        neumann = []
    if not isinstance(neumann, list):
        raise InputError(path, f"'neumann' must be a list of loop indices or [loop, segment] pairs, "
                         f"not {neumann!r}")
    for item in neumann:
        if isinstance(item, int) and not isinstance(item, bool) and 0 <= item < len(loops):
            flags[item][:] = True
        elif (isinstance(item, list) and len(item) == 2
              and all(isinstance(c, int) and not isinstance(c, bool) for c in item)
              and 0 <= item[0] < len(loops) and 0 <= item[1] < len(loops[item[0]])):
            k, j = item
            if np.array_equal(np.asarray(loops[k][j], float), np.asarray(loops[k][(j + 1) % len(loops[k])], float)):
                # from a vertex to a copy of itself (a loop's closing copy back to its first vertex):
                # the mark had been dropped with that zero-length segment, leaving a Dirichlet problem
                raise InputError(path, f"neumann entry {item!r}: segment {j} of loop {k} runs from a vertex to "
                                 "a copy of itself (zero length), so it marks nothing; segment j runs from "
                                 "vertex j to j+1 as written")
            flags[k][j] = True
        else:
            raise InputError(path, f"neumann entry {item!r} is not a loop index or [loop, segment] pair "
                             f"of this domain ({len(loops)} loops)")
    values = doc.get("values")
    if values is not None:
        if not isinstance(values, list) or len(values) != len(loops):
            raise InputError(path, "'values' must hold one list of per-vertex values per loop")
        if any(not isinstance(v, list) or any(isinstance(c, bool) or not isinstance(c, int | float) for c in v)
               for v in values):
            raise InputError(path, "'values' must be lists of numbers, one list per loop")
        try:
            values = [np.asarray(v, dtype=np.float64) for v in values]
        except (TypeError, ValueError, OverflowError):
            raise InputError(path, "'values' must be numbers") from None
    return build_domain(loops, flags, values, source=path)
