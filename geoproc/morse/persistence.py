"""Lower-star persistence of a vertex function on a surface mesh: the
minimum-saddle and saddle-maximum pairs and the essential cells."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoproc.morse.complex import SurfaceComplex
from geoproc.morse.dual_pairs import dual_pairs
from geoproc.morse.merge_forest import merge_forest
from geoproc.morse.order import vertex_order


@dataclass
class PersistencePairs:
    """Persistence pairs of the lower-star filtration (each simplex at the largest
    value of its vertices, ties by vertex index), with their cells.

    Only pairs whose two cells have different highest vertices are listed (the
    others are pairs inside one lower star, of zero persistence under any
    tie-breaking). Values are those of the cells' highest vertices.

    Attributes
    ----------
    f : (n,) float64 array
        The function.
    min_vertex, min_saddle_edge : (p0,) int64 arrays
        Minimum-saddle pairs: the minimum and the edge that kills it.
    saddle_edge, max_triangle : (p1,) int64 arrays
        Saddle-maximum pairs: the edge that creates a 1-cycle and the triangle
        that fills it.
    essential_vertices, essential_edges, essential_triangles : int64 arrays
        Cells whose classes never die: one minimum per component, the
        1-cycles of the surface's first homology, the highest triangle of each
        closed component. Their counts are the Betti numbers (Z/2).
    edge_top, triangle_top : int64 arrays
        Highest vertex (by the total order) of every edge and triangle.
    """

    f: np.ndarray
    min_vertex: np.ndarray
    min_saddle_edge: np.ndarray
    saddle_edge: np.ndarray
    max_triangle: np.ndarray
    essential_vertices: np.ndarray
    essential_edges: np.ndarray
    essential_triangles: np.ndarray
    edge_top: np.ndarray
    triangle_top: np.ndarray

    @property
    def betti(self) -> tuple[int, int, int]:
        """(b0, b1, b2) of the surface."""
        return len(self.essential_vertices), len(self.essential_edges), len(self.essential_triangles)

    def diagram(self, dim: int) -> np.ndarray:
        """(k, 2) array of (birth, death) values in dimension ``dim`` (0 or 1 for
        finite pairs; essential classes of dimension 0, 1, 2 have death inf)."""
        f = self.f
        if dim == 0:
            fin = np.column_stack([f[self.min_vertex], f[self.edge_top[self.min_saddle_edge]]])
            ess = f[self.essential_vertices]
        elif dim == 1:
            fin = np.column_stack([f[self.edge_top[self.saddle_edge]], f[self.triangle_top[self.max_triangle]]])
            ess = f[self.edge_top[self.essential_edges]]
        elif dim == 2:
            fin = np.zeros((0, 2))
            ess = f[self.triangle_top[self.essential_triangles]]
        else:
            raise ValueError("dim must be 0, 1 or 2")
        return np.concatenate([fin.reshape(-1, 2), np.column_stack([ess, np.full(len(ess), np.inf)])])

    def persistence(self, dim: int) -> np.ndarray:
        """Persistence (death - birth) of the finite pairs of dimension 0 or 1."""
        d = self.diagram(dim)
        d = d[np.isfinite(d[:, 1])]
        return d[:, 1] - d[:, 0]


def _top_vertex(cells: np.ndarray, rank: np.ndarray) -> np.ndarray:
    return cells[np.arange(len(cells)), np.argmax(rank[cells], axis=1)]


def lower_star_persistence(cx: SurfaceComplex, f: np.ndarray) -> PersistencePairs:
    """Persistence pairs of f's lower-star filtration on a surface mesh.

    Minimum-saddle pairs come from union-find on the vertices with the edges in
    filtration order (elder rule); saddle-maximum pairs from union-find on the
    dual graph in reverse order (:mod:`geoproc.morse.dual_pairs`, exact on
    closed surfaces by duality, boundaries coned off). Edges that neither merge
    components nor kill a dual component carry the essential 1-cycles.

    Parameters
    ----------
    cx : SurfaceComplex
        A 2-manifold mesh, with or without boundary, any number of components.
    f : (n,) float array
        Vertex values.
    """
    f = np.asarray(f, dtype=np.float64)
    order, rank = vertex_order(f)
    b0, _, _, e0, _, ess0, first = merge_forest(
        cx.adj_ptr, cx.adj_nbr, cx.adj_edge, order, rank, f, 0.0, False, np.zeros(len(f), bool)
    )
    pe, pt, killing, ess2 = dual_pairs(cx.F, cx.ET, cx.adj_ptr, cx.adj_nbr, cx.adj_edge, order, rank)
    edge_top = _top_vertex(cx.E, rank)
    tri_top = _top_vertex(cx.F, rank)
    neg0 = np.zeros(len(cx.E), dtype=bool)
    neg0[e0] = True
    neg0[first[first >= 0]] = True
    ess1 = np.flatnonzero(~neg0 & ~killing)
    keep = edge_top[pe] != tri_top[pt]
    return PersistencePairs(
        f, b0, e0, pe[keep], pt[keep], np.sort(ess0), ess1, np.sort(ess2), edge_top, tri_top
    )
