"""Denoising of an animation with fixed connectivity (after Algorithm 4 of the review).

1. Every frame is denoised on its own (feature-preserving normal filtering and
   the vertex update, :func:`denoise_mesh`).
2. Each frame's result is split into a smooth base (one implicit step of the
   uniform Laplacian) and the height of every vertex above it along the
   base's vertex normal. The surface carries its detail as it moves, so the
   heights of a vertex over time are nearly one value, with the residual
   noise of each frame on top; where the shape itself changes, they change
   in a few coherent ways. The (n, T) matrix of heights is split by RPCA into
   a low-rank part (the coherent detail) and a sparse part.
3. Every frame's vertices move along the base normals to their low-rank heights,
   except those of faces the move would turn more than 20 degrees from the
   frame's own result (:func:`limit_face_turn`): without that guard the move
   folded faces at thin parts (elephant, 29 frames, noise 0.3, when the guard
   came in: 378 faces newly flipped against 75 frame by frame; with it 71, and
   4.58 degrees instead of 4.74; today 66 new flips and 4.54 degrees against
   70 and 5.05 frame by frame, ``bench/denoise_pairs.py: dynamic_table``).

The review's Algorithm 4 itself (``coherence="normals"``,
:func:`coherent_normal_fit`) applies RPCA to the stacked face normals and then
fits the vertices to them; measured against the current frame-by-frame
method it is worse (elephant, 29 frames, noise 0.3: 5.24 against 5.05 degrees,
119 new flips against 70), while the heights give 4.54. It is kept to
reproduce the review.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import igl
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from geoproc.denoise import COHERENCE
from geoproc.denoise.connectivity import face_connectivity
from geoproc.denoise.face_geometry import face_normals_and_areas, vertex_normals
from geoproc.denoise.mesh_denoise import DEFAULT_METHOD, DenoiseParams, denoise_mesh
from geoproc.denoise.rpca import rpca
from geoproc.denoise.vertex_update import update_vertices
from geoproc.errors import InputError, UsageError
from geoproc.mesh.validate import mesh_arrays


def normal_heights(V: np.ndarray, F: np.ndarray, smoothing: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Height of every vertex above a smooth base of its frame, along the base normal.

    The base of a frame is ``(I + smoothing L)^-1 X`` with the uniform graph
    Laplacian L (degree minus adjacency); its area-weighted vertex normals
    (:func:`geoproc.denoise.face_geometry.vertex_normals`) give the direction.

    Parameters
    ----------
    V : (T, n, 3) float64 positions per frame; F : (m, 3) int64 triangles.
    smoothing : float
        Implicit smoothing step (unitless: the uniform Laplacian counts neighbours).

    Returns
    -------
    H : (T, n) float64 heights (length units); Nv : (T, n, 3) float64 unit base normals.
    """
    T, n = V.shape[:2]
    A = sp.csr_matrix(igl.adjacency_matrix(F), dtype=np.float64)
    if A.shape[0] < n:  # vertices after the last one a face uses: no neighbours
        A.resize((n, n))
    L = sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A
    solve = spla.factorized((sp.identity(n) + smoothing * L).tocsc())
    H = np.empty((T, n))
    Nv = np.empty((T, n, 3))
    for t in range(T):
        base = np.column_stack([solve(np.ascontiguousarray(V[t][:, k])) for k in range(3)])
        Nv[t] = vertex_normals(base, F)
        H[t] = np.einsum("ij,ij->i", V[t] - base, Nv[t])
    return H, Nv


def limit_face_turn(
    V: np.ndarray, F: np.ndarray, shift: np.ndarray, directions: np.ndarray, max_turn_deg: float = 20.0,
    max_rounds: int = 50,
) -> tuple[np.ndarray, int]:
    """Cancel the moves that would turn faces too far.

    ``V + shift[:, None] * directions`` is the moved frame; while some face of
    it is more than ``max_turn_deg`` from its normal in V, the shifts of that
    face's vertices are set to 0.

    Parameters
    ----------
    V : (n, 3) float64 positions; F : (m, 3) int64 triangles.
    shift : (n,) float64 move of each vertex along its direction (length units).
    directions : (n, 3) float64 unit directions.
    max_turn_deg : float
        Largest angle in degrees a face may turn.
    max_rounds : int
        Rounds of cancelling (each round cancels every offending face's vertices).

    Returns
    -------
    shift : (n,) float64 the kept shifts; cancelled : int vertices whose shift was cancelled.
    """
    shift = np.array(shift, dtype=np.float64, copy=True)
    N0, _ = face_normals_and_areas(V, F)
    cos_min = np.cos(np.radians(max_turn_deg))
    cancelled = np.zeros(len(V), dtype=bool)
    for _ in range(max_rounds):
        N, _ = face_normals_and_areas(V + shift[:, None] * directions, F)
        bad = np.einsum("ij,ij->i", N, N0) < cos_min
        verts = np.unique(F[bad])
        verts = verts[shift[verts] != 0.0]
        if not len(verts):
            break
        shift[verts] = 0.0
        cancelled[verts] = True
    return shift, int(cancelled.sum())


