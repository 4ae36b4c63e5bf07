"""One intrinsic Delaunay triangulation where four vertices lie on a circle.

Where a quad of two triangles is cocircular (a square of a grid, a regular
tessellation), both of its diagonals are Delaunay, and libigl's edge flips
pick one by rounding: the same mesh scaled or moved to other coordinates can
come out with the other diagonal. The Laplacian does not notice (the diagonal's
weight is zero either way), but the barycentric mass and the gradient and
divergence on the triangles do, by up to a third of a vertex's mass on a grid.
:func:`canonical_cocircular_diagonals` flips every such quad to the diagonal
that is an edge of the input mesh, which depends on its connectivity alone (not
on the coordinates, nor on how the vertices or faces are numbered). A quad
with no input edge across it, or two (made by earlier flips, or on the doubled
cover of a mesh with boundary), takes its shorter diagonal
(:func:`shorter_other_diagonal`), and between two of one length (a rectangle)
the one holding its first vertex by :func:`vertex_rank`: colour refinement of
the vertices' angle sums, face counts and edge lengths, unchanged by
relabelling, moving, turning or scaling the mesh; the index comes last (it had
come first: relabelling a grid with boundary caps moved its heat distances by
up to 9e-4 of their maximum).
"""

from __future__ import annotations

import numpy as np

from geoproc.mesh.topology import edge_key_base, halfedges, undirected_edge_keys

TOL = 1e-5
"""Cotangent sums within this (relative) of zero are cocircular. Translated
coordinates leave ~1e-11 of rounding there, and storage does more: the torus
fixture's cocircular quads, written as float32 PLY, come back with sums up to
9e-7 (an OBJ at 8 decimals, 2e-7), which a tolerance of 1e-9 read as
non-cocircular, leaving the diagonal to the rounding again. Among the shared
meshes only cow has sums below 1e-5 (two edges); between 1e-5 and 1e-4 teapot
has 16, armadillo 6 and bunny 1."""


def corner_cotangents(l: np.ndarray) -> np.ndarray:
    """(m, 3) cotangent of the angle at each corner of triangles given by
    their edge lengths ``l[f, c]`` (opposite corner c)."""
    l2 = l**2
    s = l.sum(axis=1) / 2
    area = np.sqrt(np.maximum(s * (s - l[:, 0]) * (s - l[:, 1]) * (s - l[:, 2]), 0.0))
    cot = np.stack([l2[:, 1] + l2[:, 2] - l2[:, 0],
                    l2[:, 2] + l2[:, 0] - l2[:, 1],
                    l2[:, 0] + l2[:, 1] - l2[:, 2]], axis=1)
    return cot / (4.0 * np.maximum(area, 1e-300))[:, None]


def _flip(Fi: np.ndarray, l: np.ndarray, f: int, c: int, g: int, d: int) -> None:
    """Flip (in place) the edge opposite corner c of face f, which is the edge
    opposite corner d of face g: triangles (a, b, p) and (b, a, q) become
    (p, a, q) and (q, b, p)."""
    a, b, p = Fi[f, (c + 1) % 3], Fi[f, (c + 2) % 3], Fi[f, c]
    q = Fi[g, d]
    ab, bp, pa = l[f, c], l[f, (c + 1) % 3], l[f, (c + 2) % 3]
    aq, qb = l[g, (d + 1) % 3], l[g, (d + 2) % 3]
    # the quad laid out flat: the angle at a is the sum of its angles in the two triangles
    cos1 = np.clip((ab * ab + pa * pa - bp * bp) / (2 * ab * pa), -1.0, 1.0)
    cos2 = np.clip((ab * ab + aq * aq - qb * qb) / (2 * ab * aq), -1.0, 1.0)
    theta = np.arccos(cos1) + np.arccos(cos2)
    pq = np.sqrt(max(pa * pa + aq * aq - 2 * pa * aq * np.cos(theta), 0.0))
    Fi[f] = (p, a, q)
    l[f] = (aq, pq, pa)
    Fi[g] = (q, b, p)
    l[g] = (bp, pq, qb)


