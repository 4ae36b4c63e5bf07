"""Fit vertex positions to filtered face normals (Sun et al. 2007, Eq. 12-14)."""

from __future__ import annotations

import numba
import numpy as np

from geoproc.mesh.topology import vertex_corners


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
def _face_cross(X, D, scale, F, f):
    """Cross product of two edges of face ``f`` at positions ``X + scale * D``
    (twice the area times the normal), and its length (at least 1e-300).
    With ``scale`` 0 (and ``D`` finite) it is the cross product at ``X`` itself."""
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
    return r0, r1, r2, max(np.sqrt(r0 * r0 + r1 * r1 + r2 * r2), 1e-300)


@numba.njit(cache=True)
def _cos(r0, r1, r2, norm, n):
    """Cosine between the vector (r0, r1, r2) of length ``norm`` and the unit vector ``n``."""
    return (r0 * n[0] + r1 * n[1] + r2 * n[2]) / norm


@numba.njit(cache=True)
def _withhold(X, delta, F, normals, keep, use_keep, margin, vf_ptr, vf_idx):
    """In-place core of :func:`withhold_folding_steps`: the same passes, each
    judging the guarded faces with the steps as they stood at its start.

    The first pass judges every guarded face; a later pass only the faces
    around the vertices the previous pass froze, since no other face's steps
    changed (``vf_ptr``, ``vf_idx``: the faces around each vertex, CSR).
    """
    n = X.shape[0]
    m = F.shape[0]
    moving = np.zeros(n, dtype=np.bool_)
    for v in range(n):
        moving[v] = delta[v, 0] != 0.0 or delta[v, 1] != 0.0 or delta[v, 2] != 0.0
    guarded = np.zeros(m, dtype=np.bool_)
    check_keep = np.zeros(m, dtype=np.bool_)
    for f in range(m):
        if not (moving[F[f, 0]] or moving[F[f, 1]] or moving[F[f, 2]]):
            continue
        r0, r1, r2, norm = _face_cross(X, delta, 0.0, F, f)
        if not _cos(r0, r1, r2, norm, normals[f]) > margin:
            continue
        guarded[f] = True
        check_keep[f] = use_keep and _cos(r0, r1, r2, norm, keep[f]) > margin
    todo = np.flatnonzero(guarded)
    count = todo.shape[0]
    todo = np.concatenate((todo, np.empty(m - count, dtype=np.int64)))
    frozen = np.empty(n, dtype=np.int64)
    bad = np.empty(m, dtype=np.bool_)
    seen = np.full(m, -1, dtype=np.int64)  # the pass that last queued each face
    sweep = 0
    while count:  # ends: every pass freezes at least one more moving vertex
        for i in range(count):
            f = todo[i]
            r0, r1, r2, norm = _face_cross(X, delta, 1.0, F, f)
            b = not _cos(r0, r1, r2, norm, normals[f]) > margin
            if not b and check_keep[f]:
                b = not _cos(r0, r1, r2, norm, keep[f]) > margin
            bad[i] = b
        n_frozen = 0
        for i in range(count):
            f = todo[i]
            if bad[i]:
                for k in range(3):
                    v = F[f, k]
                    if moving[v]:
                        moving[v] = False
                        frozen[n_frozen] = v
                        n_frozen += 1
        sweep += 1
        count = 0
        for i in range(n_frozen):
            v = frozen[i]
            delta[v, 0] = 0.0
            delta[v, 1] = 0.0
            delta[v, 2] = 0.0
            for p in range(vf_ptr[v], vf_ptr[v + 1]):
                f = vf_idx[p]
                if guarded[f] and seen[f] != sweep:
                    seen[f] = sweep
                    todo[count] = f
                    count += 1


def vertex_face_csr(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The faces around every vertex: CSR (indptr (n + 1,), face ids), in face order."""
    indptr, corners = vertex_corners(F, n)
    return indptr, corners // 3


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
    vertex_faces = vertex_face_csr(F, n) if prevent_flips and iterations > 0 else None
    for _ in range(iterations):
        _fitting_step(X, F, normals, valence, pinned, delta)
        if fidelity:
            delta += fidelity * (A - X)
            delta[pinned] = 0.0
        if prevent_flips:
            delta = withhold_folding_steps(X, delta, F, normals, keep_orientation, margin, vertex_faces)
        X += delta
    return X


def withhold_folding_steps(
    X: np.ndarray,
    delta: np.ndarray,
    F: np.ndarray,
    normals: np.ndarray,
    keep_orientation: np.ndarray | None = None,
    margin: float = 0.0,
    vertex_faces: tuple[np.ndarray, np.ndarray] | None = None,
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
    vertex_faces : CSR (indptr, face ids), optional
        :func:`vertex_face_csr` of F, when the caller has it (a loop of sweeps
        over one connectivity); built here otherwise.

    Returns
    -------
    (n, 3) float64 steps: ``delta`` with the offending vertices' rows zeroed
    (modified in place).
    """
    use_keep = keep_orientation is not None
    keep = np.ascontiguousarray(keep_orientation if use_keep else normals, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    vf_ptr, vf_idx = vertex_face_csr(F, len(X)) if vertex_faces is None else vertex_faces
    _withhold(np.ascontiguousarray(X, dtype=np.float64), delta, F, np.ascontiguousarray(normals, dtype=np.float64),
              keep, use_keep, float(margin), vf_ptr, vf_idx)
    return delta


@numba.njit(cache=True)
def _folded(X, F, normals, edge_nb, use_nb, idx, out):
    """Core of :func:`folded_faces` for the faces ``idx``, into ``out``."""
    for i in range(idx.shape[0]):
        f = idx[i]
        r0, r1, r2, _ = _face_cross(X, X, 0.0, F, f)
        n = normals[f]
        folded = r0 * n[0] + r1 * n[1] + r2 * n[2] < 0.0
        if use_nb and not folded:
            g0 = g1 = g2 = 0.0  # area-weighted sums over the edge neighbours: geometry
            t0 = t1 = t2 = 0.0  # and target
            for k in range(3):
                j = edge_nb[f, k]
                if j < 0:
                    continue
                s0, s1, s2, _ = _face_cross(X, X, 0.0, F, j)
                g0 += s0
                g1 += s1
                g2 += s2
                area2 = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
                t0 += area2 * normals[j, 0]
                t1 += area2 * normals[j, 1]
                t2 += area2 * normals[j, 2]
            folded = r0 * g0 + r1 * g1 + r2 * g2 < 0.0 and n[0] * t0 + n[1] * t1 + n[2] * t2 > 0.0
        out[i] = folded


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
    out = np.empty(len(idx), dtype=np.bool_)
    use_nb = edge_nb is not None
    nb = np.ascontiguousarray(edge_nb if use_nb else np.zeros((0, 3)), dtype=np.int64)
    _folded(np.ascontiguousarray(X, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64),
            np.ascontiguousarray(normals, dtype=np.float64), nb, use_nb, idx, out)
    return out


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
    vertex_faces = vertex_face_csr(F, n) if count else None
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
        delta = withhold_folding_steps(X, delta, F, normals, keep_orientation, vertex_faces=vertex_faces)
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
