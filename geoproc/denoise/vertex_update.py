"""Fit vertex positions to filtered face normals (Sun et al. 2007, Eq. 12-14)."""

from __future__ import annotations

import numpy as np


def update_vertices(
    V: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    iterations: int = 20,
    fixed: np.ndarray | None = None,
) -> np.ndarray:
    """Move vertices so that faces become orthogonal to the target normals.

    Each iteration applies ``x_i += 1/|F_i| sum_{f in F_i} n_f (n_f . (c_f - x_i))``
    with the face centroids ``c_f`` of the current positions (a gradient step on
    ``sum_f sum_{(i,j) in f} (n_f . (x_j - x_i))^2``).

    Parameters
    ----------
    V : (n, 3) float64 positions; F : (m, 3) int64 triangles.
    normals : (m, 3) float64
        Target unit normal of each face.
    iterations : int
        Number of update sweeps.
    fixed : (n,) bool, optional
        Vertices that must not move (e.g. the boundary).

    Returns
    -------
    (n, 3) float64 new positions.
    """
    X = np.array(V, dtype=np.float64, copy=True)
    n = len(X)
    valence = np.bincount(F.reshape(-1), minlength=n).astype(np.float64)
    valence[valence == 0] = 1.0
    corners = F.reshape(-1)
    Nc = np.repeat(normals, 3, axis=0)
    for _ in range(iterations):
        C = X[F].mean(axis=1)
        d = np.repeat(C, 3, axis=0) - X[corners]
        step = Nc * np.einsum("ij,ij->i", Nc, d)[:, None]
        delta = np.column_stack([np.bincount(corners, weights=step[:, k], minlength=n) for k in range(3)])
        delta /= valence[:, None]
        if fixed is not None:
            delta[fixed] = 0.0
        X += delta
    return X
