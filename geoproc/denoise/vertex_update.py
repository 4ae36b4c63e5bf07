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
            delta = withhold_folding_steps(X, delta, F, normals, keep_orientation, margin)
        X += delta
    return X


def withhold_folding_steps(
    X: np.ndarray,
    delta: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    keep_orientation: np.ndarray | None = None,
    margin: float = 0.0,
) -> np.ndarray:
    """Zero the steps of the vertices of every face that a step would fold over.

    A face that agrees with its target normal (cosine above ``margin``) before
    the step must still agree after it; with ``keep_orientation`` such a face
    must also stay within 90 degrees of that normal. Vertices are frozen a face
    at a time until no guarded face folds (each pass freezes at least one more
    vertex, so the loop ends). Faces that start against their target are not
    guarded.

    Parameters
    ----------
    X : (n, 3) float64 positions; delta : (n, 3) float64 proposed steps (length units).
    F : (m, 3) int64 triangles; normals : (m, 3) float64 unit target normals.
    keep_orientation : (m, 3) float64, optional
        Unit normals (the input's) that guarded faces must stay within 90 degrees of.
    margin : float
        Cosine the guard keeps (0: 90 degrees).

    Returns
    -------
    (n, 3) float64 steps: ``delta`` with the offending vertices' rows zeroed
    (modified in place).
    """
    moving = (delta != 0.0).any(axis=1)
    act = np.flatnonzero(moving[F].any(axis=1))  # only faces with a moving corner can change
    if len(act) == len(F):
        Fa, Na, Ka = F, normals, keep_orientation
    else:
        Fa, Na = F[act], normals[act]
        Ka = None if keep_orientation is None else keep_orientation[act]
    R0 = _unit(_raw_normals(X, Fa))
    before = np.einsum("ij,ij->i", R0, Na) > margin
    if Ka is not None:
        before_k = before & (np.einsum("ij,ij->i", R0, Ka) > margin)
    while True:  # ends: every pass freezes at least one more vertex
        R1 = _unit(_raw_normals(X + delta, Fa))
        bad = before & ~(np.einsum("ij,ij->i", R1, Na) > margin)
        if Ka is not None:
            bad |= before_k & ~(np.einsum("ij,ij->i", R1, Ka) > margin)
        if not bad.any():
            return delta
        delta[Fa[bad].reshape(-1)] = 0.0


def folded_faces(
    X: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    edge_nb: np.ndarray | None = None,
    faces: np.ndarray | None = None,
) -> np.ndarray:
    """Faces folded over: against their target normal, or against their neighbours.

    A face is folded when its normal is more than 90 degrees from its target
    normal, or (with ``edge_nb``) more than 90 degrees from the area-weighted
    mean normal of its edge neighbours while its target is within 90 degrees of
    the neighbours' area-weighted mean target: the filtered field is smooth
    there, so the disagreement is a fold of the geometry, not a crease.

    Parameters
    ----------
    X : (n, 3) float64 positions; F : (m, 3) int64 triangles.
    normals : (m, 3) float64 unit target normals.
    edge_nb : (m, 3) int64, optional
        Edge-adjacent face per corner, -1 on a boundary
        (:func:`geoproc.denoise.face_geometry.face_edge_neighbors`).
    faces : (k,) int64, optional
        Test only these faces (default: all).

    Returns
    -------
    (k,) bool, or (m,) without ``faces``.
    """
    idx = np.arange(len(F)) if faces is None else np.asarray(faces, dtype=np.int64)
    if edge_nb is None or faces is None:
        need = idx
    else:
        need = np.union1d(idx, edge_nb[idx].reshape(-1))
        need = need[need >= 0]
    R_need = _raw_normals(X, F[need])  # length = twice the area
    R = R_need if need is idx else R_need[np.searchsorted(need, idx)]
    folded = np.einsum("ij,ij->i", R, normals[idx]) < 0.0
    if edge_nb is not None and len(idx):
        nb = edge_nb[idx]
        has = (nb >= 0).astype(np.float64)
        nb = np.maximum(nb, 0)
        Rn = (R_need[nb] if need is idx else R_need[np.searchsorted(need, nb)]) * has[:, :, None]
        area2 = np.sqrt(np.einsum("ijk,ijk->ij", Rn, Rn))
        geometry = Rn.sum(axis=1)  # area-weighted sums over the edge neighbours
        target = np.einsum("ij,ijk->ik", area2, normals[nb])
        folded |= (np.einsum("ij,ij->i", R, geometry) < 0.0) & (np.einsum("ij,ij->i", normals[idx], target) > 0.0)
    return folded