def _interior_edges(Fi: np.ndarray, l: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every interior edge once: its half-edge ids ``f * 3 + c`` in the two
    triangles (``h``, with endpoints a < b, and its twin ``t``) and the endpoints.

    An intrinsic triangulation may join two vertices by more than one edge
    (the flips make a Delta-complex: camelhead's has such pairs), so the
    vertex indices alone do not tell twins apart: half-edges are twins when
    they join the same two vertices in opposite directions with the same
    length ``l`` (m, 3) (stored once per flip, so equal to the bit). Edges
    from a vertex to itself are left out.
    """
    rolled = np.roll(np.asarray(Fi, dtype=np.int64), -1, axis=1)
    a, b = halfedges(rolled).T  # f * 3 + c runs a -> b, opposite c
    length = np.asarray(l, dtype=np.float64).reshape(-1)
    key = undirected_edge_keys(rolled)
    forward = a < b
    idx = np.flatnonzero(a != b)
    # groups of equal (vertex pair, length): forward half-edges first, each direction in id order;
    # sorting by vertex pair and direction alone gives that order unless two edges join the same pair
    order = idx[np.argsort(key[idx] * 2 + ~forward[idx], kind="stable")]
    k, w = key[order], length[order]
    mixed = (k[1:] == k[:-1]) & (w[1:] != w[:-1])
    if mixed.any():  # re-sort those pairs' half-edges by length too, in the places they hold
        at = np.flatnonzero(np.isin(k, k[1:][mixed]))
        sub = order[at]
        order[at] = sub[np.lexsort((sub, ~forward[sub], length[sub], key[sub]))]
        k, w = key[order], length[order]
    fw = forward[order]
    new_group = np.r_[True, (k[1:] != k[:-1]) | (w[1:] != w[:-1])]
    gid = np.cumsum(new_group) - 1
    gstart = np.flatnonzero(new_group)
    nfw = np.bincount(gid, weights=fw, minlength=len(gstart)).astype(np.int64)
    nbw = np.diff(np.r_[gstart, len(order)]) - nfw
    rank = np.arange(len(order)) - gstart[gid]
    fpos = np.flatnonzero(fw)  # the j-th forward half-edge of a group pairs with its j-th backward one
    fpos = fpos[rank[fpos] < nbw[gid[fpos]]]
    h = order[fpos]
    t = order[gstart[gid[fpos]] + nfw[gid[fpos]] + rank[fpos]]
    s = np.argsort(h)
    return h[s], t[s], a[h[s]], b[h[s]]


def _cocircular(cot: np.ndarray, h: np.ndarray, t: np.ndarray, tol: float) -> np.ndarray:
    """Which of the edges (half-edges h, twins t) have opposite angles summing to pi within tol."""
    w = cot[h] + cot[t]
    return np.abs(w) <= tol * np.maximum(1.0, np.maximum(np.abs(cot[h]), np.abs(cot[t])))


def cocircular_edges(Fi: np.ndarray, l: np.ndarray, tol: float = TOL) -> np.ndarray:
    """(k, 2) vertex pairs of the interior edges whose two triangles are
    cocircular (see :func:`canonical_cocircular_diagonals`): their cotangent
    weight is zero, up to rounding."""
    return cocircular_edge_weights(Fi, l, tol)[0]


def cocircular_edge_weights(Fi: np.ndarray, l: np.ndarray,
                            tol: float = TOL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cocircular edges of the triangulation ``(Fi, l)``: (k, 2) their
    vertex pairs (:func:`cocircular_edges`), (k,) their cotangent weights
    ``(cot a + cot b) / 2`` (zero up to rounding), and (k,) bool whether each is
    the only edge joining its two vertices (an intrinsic triangulation may
    join them by two; the Laplacian's entry then sums both weights)."""
    if len(Fi) == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0), np.zeros(0, dtype=bool)
    return _edge_weights(Fi, *_cocircular_pairs(Fi, l, tol))


def _cocircular_pairs(Fi: np.ndarray, l: np.ndarray, tol: float):
    """:func:`_interior_edges` ``(h, t, a, b)``, the corner cotangents (3m,) and
    which of the edges are cocircular (bool)."""
    h, t, a, b = _interior_edges(Fi, l)
    cot = corner_cotangents(l).ravel()
    return h, t, a, b, cot, _cocircular(cot, h, t, tol)


def _edge_weights(Fi, h, t, a, b, cot, on) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`cocircular_edge_weights` from :func:`_cocircular_pairs`'s output."""
    n = edge_key_base(Fi)
    keys = np.sort(undirected_edge_keys(Fi))
    k = a[on] * n + b[on]
    halves = np.searchsorted(keys, k, side="right") - np.searchsorted(keys, k, side="left")
    return np.stack([a[on], b[on]], axis=1), 0.5 * (cot[h[on]] + cot[t[on]]), halves == 2


ANGLE_STEP = 2 * np.pi * 1e-9
"""The unit in which :func:`vertex_rank` compares the angle sums around vertices:
sums closer than rounding are the same, whatever the mesh's numbering or pose."""


LENGTH_STEP = 1e-7
"""The unit, in mean edge lengths, in which :func:`vertex_rank` compares edge lengths."""

RANK_ROUNDS = 8
"""Rounds of :func:`vertex_rank`'s refinement: vertices whose surroundings differ
within this many edges of them are told apart."""


def vertex_rank(V: np.ndarray, F: np.ndarray, rounds: int = RANK_ROUNDS) -> np.ndarray:
    """(n,) int64 rank of each vertex of the mesh (V (n, 3), F (m, 3)) in an
    order that does not depend on how the vertices are numbered, nor on the
    mesh's position, orientation or unit, wherever the mesh's geometry tells
    them apart.

    Each vertex starts with its angle sum (the corners of the faces around it,
    in units of :data:`ANGLE_STEP`) and its face count; then, ``rounds`` times,
    its class is refined by the classes of its neighbours and the lengths of
    the edges to them (in units of :data:`LENGTH_STEP` mean edge lengths), as
    colour refinement does (an order-free sum of 64-bit hashes). So a vertex
    of a grid's boundary next to a moved vertex differs from the other
    boundary vertices (they share angle sum and face count, which alone had
    left the index to order them). The index orders what still ties: vertices
    a symmetry of the mesh exchanges, or that lie farther from anything that
    tells them apart."""
    from geoproc.mesh.topology import face_cross_products, unique_edges

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    n = len(V)
    area2 = np.linalg.norm(face_cross_products(V, F), axis=1)
    angles = np.empty((len(F), 3))
    for c in range(3):
        u, w = V[F[:, (c + 1) % 3]] - V[F[:, c]], V[F[:, (c + 2) % 3]] - V[F[:, c]]
        angles[:, c] = np.arctan2(area2, np.einsum("ij,ij->i", u, w))
    total = np.bincount(F.ravel(), weights=angles.ravel(), minlength=n)
    faces = np.bincount(F.ravel(), minlength=n)
    color = _dense_classes(np.round(total / ANGLE_STEP).astype(np.int64), faces)
    E = unique_edges(F)[0]
    if len(E):
        length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
        unit = float(length.mean()) if length.mean() > 0 else 1.0
        q = np.round(length / (unit * LENGTH_STEP)).astype(np.int64).astype(np.uint64)
        a, b = np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]]
        qq = np.r_[q, q]
        for _ in range(rounds):
            h = _mix64(_mix64(color[b].astype(np.uint64)) ^ qq)
            summed = np.zeros(n, dtype=np.uint64)
            np.add.at(summed, a, h)  # (unsigned: wraps)
            new = _dense_classes(color, summed)
            if new.max() == color.max():  # no class split: the refinement is stable
                break
            color = new
    order = np.lexsort((np.arange(n), color))
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    return rank


