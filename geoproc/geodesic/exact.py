"""Exact polyhedral geodesic distance (the MMP algorithm, via libigl)."""

from __future__ import annotations

import numpy as np


def exact_geodesic_distance(V: np.ndarray, F: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """(n,) exact geodesic distance on the polyhedral surface to the nearest source.

    ``igl.exact_geodesic`` (Mitchell-Mount-Papadimitriou, Kirsanov's
    implementation). Vertices it cannot reach come back as +inf. The mesh is
    solved at unit bounding-box diagonal and the distances scaled back, since
    the implementation's tolerances are absolute (at a diagonal of 1e-30 it
    does not finish).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Edge-manifold triangles.
    sources : (k,) int array
        Source vertex indices.
    """
    import igl

    from geoproc.mesh.topology import vertex_components

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)  # libigl takes native int64 (not big-endian)
    VS = np.atleast_1d(np.ascontiguousarray(sources, dtype=np.int64))
    VT = np.arange(len(V), dtype=np.int64)
    empty = np.zeros(0, dtype=np.int64)
    lo = V.min(axis=0)
    scale = float(np.linalg.norm(V.max(axis=0) - lo)) or 1.0
    U = np.ascontiguousarray((V - lo) / scale)
    d = np.asarray(igl.exact_geodesic(U, np.ascontiguousarray(F), VS, empty, VT, empty), dtype=np.float64)
    d[~np.isfinite(d) | (d > 1e99)] = np.inf
    # libigl leaves the vertices of components without a source at 0
    _, comp = vertex_components(F, len(V))  # -1: a vertex no face uses
    reached = np.isin(comp, comp[VS][comp[VS] >= 0])
    reached[VS] = True
    d[~reached] = np.inf
    return d * scale
