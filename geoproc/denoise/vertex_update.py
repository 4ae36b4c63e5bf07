"""Fit vertex positions to filtered face normals (Sun et al. 2007, Eq. 12-14)."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _fitting_step(X, F, normals, valence, fixed, delta):
    """Sun et al.'s step into ``delta``, summed over the corners in face order."""
    delta[:] = 0.0
    for f in range(F.shape[0]):
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        n0, n1, n2 = normals[f, 0], normals[f, 1], normals[f, 2]
        c0 = (X[a, 0] + X[b, 0] + X[c, 0]) / 3.0
        c1 = (X[a, 1] + X[b, 1] + X[c, 1]) / 3.0
        c2 = (X[a, 2] + X[b, 2] + X[c, 2]) / 3.0
        for k in range(3):
            v = F[f, k]
            s = n0 * (c0 - X[v, 0]) + n1 * (c1 - X[v, 1]) + n2 * (c2 - X[v, 2])
            delta[v, 0] += n0 * s
            delta[v, 1] += n1 * s
            delta[v, 2] += n2 * s
    for v in range(X.shape[0]):
        for k in range(3):
            delta[v, k] = 0.0 if fixed[v] else delta[v, k] / valence[v]


@numba.njit(cache=True)
def _face_cos(X, D, scale, F, f, n):
    """Cosine between the normal of face ``f`` at positions ``X + scale * D`` and the unit vector ``n``."""
    a, b, c = F[f, 0], F[f, 1], F[f, 2]
    u0 = X[b, 0] - X[a, 0] + scale * (D[b, 0] - D[a, 0])
    u1 = X[b, 1] - X[a, 1] + scale * (D[b, 1] - D[a, 1])
    u2 = X[b, 2] - X[a, 2] + scale * (D[b, 2] - D[a, 2])
    w0 = X[c, 0] - X[a, 0] + scale * (D[c, 0] - D[a, 0])
    w1 = X[c, 1] - X[a, 1] + scale * (D[c, 1] - D[a, 1])
    w2 = X[c, 2] - X[a, 2] + scale * (D[c, 2] - D[a, 2])
    r0 = u1 * w2 - u2 * w1
    r1 = u2 * w0 - u0 * w2
    r2 = u0 * w1 - u1 * w0
    norm = max(np.sqrt(r0 * r0 + r1 * r1 + r2 * r2), 1e-300)
    return (r0 * n[0] + r1 * n[1] + r2 * n[2]) / norm


@numba.njit(cache=True)
def _withhold(X, delta, F, normals, keep, use_keep, margin):
    """In-place core of :func:`withhold_folding_steps`: the same passes, each
    judging every guarded face with the steps as they stood at its start."""
    n = X.shape[0]
    moving = np.zeros(n, dtype=np.bool_)
    for v in range(n):
        moving[v] = delta[v, 0] != 0.0 or delta[v, 1] != 0.0 or delta[v, 2] != 0.0
    guarded = np.empty(F.shape[0], dtype=np.int64)
    check_keep = np.zeros(F.shape[0], dtype=np.bool_)
    count = 0
    for f in range(F.shape[0]):
        if not (moving[F[f, 0]] or moving[F[f, 1]] or moving[F[f, 2]]):
            continue
        if not _face_cos(X, delta, 0.0, F, f, normals[f]) > margin:
            continue
        guarded[count] = f
        check_keep[count] = use_keep and _face_cos(X, delta, 0.0, F, f, keep[f]) > margin
        count += 1
    freeze = np.zeros(n, dtype=np.bool_)
    while True:  # ends: every pass freezes at least one more vertex
        any_bad = False
        for i in range(count):
            f = guarded[i]
            bad = not _face_cos(X, delta, 1.0, F, f, normals[f]) > margin
            if not bad and check_keep[i]:
                bad = not _face_cos(X, delta, 1.0, F, f, keep[f]) > margin
            if bad:
                any_bad = True
                for k in range(3):
                    freeze[F[f, k]] = True
        if not any_bad:
            return
        for v in range(n):
            if freeze[v]:
                delta[v, 0] = 0.0
                delta[v, 1] = 0.0
                delta[v, 2] = 0.0
                freeze[v] = False


def _raw_normals(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    return np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])


def update_vertices(
    V: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    iterations: int = 20,
    fixed: np.ndarray | None = None,
    prevent_flips: bool = True,
    keep_orientation: np.ndarray | None = None,
    margin: float = 0.0,
    anchor: np.ndarray | None = None,
    fidelity: float = 0.0,
) -> np.ndarray:
    """Move vertices so that faces become orthogonal to the target normals.

    Each iteration applies ``x_i += 1/|F_i| sum_{f in F_i} n_f (n_f . (c_f - x_i))``
    with the face centroids ``c_f`` of the current positions (a gradient step on
    ``sum_f sum_{(i,j) in f} (n_f . (x_j - x_i))^2``). With ``fidelity`` each
    step also adds ``fidelity * (a_i - x_i)``, a pull towards the ``anchor``
    positions (a data term: the fixed point balances the normal fit against
    the distance to the anchor).

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
    anchor : (n, 3) float64, optional
        Positions the data term pulls towards (the input's, in
        :func:`geoproc.denoise.mesh_denoise.denoise_mesh`); ``V`` when None.
    fidelity : float
        Weight of that pull per sweep, as a fraction of the distance (0: none).

    Returns
    -------
    (n, 3) float64 new positions.
    """
    X = np.array(V, dtype=np.float64, copy=True)
    n = len(X)
    F = np.ascontiguousarray(F, dtype=np.int64)
    normals = np.ascontiguousarray(normals, dtype=np.float64)
    valence = np.bincount(F.reshape(-1), minlength=n).astype(np.float64)
    valence[valence == 0] = 1.0
    pinned = np.zeros(n, dtype=bool) if fixed is None else np.asarray(fixed, dtype=bool)
    delta = np.empty_like(X)
    if fidelity:
        A = X.copy() if anchor is None else np.asarray(anchor, dtype=np.float64)
    for _ in range(iterations):
        _fitting_step(X, F, normals, valence, pinned, delta)
        if fidelity:
            delta += fidelity * (A - X)
            delta[pinned] = 0.0
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
    use_keep = keep_orientation is not None
    keep = np.ascontiguousarray(keep_orientation if use_keep else normals, dtype=np.float64)
    _withhold(np.ascontiguousarray(X, dtype=np.float64), delta, np.ascontiguousarray(F, dtype=np.int64),
              np.ascontiguousarray(normals, dtype=np.float64), keep, use_keep, float(margin))
    return delta


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
