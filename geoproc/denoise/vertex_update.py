"""Fit vertex positions to filtered face normals (Sun et al. 2007, Eq. 12-14)."""

from __future__ import annotations

import numpy as np


def _raw_normals(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    return np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])


def _unit(R: np.ndarray) -> np.ndarray:
    return R / np.maximum(np.linalg.norm(R, axis=1, keepdims=True), 1e-300)


def update_vertices(
    V: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    iterations: int = 20,
    fixed: np.ndarray | None = None,
    prevent_flips: bool = True,
    keep_orientation: np.ndarray | None = None,
    margin: float = 0.0,
) -> np.ndarray:
    """Move vertices so that faces become orthogonal to the target normals.

    Each iteration applies ``x_i += 1/|F_i| sum_{f in F_i} n_f (n_f . (c_f - x_i))``
    with the face centroids ``c_f`` of the current positions (a gradient step on
    ``sum_f sum_{(i,j) in f} (n_f . (x_j - x_i))^2``).

    With ``prevent_flips`` a step is withheld from the vertices of any face that
    the step would turn to face away from its target normal (while it faced
    along it before), so the update never creates a fold-over; faces that start
    out folded are free to unfold.

    Parameters
    ----------
    V : (n, 3) float64 positions; F : (m, 3) int64 triangles.
    normals : (m, 3) float64
        Target unit normal of each face.
    iterations : int
        Number of update sweeps.
    fixed : (n,) bool, optional
        Vertices that must not move (e.g. the boundary).
    prevent_flips : bool
        Withhold steps that would fold a face over (see above).
    margin : float
        Cosine the guard keeps: 0 forbids turning past 90 degrees; larger values
        keep faces closer to their target and input normals.
    keep_orientation : (m, 3) float64, optional
        Normals of the input: with ``prevent_flips``, a face that agrees with
        its target is also kept within 90 degrees of this normal (a wrong target
        at a sharp feature then cannot fold the face over); faces that start
        against their target are exempt, so flipped input faces can unfold.

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
        if prevent_flips:
            R0 = _unit(_raw_normals(X, F))
            before = np.einsum("ij,ij->i", R0, normals) > margin
            if keep_orientation is not None:
                before_k = before & (np.einsum("ij,ij->i", R0, keep_orientation) > margin)
            while True:  # ends: every pass freezes at least one more vertex
                R1 = _unit(_raw_normals(X + delta, F))
                after = np.einsum("ij,ij->i", R1, normals) > margin
                bad = before & ~after
                if keep_orientation is not None:
                    bad |= before_k & ~(np.einsum("ij,ij->i", R1, keep_orientation) > margin)
                if not bad.any():
                    break
                delta[F[bad].reshape(-1)] = 0.0
        X += delta
    return X
