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


def input_side_targets(
    N: np.ndarray,
    N_input: np.ndarray,
    neighbors: tuple[np.ndarray, np.ndarray],
    max_angle_deg: float = 90.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Give faces the filter turned past a crease the target of their input's side.

    A target more than ``max_angle_deg`` from the face's own input normal
    means the filter put the face on the far side of a crease sharper than
    that angle (on smooth parts of the surface the filtered normal stays near
    the input normal's side). If a face of its neighbourhood has a target
    within ``max_angle_deg`` of the face's input normal, the face takes the
    one closest to it; otherwise (an input face folded by the noise, which
    the filter turned back) its target is kept.

    Parameters
    ----------
    N : (m, 3) float64 unit target normals.
    N_input : (m, 3) float64 unit face normals of the input.
    neighbors : (indptr, indices) CSR face neighbourhoods (the filter's, see
        :func:`geoproc.denoise.face_geometry.face_ring_csr`).
    max_angle_deg : float
        Largest angle (degrees) kept between a target and its input normal.

    Returns
    -------
    targets : (m, 3) float64 unit normals (a copy of N with the faces replaced).
    changed : (m,) bool the faces replaced.
    """
    indptr, indices = neighbors
    ct = np.cos(np.radians(max_angle_deg))
    bad = np.flatnonzero(np.einsum("ij,ij->i", N, N_input) < ct)
    out = N.copy()
    changed = np.zeros(len(N), dtype=bool)
    if len(bad) == 0:
        return out, changed
    counts = indptr[bad + 1] - indptr[bad]
    owner = np.repeat(np.arange(len(bad)), counts)
    pos = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(indptr[bad], counts)
    cand = indices[pos]
    score = np.einsum("ij,ij->i", N[cand], N_input[bad[owner]])
    # best candidate per face: sort by (owner, -score), take each owner's first
    order = np.lexsort((-score, owner))
    first = order[np.r_[0, np.flatnonzero(np.diff(owner[order])) + 1]]
    ok = score[first] > ct
    faces = bad[owner[first[ok]]]
    out[faces] = N[cand[first[ok]]]
    changed[faces] = True
    return out, changed
