"""The whole morse-simplify computation on a mesh, with vertices relabelled by
value first (memory locality: every sweep then walks the arrays in order)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoproc.errors import InputError, UsageError
from geoproc.mesh.topology import referenced_vertices
from geoproc.mesh.validate import require_indices_below, triangle_array, vertex_field_values
from geoproc.morse.complex import SurfaceComplex, canonical_faces, require_distinct_corners, surface_complex
from geoproc.morse.gradient import DiscreteGradient, discrete_gradient
from geoproc.morse.order import vertex_order
from geoproc.morse.persistence import PersistencePairs, lower_star_persistence
from geoproc.morse.simplify import Simplification, simplify_function


@dataclass
class MorseSimplification:
    """Everything morse-simplify computes, in the relabelled vertex numbering.

    Attributes
    ----------
    order : (k,) int64 array
        ``order[i]`` is the input vertex with relabelled index i (the k
        vertices some face uses, sorted by (value, index)); map a relabelled
        vertex id back with it. A vertex no face uses is no cell of the
        surface: it is left out of the complex, and g keeps its value.
    cx : SurfaceComplex
        The complex of the relabelled mesh (faces ``rank[F]`` in
        :func:`~geoproc.morse.complex.canonical_faces` order).
    gradient, pairs : DiscreteGradient, PersistencePairs
        Of the input field (relabelled: ``f[order]``).
    simplification : Simplification
        Its ``g`` is in the relabelled numbering; use ``g`` below for the input's.
    g : (n,) float64 array
        The simplified field, indexed like the input vertices.
    """

    order: np.ndarray
    cx: SurfaceComplex
    gradient: DiscreteGradient
    pairs: PersistencePairs
    simplification: Simplification
    g: np.ndarray

    @property
    def tie_slack(self) -> np.ndarray | float:
        """The simplification's ``tie_slack`` indexed like the input vertices, as ``g`` is."""
        slack = self.simplification.tie_slack
        if not np.ndim(slack):
            return slack
        out = np.zeros(len(self.g))
        out[self.order] = slack
        return out


def morse_simplify(F: np.ndarray, f: np.ndarray, threshold: float, path: str | None = None,
                   exact_windows: int = 4) -> MorseSimplification:
    """Gradient, persistence pairs and simplification of f on the mesh F.

    Parameters
    ----------
    F : (m, 3) int array
        Triangles of a 2-manifold mesh.
    f : (n,) float array
        Vertex values.
    threshold : float
        Absolute persistence threshold P >= 0.
    path : str, optional
        File name for error messages.
    exact_windows : int
        Windows re-solved exactly (see :func:`simplify_function`).
    """
    f = vertex_field_values(f, np.size(f), "f", path)  # one value per vertex: n is its length
    if not (np.isfinite(threshold) and threshold >= 0):
        raise UsageError(f"the persistence threshold must be a finite number >= 0, not {threshold}")
    n = len(f)
    F = triangle_array(F, path)
    require_indices_below(F, n, path)
    require_distinct_corners(F, path)  # before the faces are reordered: the message names the input's triangle
    if not len(F):
        raise InputError(path, "has no faces; this method needs a triangle mesh")
    # a vertex no face uses (kept under --no-clean) is no cell of the surface: as an
    # isolated point of the complex it had counted as a component and an essential
    # minimum, where `info` counts the surface alone
    keep = np.flatnonzero(referenced_vertices(F, n))
    order, rank_kept = vertex_order(f[keep])
    order = keep[order]
    rank = np.full(n, -1, dtype=np.int64)
    rank[keep] = rank_kept
    # faces and corners in a canonical order: the exact windows' programs, and so
    # what HiGHS finds within its node limit, do not depend on how the input lists them
    cx = surface_complex(canonical_faces(rank[F]), len(keep), path)
    fr = f[order]
    grad = discrete_gradient(cx, fr)
    pairs = lower_star_persistence(cx, fr)
    simp = simplify_function(cx, fr, threshold, grad, exact_windows)
    g = f.copy()
    g[order] = simp.g
    return MorseSimplification(order, cx, grad, pairs, simp, g)
