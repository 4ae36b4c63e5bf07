"""Noise level of a mesh, estimated from the mesh alone."""

from __future__ import annotations

import numpy as np

from geoproc.denoise.face_geometry import face_edge_neighbors, face_normals_and_areas, vertex_normals
from geoproc.mesh.topology import edge_adjacency_matrix, unique_edges

# chord between unit face normals below which two edge-adjacent faces count as
# one plane (0.006 degrees): far below what noise of 0.01 mean edge lengths
# gives, above the rounding of coordinates written with six decimals
COPLANAR_CHORD = 1e-4


def exactly_planar_vertices(V: np.ndarray, F: np.ndarray, edge_nb: np.ndarray | None = None) -> np.ndarray:
    """(n,) bool: vertices where the surface is made of exact planes.

    A vertex qualifies when at most three of its edges are creases and either
    one of its edges joins two coplanar faces (normals within
    ``COPLANAR_CHORD``) or each of its faces has a coplanar edge neighbour (a
    flat region, a crease line or a corner of planar pieces; the second rule
    takes the corners that no diagonal of their faces reaches, such as a
    cube's corner of three edges, all creases). Noise moves every vertex off
    every plane, so a noisy mesh has next to no such vertices; clean CAD
    meshes are made of them. F is edge-manifold (the
    edge pairs are :func:`~geoproc.denoise.face_geometry.face_edge_neighbors`,
    computed here unless given as ``edge_nb``).
    """
    enb = face_edge_neighbors(F) if edge_nb is None else edge_nb
    f, k = np.nonzero(enb > np.arange(len(F))[:, None])  # each interior edge once, from its lower face
    N, _ = face_normals_and_areas(V, F)
    flat = np.linalg.norm(N[f] - N[enb[f, k]], axis=1) < COPLANAR_CHORD
    ends = np.stack([F[f, k], F[f, (k + 1) % 3]], axis=1)  # corner k's outgoing edge
    flat_at = np.bincount(ends[flat].ravel(), minlength=len(V))
    crease_at = np.bincount(ends[~flat].ravel(), minlength=len(V))
    in_plane = np.zeros(len(F), dtype=bool)  # faces with a coplanar edge neighbour
    in_plane[f[flat]] = True
    in_plane[enb[f[flat], k[flat]]] = True
    pieces_only = np.bincount(F[~in_plane].ravel(), minlength=len(V)) == 0
    pieces_only &= np.bincount(F.ravel(), minlength=len(V)) > 0
    return ((flat_at > 0) | pieces_only) & (crease_at <= 3)


def roughness(V: np.ndarray, F: np.ndarray, edge_nb: np.ndarray | None = None) -> float:
    """High-frequency roughness, in mean edge lengths: a noise-level estimate.

    Every vertex's height over the centroid of its neighbours along its normal,
    ``h_i = n_i . (x_i - mean_j x_j)``, is smooth on a clean surface (it follows
    the curvature, with one sign on a sphere); noise makes it jump from vertex
    to vertex. The estimate is the median of ``|h_i - mean_j h_j|`` over the
    vertices, divided by the mean edge length: near 0 on clean meshes however
    curved, and growing in proportion to the noise. Vertices where the surface
    is made of exact planes (:func:`exactly_planar_vertices`) are left out,
    and a mesh made only of them reads 0: on a coarse CAD mesh (a cube of 12
    triangles) the heights jump with the valence, not with noise. ``edge_nb``
    (:func:`~geoproc.denoise.face_geometry.face_edge_neighbors` of F) saves
    recomputing it when the caller has it.
    """
    n = len(V)
    E, _, _ = unique_edges(F)
    E = E[E[:, 0] != E[:, 1]]
    if len(E) == 0:
        return 0.0
    le = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean())
    if le <= 0:
        return 0.0
    A = edge_adjacency_matrix(E, n)
    deg = np.asarray(A.sum(axis=1)).ravel()
    used = deg > 0
    deg[~used] = 1.0
    h = np.einsum("ij,ij->i", vertex_normals(V, F), V - (A @ V) / deg[:, None])
    r = np.abs(h - (A @ h) / deg)
    used &= ~exactly_planar_vertices(V, F, edge_nb)
    if not used.any():
        return 0.0
    return float(np.percentile(r[used], 25) * (0.6745 / 0.3186) / le)