def coherent_heights(
    V: np.ndarray, F: np.ndarray, smoothing: float = 0.5, lam: float | None = None,
    fixed: np.ndarray | None = None, max_turn_deg: float = 20.0,
) -> tuple[np.ndarray, dict]:
    """Steps 2 and 3: every frame's vertices moved along their base normals to
    the low-rank part of the (n, T) matrix of normal heights.

    Parameters
    ----------
    V : (T, n, 3) float64 frames (each already denoised); F : (m, 3) triangles.
    smoothing : float
        See :func:`normal_heights`.
    lam : float, optional
        RPCA sparsity weight (default ``1/sqrt(max(n, T))``).
    fixed : (n,) bool, optional
        Vertices that must not move.
    max_turn_deg : float
        No face turns more than this (degrees) from its normal in V
        (:func:`limit_face_turn`, frame by frame).

    Returns
    -------
    V_out : (T, n, 3) float64; info : dict (RPCA iterations, convergence, rank
    of the low-rank part, ``turn_limited_vertices``: vertex moves cancelled
    over all frames).
    """
    H, Nv = normal_heights(V, F, smoothing)
    res = rpca(np.ascontiguousarray(H.T), lam=lam, tol=1e-7, max_iter=500)
    shift = res.P.T - H
    if fixed is not None:
        shift[:, fixed] = 0.0
    cancelled = 0
    for t in range(len(V)):
        shift[t], c = limit_face_turn(V[t], F, shift[t], Nv[t], max_turn_deg)
        cancelled += c
    return V + shift[:, :, None] * Nv, {**_rpca_info(res), "turn_limited_vertices": cancelled}


def coherent_normals(V: np.ndarray, F: np.ndarray, lam: float | None = None) -> tuple[np.ndarray, dict]:
    """Temporally coherent face normals of every frame: the low-rank part of the
    (3m, T) matrix whose columns are the frames' stacked face normals, taken
    in the principal axes of all the normals so that the result turns with
    the animation.

    Parameters
    ----------
    V : (T, n, 3) float64 positions per frame; F : (m, 3) int64 triangles.
    lam : float, optional
        RPCA sparsity weight (default ``1/sqrt(max(3m, T))``).

    Returns
    -------
    N : (T, m, 3) float64 unit normals (the low-rank part, renormalized; a
    face whose low-rank normal vanishes keeps its own).
    info : dict (RPCA iterations, convergence, rank of the low-rank part).
    """
    T, m = len(V), len(F)
    N0 = np.stack([face_normals_and_areas(V[t], F)[0] for t in range(T)])  # (T, m, 3)
    # in the principal axes of all the normals (eigenvectors of sum n n^T), which turn with
    # the animation: RPCA's sparse term is entrywise, so in world axes its result did not
    _, R = np.linalg.eigh(np.einsum("tmi,tmj->ij", N0, N0))
    D = np.ascontiguousarray((N0 @ R).reshape(T, 3 * m).T)
    res = rpca(D, lam=lam, tol=1e-7, max_iter=500)
    P = res.P.T.reshape(T, m, 3) @ R.T
    norm = np.linalg.norm(P, axis=2, keepdims=True)
    N = np.where(norm > 1e-12, P / np.maximum(norm, 1e-300), N0)
    return N, _rpca_info(res)


def coherent_normal_fit(
    V: np.ndarray, F: np.ndarray, iterations: int = 3, lam: float | None = None,
    fixed: np.ndarray | None = None,
) -> tuple[np.ndarray, dict]:
    """Steps 2 and 3 of the review's Algorithm 4: :func:`coherent_normals`, then
    ``iterations`` vertex-update sweeps (Sun et al.) of every frame towards them.

    Parameters
    ----------
    V : (T, n, 3) float64 frames (each already denoised); F : (m, 3) int64 triangles.
    iterations : int
        Vertex-update sweeps per frame.
    lam : float, optional
        RPCA sparsity weight (see :func:`coherent_normals`).
    fixed : (n,) bool, optional
        Vertices that must not move.

    Returns
    -------
    V_out : (T, n, 3) float64; info : dict as for :func:`coherent_normals`.
    """
    N, info = coherent_normals(V, F, lam)
    out = np.stack([update_vertices(V[t], F, N[t], iterations, fixed=fixed) for t in range(len(V))])
    return out, info