def _dense_classes(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(n,) int64 0, 1, 2, ...: the rank of each (first, second) pair among the distinct pairs."""
    order = np.lexsort((second, first))
    step = np.r_[True, (first[order][1:] != first[order][:-1]) | (second[order][1:] != second[order][:-1])]
    out = np.empty(len(first), dtype=np.int64)
    out[order] = np.cumsum(step) - 1
    return out


def _mix64(x: np.ndarray) -> np.ndarray:
    """splitmix64's finalizer on uint64 (wrapping): a hash that spreads nearby integers apart."""
    with np.errstate(over="ignore"):
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))


class _LazyRank:
    """:func:`vertex_rank` of (V, F), computed on first use (by index without V or F)."""

    def __init__(self, V, F, n: int):
        self.V, self.F, self.n, self._rank = V, F, n, None

    def __call__(self) -> np.ndarray:
        if self._rank is None:
            ok = self.V is not None and self.F is not None
            self._rank = vertex_rank(self.V, self.F) if ok else np.arange(self.n, dtype=np.int64)
        return self._rank


def other_diagonal_first(l, h, t, a, b, p, q, rank) -> np.ndarray:
    """(k,) bool for cocircular quads the input's edges leave undecided (edge ab,
    half-edges h and twins t, p and q across it): whether to flip to pq. The
    shorter diagonal (:func:`shorter_other_diagonal`); between two of one
    length, the one through the first vertex by ``rank()`` (a callable giving
    :func:`vertex_rank`, asked only when some quad ties)."""
    shorter = shorter_other_diagonal(l, h, t)
    flip = shorter > 0
    tie = np.flatnonzero(shorter == 0)
    if len(tie):
        r = rank()
        flip[tie] = np.minimum(r[p[tie]], r[q[tie]]) < np.minimum(r[a[tie]], r[b[tie]])
    return flip


