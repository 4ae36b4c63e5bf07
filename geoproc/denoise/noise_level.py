"""Noise level of a mesh, estimated from the mesh alone."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geoproc.denoise.face_geometry import vertex_normals
from geoproc.mesh.topology import unique_edges


def roughness(V: np.ndarray, F: np.ndarray) -> float:
    """High-frequency roughness, in mean edge lengths: a noise-level estimate.

    Every vertex's height over the centroid of its neighbours along its normal,
    ``h_i = n_i . (x_i - mean_j x_j)``, is smooth on a clean surface (it follows
    the curvature, with one sign on a sphere); noise makes it jump from vertex
    to vertex. The estimate is the median of ``|h_i - mean_j h_j|`` over the
    vertices, divided by the mean edge length: near 0 on clean meshes however
    curved, and growing in proportion to the noise.
    """
    n = len(V)
    E, _, _ = unique_edges(F)
    E = E[E[:, 0] != E[:, 1]]
    if len(E) == 0:
        return 0.0
    le = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean())
    if le <= 0:
        return 0.0
    A = sp.coo_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                      shape=(n, n)).tocsr()
    deg = np.asarray(A.sum(axis=1)).ravel()
    used = deg > 0
    deg[~used] = 1.0
    h = np.einsum("ij,ij->i", vertex_normals(V, F), V - (A @ V) / deg[:, None])
    r = np.abs(h - (A @ h) / deg)
    return float(np.percentile(r[used], 25) * (0.6745 / 0.3186) / le)