def _rpca_info(res) -> dict:
    sv = np.linalg.svd(res.P, compute_uv=False)
    return {"rpca_iterations": res.iterations, "rpca_converged": bool(res.converged),
            "low_rank": int((sv > 1e-6 * max(sv[0], 1e-300)).sum())}


def denoise_animation(
    V: np.ndarray,
    F: np.ndarray,
    method: str = DEFAULT_METHOD,
    params: DenoiseParams | None = None,
    progress: Callable[[float], None] | None = None,
    smoothing: float = 0.5,
    coherence: str = "heights",
) -> tuple[np.ndarray, dict]:
    """Denoise every frame of an animation, using its temporal coherence.

    Parameters
    ----------
    V : (T, n, 3) float64 noisy positions; F : (m, 3) int64 shared triangles.
    method, params : as for :func:`denoise_mesh` (step 1).
    progress : callable, optional
        Fraction done.
    smoothing : float
        Implicit smoothing step of the base surface (step 2, :func:`normal_heights`).
    coherence : {"heights", "normals"}
        What RPCA makes coherent over time: the normal heights over a smooth
        base (:func:`coherent_heights`, the default: lower error) or the
        stacked face normals, as in the review's Algorithm 4
        (:func:`coherent_normal_fit`).

    Returns
    -------
    V_out : (T, n, 3) float64 denoised positions; info : dict of scalars,
        with the static step's schedule over the frames (each frame's is chosen
        from its own noise, :func:`frame_schedule_summary`).
    """
    if coherence not in COHERENCE:
        raise ValueError(f"coherence {coherence!r}: use one of {', '.join(COHERENCE)}")
    T = len(V)
    p = DenoiseParams() if params is None else params
    per_frame = replace(p, features="none")  # only the positions are used
    from geoproc.mesh.topology import repeated_corner_faces

    repeated = repeated_corner_faces(np.asarray(F).reshape(-1, 3))
    F = np.asarray(F).reshape(-1, 3)[~repeated]  # no area, no normal: left out, as by denoise_mesh
    static = np.empty_like(V, dtype=np.float64)
    frame_info = []
    conn = None  # the faces, checked and prepared once for all frames
    for t in range(T):
        try:
            if conn is None:
                Vt, Ft = mesh_arrays(V[t], F)
                conn = face_connectivity(Ft, len(Vt))
            res = denoise_mesh(V[t], F, method, per_frame, connectivity=conn)
            static[t] = res.V
            frame_info.append(res.info)
        except InputError as exc:  # say which frame
            raise InputError(exc.path, f"frame {t}: {exc.problem}") from None
        except UsageError as exc:
            raise UsageError(f"frame {t}: {exc}") from None
        if progress is not None:
            progress(0.9 * (t + 1) / T)
    fixed = None
    if p.pin_boundary:
        from geoproc.mesh.topology import boundary_vertices

        fixed = np.zeros(V.shape[1], dtype=bool)
        fixed[boundary_vertices(F)] = True
    if coherence == "heights":  # vertex normals need the faces turned consistently
        out, info = coherent_heights(static, conn.F if conn is not None else F, smoothing, fixed=fixed)
    else:
        out, info = coherent_normal_fit(static, F, fixed=fixed)
    if progress is not None:
        progress(1.0)
    info.update({"frames": T, "coherence": coherence, "repeated_corner_faces": int(repeated.sum()),
                 **frame_schedule_summary(frame_info)})
    return out, info


SCHEDULE_MEANS = ("noise_roughness", "sigma_r", "sigma_s", "guidance_mix")
SCHEDULE_LARGEST = ("outer_iterations", "normal_iterations", "scale_groups")


def frame_schedule_summary(frame_info: list[dict]) -> dict:
    """The static step's noise estimate and schedule over the frames, from each
    frame's :func:`denoise_mesh` info: the mean of ``SCHEDULE_MEANS`` (the
    roughness, the kernel widths, the guidance mix) and the largest of
    ``SCHEDULE_LARGEST`` (rounds, passes per round), over the frames where
    they acted (not None); None where they acted on no frame (every frame
    clean); entries no frame has are left out."""
    out: dict = {}
    for key in SCHEDULE_MEANS + SCHEDULE_LARGEST:
        if not any(key in i for i in frame_info):
            continue
        values = [i[key] for i in frame_info if i.get(key) is not None]
        out[key] = (float(np.mean(values)) if key in SCHEDULE_MEANS else int(max(values))) if values else None
    return out