def shorter_other_diagonal(l: np.ndarray, h: np.ndarray, t: np.ndarray, tol: float = TOL) -> np.ndarray:
    """(k,) int8 for the cocircular quads of the interior edges (half-edges h
    and their twins t, ``f * 3 + c`` opposite corner c of an oriented
    triangulation with edge lengths ``l`` (m, 3)): 1 where the other diagonal
    is shorter than the edge by more than ``tol`` of the longer, -1 where it
    is longer, 0 within that (a square, or a quad near one).

    The other diagonal's length follows from Ptolemy's theorem,
    ``|pq| |ab| = |pa| |qb| + |qa| |pb|`` (the edge ab, p and q the corners
    across it), so it needs no flip. Lengths are intrinsic: the comparison does
    not change when the vertices are relabelled or the mesh is moved, turned
    or scaled, and ``tol`` keeps a quad whose diagonals differ by storage
    rounding alone (float32 positions: about 1e-7) among the ties."""
    L = np.asarray(l, dtype=np.float64).reshape(-1)
    f, c, g, d = 3 * (h // 3), h % 3, 3 * (t // 3), t % 3
    ab = L[h]
    other = (L[f + (c + 2) % 3] * L[g + (d + 2) % 3] + L[g + (d + 1) % 3] * L[f + (c + 1) % 3]) / ab
    gap = (ab - other) / np.maximum(ab, other)
    return np.where(gap > tol, 1, np.where(gap < -tol, -1, 0)).astype(np.int8)


def _are_edges(keys: np.ndarray, n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k,) bool: whether each vertex pair (a, b) is among the sorted undirected
    edge ``keys`` (:func:`~geoproc.mesh.topology.undirected_edge_keys`, base ``n``)."""
    k = np.minimum(a, b) * n + np.maximum(a, b)
    at = np.minimum(np.searchsorted(keys, k), len(keys) - 1)
    return (np.maximum(a, b) < n) & (keys[at] == k)


def canonical_cocircular_diagonals(Fi: np.ndarray, l: np.ndarray, tol: float = TOL,
                                   max_passes: int = 64,
                                   F: np.ndarray | None = None,
                                   V: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, int, tuple]:
    """Flip every cocircular quad of an intrinsic Delaunay triangulation to the
    diagonal that is an edge of the input faces ``F``; where neither or both
    diagonals are, to the shorter one, and between two of one length to the
    one that holds the quad's first vertex by :func:`vertex_rank` (of ``V``
    and ``F``; by index without them).

    A quad is cocircular when the cotangents of its two angles opposite the
    diagonal sum to zero, within ``tol`` times the larger of 1 and their sizes
    (coordinates far from the origin leave about 1e-11 there, float32 storage
    about 1e-6; see :data:`TOL`). Each pass flips
    quads that share no triangle; passes repeat until none is left to flip (at
    most ``max_passes``: several cocircular quads in a row, as around a regular
    polygon, need more than one).

    Parameters
    ----------
    Fi : (m, 3) int64 triangles; l : (m, 3) float64 edge lengths, ``l[f, c]``
        opposite corner c (libigl's ``intrinsic_delaunay_cotmatrix`` output).
    F : (m, 3) int array, optional
        The mesh the triangulation was made from (same vertex ids). Without
        it every quad takes its shorter diagonal or its smallest vertex's.
    V : (n, 3) float array, optional
        The mesh's positions, for :func:`vertex_rank`; without them the
        index orders the vertices, which depends on the numbering.

    Returns
    -------
    Fi, l : the triangulation after the flips (copies; the inputs when none);
    flips : int, how many edges were flipped;
    cocircular : its :func:`cocircular_edge_weights` (edges, weights, single), found on the way.
    """
    Fi = np.asarray(Fi, dtype=np.int64)
    l = np.asarray(l, dtype=np.float64)
    if len(Fi) == 0:
        return Fi, l, 0, cocircular_edge_weights(Fi, l, tol)
    total = 0
    rank = None  # the vertices' order (vertex_rank), computed when a cocircular quad first asks
    input_keys = None  # F's edges, sorted when a cocircular quad first asks (most meshes have none)
    for _ in range(max_passes):
        pairs = _cocircular_pairs(Fi, l, tol)
        h, t, a, b, _, on = pairs
        p, q = Fi.ravel()[h], Fi.ravel()[t]
        want = np.zeros(len(on), dtype=bool)
        at = np.flatnonzero(on)
        undecided = at
        if len(at) and F is not None and len(F):  # the input's edge, where exactly one diagonal is one
            input_keys = np.unique(undirected_edge_keys(F)) if input_keys is None else input_keys
            now, other = (_are_edges(input_keys, edge_key_base(F), x[at], y[at]) for x, y in ((a, b), (p, q)))
            want[at] = other
            undecided = at[now == other]
        if len(undecided):
            if rank is None:  # computed once, when a quad first needs it
                rank = _LazyRank(V, F, int(Fi.max()) + 1)
            u = undecided
            want[u] = other_diagonal_first(l, h[u], t[u], a[u], b[u], p[u], q[u], rank)
        if not want.any():
            return Fi, l, total, _edge_weights(Fi, *pairs)
        if total == 0:
            Fi, l = Fi.copy(), l.copy()
        used = np.zeros(len(Fi), dtype=bool)
        for he, tw in zip(h[want].tolist(), t[want].tolist(), strict=True):
            f, g = he // 3, tw // 3
            if used[f] or used[g]:
                continue  # this pass already changed one of its triangles
            used[f] = used[g] = True
            _flip(Fi, l, f, he % 3, g, tw % 3)
            total += 1
    return Fi, l, total, cocircular_edge_weights(Fi, l, tol)
