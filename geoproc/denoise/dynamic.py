"""Denoising of an animation with fixed connectivity (Algorithm 4 of the review).

1. Every frame is denoised on its own (feature-preserving normal filtering and
   the vertex update, :func:`denoise_mesh`).
2. The face normals of all frames are stacked as the columns of a (3m, T)
   matrix and split by RPCA into a low-rank part, the temporally coherent
   normal field (the surface moves with few degrees of freedom), and a sparse
   part (frame-wise errors).
3. Every frame's vertices are updated towards its coherent normals.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from geoproc.denoise.face_geometry import face_normals_and_areas
from geoproc.denoise.mesh_denoise import DEFAULT_METHOD, DenoiseParams, denoise_mesh
from geoproc.denoise.rpca import rpca
from geoproc.denoise.vertex_update import update_vertices


def coherent_normals(V: np.ndarray, F: np.ndarray, lam: float | None = None) -> tuple[np.ndarray, dict]:
    """Temporally coherent face normals of every frame by RPCA.

    Parameters
    ----------
    V : (T, n, 3) float64 positions per frame; F : (m, 3) triangles.
    lam : float, optional
        RPCA sparsity weight (default ``1/sqrt(3m)``).

    Returns
    -------
    N : (T, m, 3) float64 unit normals (low-rank part, renormalized).
    info : dict with the RPCA iteration count, convergence and rank of the low-rank part.
    """
    T = len(V)
    m = len(F)
    D = np.empty((3 * m, T))
    for t in range(T):
        N, _ = face_normals_and_areas(V[t], F)
        D[:, t] = N.reshape(-1)
    res = rpca(D, lam=lam, tol=1e-7, max_iter=300)
    P = res.P.T.reshape(T, m, 3)
    norm = np.linalg.norm(P, axis=2, keepdims=True)
    out = np.where(norm > 1e-12, P / np.maximum(norm, 1e-300), D.T.reshape(T, m, 3))
    sv = np.linalg.svd(res.P, compute_uv=False)
    info = {"rpca_iterations": res.iterations, "rpca_converged": bool(res.converged),
            "low_rank": int((sv > 1e-6 * max(sv[0], 1e-300)).sum())}
    return out, info


def coherent_refinement(
    V: np.ndarray, F: np.ndarray, iterations: int = 3, fixed: np.ndarray | None = None,
) -> tuple[np.ndarray, dict]:
    """Steps 2 and 3: RPCA on the stacked face normals of the (per-frame
    denoised) frames, then ``iterations`` vertex-update sweeps of every frame
    towards its coherent normals.

    Parameters
    ----------
    V : (T, n, 3) float64 frames; F : (m, 3) triangles; fixed : (n,) bool, optional
        vertices that must not move.

    Returns
    -------
    V_out : (T, n, 3) float64; info : dict (RPCA iterations, convergence, rank).
    """
    N, info = coherent_normals(V, F)
    out = np.stack([update_vertices(V[t], F, N[t], iterations, fixed=fixed) for t in range(len(V))])
    return out, info


def denoise_animation(
    V: np.ndarray,
    F: np.ndarray,
    method: str = DEFAULT_METHOD,
    params: DenoiseParams | None = None,
    progress: Callable[[float], None] | None = None,
    coherent_iterations: int = 3,
) -> tuple[np.ndarray, dict]:
    """Denoise every frame of an animation, using its temporal coherence.

    Parameters
    ----------
    V : (T, n, 3) float64 noisy positions; F : (m, 3) int64 shared triangles.
    method, params : as for :func:`denoise_mesh` (step 1).
    progress : callable, optional
        Fraction done.
    coherent_iterations : int
        Vertex-update sweeps towards the coherent normals (step 3).

    Returns
    -------
    V_out : (T, n, 3) float64 denoised positions; info : dict of scalars.
    """
    T = len(V)
    p = DenoiseParams() if params is None else params
    per_frame = replace(p, features="none")  # only the positions are used
    static = np.empty_like(V, dtype=np.float64)
    for t in range(T):
        static[t] = denoise_mesh(V[t], F, method, per_frame).V
        if progress is not None:
            progress(0.9 * (t + 1) / T)
    fixed = None
    if p.pin_boundary:
        from geoproc.mesh.topology import boundary_vertices

        fixed = np.zeros(V.shape[1], dtype=bool)
        fixed[boundary_vertices(F)] = True
    out, info = coherent_refinement(static, F, coherent_iterations, fixed)
    if progress is not None:
        progress(1.0)
    info.update({"frames": T})
    return out, info
