"""Target normals of faces the vertex fit squashed against a crease."""

from __future__ import annotations

import numpy as np

from geoproc.denoise.face_geometry import face_normals_and_areas


def bisect_collapsed_targets(
    X: np.ndarray,
    F: np.ndarray,
    N: np.ndarray,
    A_input: np.ndarray,
    edge_nb: np.ndarray,
    ratio: float = 0.3,
    differ_deg: float = 30.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Replace the target of collapsed crease faces by a bisector.

    A face whose area after the fit is below ``ratio`` times its input area,
    and whose target normal differs from an edge neighbour's by more than
    ``differ_deg``, straddles a crease of the target field: the filter gave
    it one side's normal, the fit squashed it between the two sides, and when
    the side is the wrong one it ends folded past 90 degrees. Its target
    becomes the normalised sum of its own and its most different edge
    neighbour's target, which no side choice can leave more than 90 degrees off.

    Parameters
    ----------
    X : (n, 3) float64 positions after the fit; F : (m, 3) int64 triangles.
    N : (m, 3) float64 unit target normals.
    A_input : (m,) float64 face areas of the input (squared length units).
    edge_nb : (m, 3) int64 edge-adjacent face per corner, -1 on a boundary.
    ratio : float
        Area ratio below which a face counts as collapsed.
    differ_deg : float
        Angle (degrees) to the most different edge neighbour's target above
        which the face straddles a crease.

    Returns
    -------
    targets : (m, 3) float64 unit normals (a copy of N with the faces replaced).
    changed : (m,) bool the faces replaced.
    """
    _, A = face_normals_and_areas(X, F)
    collapsed = A < ratio * np.asarray(A_input, dtype=np.float64)
    Nn = N[np.maximum(edge_nb, 0)]  # (m, 3, 3) neighbours' targets
    cos = np.einsum("ij,ikj->ik", N, Nn)
    cos[edge_nb < 0] = 2.0
    k = np.argmin(cos, axis=1)
    rows = np.arange(len(F))
    changed = collapsed & (cos[rows, k] < np.cos(np.radians(differ_deg)))
    out = N.copy()
    B = N[changed] + Nn[rows[changed], k[changed]]
    out[changed] = B / np.maximum(np.linalg.norm(B, axis=1, keepdims=True), 1e-300)
    return out, changed