def unfold_faces(
    X: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    edge_nb: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
    keep_orientation: np.ndarray | None = None,
    rounds: int = 5,
) -> tuple[np.ndarray, int]:
    """Repair folded faces by relaxing their vertices.

    The normal-fitting update moves a vertex only along the target normals of
    its faces, so a face folded by a lateral misplacement (a vertex pushed
    across an opposite edge) cannot unfold by it. Each round finds the folded
    faces (:func:`folded_faces`) and moves each of their vertices to the mean
    of the centroids of the faces around it (an umbrella step, which undoes a
    lateral misplacement), with the steps that would fold another face
    withheld (:func:`withhold_folding_steps`). It stops when no face is
    folded, when a round leaves as many folded faces as before (the rest are
    held by the guard), or after ``rounds`` rounds. The reference shape is
    never used.

    Parameters
    ----------
    X : (n, 3) float64 positions; F : (m, 3) int64 triangles.
    normals : (m, 3) float64 unit target normals.
    edge_nb : (m, 3) int64, optional
        Edge neighbours: also repair folds against the neighbours (see :func:`folded_faces`).
    fixed : (n,) bool, optional
        Vertices that must not move.
    keep_orientation : (m, 3) float64, optional
        Passed to :func:`withhold_folding_steps`.
    rounds : int
        Most relaxation rounds.

    Returns
    -------
    X : (n, 3) float64 repaired positions (a copy).
    folded : int
        Faces still folded at the end.
    """
    X = np.array(X, dtype=np.float64, copy=True)
    n = len(X)
    folded = folded_faces(X, F, normals, edge_nb)
    count = int(folded.sum())
    for _ in range(rounds):
        if count == 0:
            break
        move = np.zeros(n, dtype=bool)
        move[F[folded].reshape(-1)] = True
        if fixed is not None:
            move &= ~fixed
        verts = np.flatnonzero(move)
        delta = np.zeros_like(X)
        delta[verts] = _centroid_umbrella(X, F, verts) - X[verts]
        delta = withhold_folding_steps(X, delta, F, normals, keep_orientation)
        moved = (delta != 0.0).any(axis=1)
        if not moved.any():
            break
        X += delta
        near = moved[F].any(axis=1)  # faces whose shape changed, then their edge neighbours
        if edge_nb is not None:
            nb = edge_nb[near].reshape(-1)
            near[nb[nb >= 0]] = True
        faces = np.flatnonzero(near)
        folded[faces] = folded_faces(X, F, normals, edge_nb, faces)
        new_count = int(folded.sum())
        if new_count >= count:
            count = new_count
            break
        count = new_count
    return X, count


def _centroid_umbrella(X: np.ndarray, F: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """(k, 3) mean of the centroids of the faces around each of ``verts`` (an isolated vertex stays)."""
    inc = np.isin(F, verts)
    fi, ci = np.nonzero(inc)
    C = X[F[fi]].mean(axis=1)
    slot = np.searchsorted(verts, F[fi, ci])
    total = np.zeros((len(verts), 3))
    np.add.at(total, slot, C)
    cnt = np.bincount(slot, minlength=len(verts)).astype(np.float64)
    out = X[verts].copy()
    has = cnt > 0
    out[has] = total[has] / cnt[has, None]
    return out
