"""Critical cells with their persistence partners, as plain records (for JSON)."""

from __future__ import annotations

import numpy as np

from geoproc.morse.complex import SurfaceComplex
from geoproc.morse.persistence import PersistencePairs


def critical_cells_table(cx: SurfaceComplex, pp: PersistencePairs,
                         vertex_ids: np.ndarray | None = None) -> list[dict]:
    """One record per critical cell of the lower-star gradient.

    Parameters
    ----------
    cx : SurfaceComplex
        The mesh's cells.
    pp : PersistencePairs
        Its persistence pairs (:func:`geoproc.morse.lower_star_persistence`).
    vertex_ids : (n,) int array, optional
        Vertex ids to report for the complex's vertices (``order`` of a
        :class:`~geoproc.morse.MorseSimplification` maps relabelled vertices
        back to the input's).

    Returns
    -------
    list of dict
        ``dimension`` (0 minimum, 1 saddle, 2 maximum), ``simplex`` (its
        vertices), ``vertex`` (its highest vertex under (value, index)),
        ``value`` (f there), ``paired_with`` (``{"dimension", "simplex",
        "vertex"}`` of its persistence partner, or None for an essential
        class) and ``persistence`` (None for an essential class), sorted by
        dimension, then value, then vertex.
    """
    f = pp.f
    ids = np.arange(cx.n) if vertex_ids is None else np.asarray(vertex_ids)

    def _simplex(cx, dim, idx):
        cell = [idx] if dim == 0 else cx.E[idx] if dim == 1 else cx.F[idx]
        return sorted(int(ids[x]) for x in cell)

    def top(d, i):
        return int(i) if d == 0 else int(pp.edge_top[i]) if d == 1 else int(pp.triangle_top[i])

    rows = []

    def add(d, i, pd, pi):
        v = top(d, i)
        rec = {"dimension": d, "simplex": _simplex(cx, d, i), "vertex": int(ids[v]), "value": float(f[v])}
        if pd is None:
            rec["paired_with"] = None
            rec["persistence"] = None
        else:
            w = top(pd, pi)
            rec["paired_with"] = {"dimension": pd, "simplex": _simplex(cx, pd, pi), "vertex": int(ids[w])}
            rec["persistence"] = float(abs(f[w] - f[v]))
        rows.append(rec)

    for m, e in zip(pp.min_vertex, pp.min_saddle_edge, strict=True):
        add(0, m, 1, e)
        add(1, e, 0, m)
    for e, t in zip(pp.saddle_edge, pp.max_triangle, strict=True):
        add(1, e, 2, t)
        add(2, t, 1, e)
    for v in pp.essential_vertices:
        add(0, v, None, None)
    for e in pp.essential_edges:
        add(1, e, None, None)
    for t in pp.essential_triangles:
        add(2, t, None, None)
    rows.sort(key=lambda r: (r["dimension"], r["value"], r["vertex"]))
    return rows


def critical_counts(pp: PersistencePairs) -> tuple[int, int, int]:
    """Numbers of critical vertices, edges and triangles (minima, saddles with
    multiplicity, maxima)."""
    c0 = len(pp.min_vertex) + len(pp.essential_vertices)
    c1 = len(pp.min_saddle_edge) + len(pp.saddle_edge) + len(pp.essential_edges)
    c2 = len(pp.max_triangle) + len(pp.essential_triangles)
    return c0, c1, c2


def finite_persistence(pp: PersistencePairs) -> np.ndarray:
    """Persistence of every finite pair, both dimensions."""
    return np.concatenate([pp.persistence(0), pp.persistence(1)])
