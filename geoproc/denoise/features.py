"""Sharp-feature identification by l1 minimisation of the normal Laplacian.

On a piecewise-flat surface the normal component of the (uniform) Laplacian,
``J_i = n_i . (L_i v)`` with ``L_i v = v_i - mean_{j ~ i} v_j``, vanishes
everywhere except on the vertices of creases and corners: the vector J is
sparse and its support marks the features (Eq. 54-56 of the review). Noise and
smooth curvature make J small but non-zero everywhere, so the sparse part is
found by an l1-regularized fit: the vertices may move along their normals by
``d`` (kept small by a least-squares term) so that the normal Laplacian of the
moved surface is as sparse as possible,

    min_d  1/2 |d|^2 + lam |J0 + A d|_1,
    J0_i = n_i . (L v)_i,   A_ij = L_ij (n_i . n_j),

(J of ``v + d n`` is ``J0 + A d`` to first order, normals held fixed). The l1
term does not penalise a crease for being sharp (a crease's J has one sign, and
moving it between neighbours keeps its l1 norm) while small oscillations of
either sign cost more than the displacement that removes them: the minimiser
keeps the creases and zeroes the rest. It is solved by ADMM on the splitting
``z = J0 + A d``; feature vertices are those whose ``|z|`` exceeds ``tau``
(smooth curvature leaves a small non-zero z). J of a vertex is measured in
the mean length of its own edges.

For scale: a vertex on a straight crease of exterior angle theta in a regular
triangulation has ``|J| ~ 0.59 sin(theta / 2)`` edge lengths: 0.10 at 20
degrees, 0.12 at 24, 0.15 at 30, 0.29 at 60, 0.42 at 90.

On a noisy input the noise's J is as large as a crease's; the denoiser
therefore identifies the features of its output (the base mesh of a two-phase
scheme), where the l1 step removes the residual oscillations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from geoproc.denoise.face_geometry import vertex_normals
from geoproc.mesh.topology import referenced_vertices, unique_edges
from geoproc.mesh.validate import mesh_arrays

#: default cut on |J| (local mean edge lengths): a crease of about 24 degrees on a regular mesh
DEFAULT_TAU = 0.12


@dataclass
class L1FeatureResult:
    """Output of :func:`l1_feature_vertices`.

    Attributes
    ----------
    J : (n,) float64
        Sparse normal Laplacian ``z`` of the l1 solution, in local mean edge lengths.
    J0 : (n,) float64
        Normal Laplacian of the input, in local mean edge lengths.
    offset : (n,) float64
        Displacement ``d`` along the vertex normals, in mean edge lengths.
    feature : (n,) bool
        ``|J| > tau``.
    lam, tau : float
        The regularization weight and cut used.
    iterations : int
        ADMM iterations run.
    converged : bool
        Whether the primal and dual residuals fell below the tolerance.
    """

    J: np.ndarray
    J0: np.ndarray
    offset: np.ndarray
    feature: np.ndarray
    lam: float
    tau: float
    iterations: int
    converged: bool


def normal_laplacian(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix, float]:
    """The normal Laplacian of a mesh and its linearization along the normals.

    Each vertex's J is measured in its own mean edge length ``h_i`` (irregular
    triangulations mix long and short edges), displacements in the mesh's
    mean edge length ``h``.

    Parameters
    ----------
    V : (n, 3) float64; F : (m, 3) int64 triangles.

    Returns
    -------
    J0 : (n,) float64
        ``n_i . (v_i - mean_{j ~ i} v_j) / h_i`` (0 for isolated vertices).
    A : (n, n) CSR
        ``A_ij = (h / h_i) L_ij (n_i . n_j)`` with the uniform Laplacian
        ``L = I - D^-1 W``: ``J0 + A d`` is the normal Laplacian after moving
        every vertex by ``h d_i n_i`` (normals held fixed).
    h : float
        The mean edge length (the length unit of d).
    """
    n = len(V)
    E, _, _ = unique_edges(F)
    E = E[E[:, 0] != E[:, 1]]
    row = np.r_[E[:, 0], E[:, 1]]
    col = np.r_[E[:, 1], E[:, 0]]
    length = np.linalg.norm(V[row] - V[col], axis=1)
    h = float(length.mean()) if len(length) else 1.0
    h = h if h > 0 else 1.0
    deg = np.bincount(row, minlength=n).astype(np.float64)
    used = deg > 0
    inv = np.where(used, 1.0 / np.maximum(deg, 1.0), 0.0)
    h_i = np.bincount(row, weights=length, minlength=n) * inv
    h_i = np.where(h_i > 0, h_i, h)
    scale = np.where(used, h / h_i, 0.0)
    Nv = vertex_normals(V, F)
    off = -(scale * inv)[row] * np.einsum("ij,ij->i", Nv[row], Nv[col])
    diag = np.flatnonzero(used)
    A = sp.csr_matrix((np.r_[off, scale[diag]], (np.r_[row, diag], np.r_[col, diag])), shape=(n, n))
    W = sp.csr_matrix((np.ones(len(row)), (row, col)), shape=(n, n))
    LV = np.where(used[:, None], V - (W @ V) * inv[:, None], 0.0)
    J0 = np.einsum("ij,ij->i", Nv, LV) / h_i
    return J0, A, h


def default_lam(J0: np.ndarray) -> float:
    """Regularization weight from the spread of J itself: three robust standard
    deviations (1.4826 x the median absolute deviation) of ``J0`` about its median.
    Large on a noisy input (its oscillations are removed), small on a clean or
    denoised one (J is kept nearly as is)."""
    if len(J0) == 0:
        return 0.0
    return float(3.0 * 1.4826 * np.median(np.abs(J0 - np.median(J0))))


def _cg(M: sp.csr_matrix, b: np.ndarray, x: np.ndarray, inv_diag: np.ndarray, rtol: float = 1e-8,
        max_iter: int = 200) -> np.ndarray:
    """Solve the SPD system ``M x = b`` by Jacobi-preconditioned conjugate gradients from ``x``."""
    r = b - M @ x
    stop = rtol * max(np.linalg.norm(b), 1e-300)
    if np.linalg.norm(r) <= stop:
        return x
    x = x.copy()
    zv = inv_diag * r
    p = zv.copy()
    rz = r @ zv
    for _ in range(max_iter):
        Mp = M @ p
        alpha = rz / (p @ Mp)
        x += alpha * p
        r -= alpha * Mp
        if np.linalg.norm(r) <= stop:
            break
        zv = inv_diag * r
        rz_new = r @ zv
        p = zv + (rz_new / rz) * p
        rz = rz_new
    return x


def l1_sparse_normal_laplacian(
    J0: np.ndarray, A: sp.spmatrix, lam: float, rho: float = 1.0, tol: float = 1e-5, max_iter: int = 2000,
) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Solve ``min_d 1/2 |d|^2 + lam |J0 + A d|_1`` by ADMM.

    Splitting ``z = J0 + A d`` with the scaled multiplier u:
    ``d = (I + rho A^T A)^-1 rho A^T (z - J0 - u)`` (Jacobi-preconditioned conjugate
    gradients from the previous d: the matrix is well conditioned),
    ``z = shrink(J0 + A d + u, lam / rho)``, ``u += J0 + A d - z``. Stops when the
    primal residual ``|J0 + A d - z|`` and the dual residual ``rho |A^T (z - z_prev)|``
    are both below ``tol (sqrt(n) + |J0|)``.

    Parameters
    ----------
    J0 : (n,) float64; A : (n, n) sparse; lam : float >= 0
    rho : float
        ADMM penalty.
    tol : float
        Relative stopping tolerance.
    max_iter : int
        Iteration cap.

    Returns
    -------
    d : (n,) displacements; z : (n,) sparse J (exact zeros off the support);
    iterations : int; converged : bool
    """
    n = len(J0)
    A = sp.csr_matrix(A)
    if lam <= 0 or n == 0:
        return np.zeros(n), J0.copy(), 0, True
    AT = sp.csr_matrix(A.T)
    M = sp.csr_matrix(sp.identity(n) + rho * (AT @ A))  # SPD, eigenvalues in [1, 1 + rho |A|^2]
    inv_diag = 1.0 / M.diagonal()
    d = np.zeros(n)
    z = J0.copy()
    u = np.zeros(n)
    scale = tol * (np.sqrt(n) + np.linalg.norm(J0))
    converged = False
    it = 0
    while it < max_iter:
        it += 1
        d = _cg(M, rho * (AT @ (z - J0 - u)), d, inv_diag, rtol=min(1e-6, 0.1 * tol))
        Jd = J0 + A @ d
        v = Jd + u
        z_prev = z
        z = np.sign(v) * np.maximum(np.abs(v) - lam / rho, 0.0)
        r = Jd - z
        u += r
        if np.linalg.norm(r) <= scale and rho * np.linalg.norm(AT @ (z - z_prev)) <= scale:
            converged = True
            break
    return d, z, it, converged


def l1_feature_vertices(
    V: np.ndarray, F: np.ndarray, lam: float | None = None, tau: float = DEFAULT_TAU,
    max_iter: int = 2000,
) -> L1FeatureResult:
    """Feature vertices of a mesh: the support of the l1-sparse normal Laplacian.

    Parameters
    ----------
    V : (n, 3) float64 positions; F : (m, 3) int64 triangles.
    lam : float, optional
        l1 weight (default :func:`default_lam` of the mesh's J).
    tau : float
        Cut on the sparse ``|J|``, in local mean edge lengths (default 0.12, a
        crease of about 24 degrees in a regular mesh).
    max_iter : int
        ADMM iteration cap.

    Returns
    -------
    L1FeatureResult
    """
    V, F = mesh_arrays(V, F)
    J0, A, _ = normal_laplacian(V, F)
    # over the vertices of the surface: those no face uses have J = 0, and kept in the
    # file (--no-clean) they had pulled the spread down (lambda 0.12 -> 0.005 on half a fandisk)
    lam_used = default_lam(J0[referenced_vertices(F, len(J0))]) if lam is None else float(lam)
    d, z, it, ok = l1_sparse_normal_laplacian(J0, A, lam_used, max_iter=max_iter)
    return L1FeatureResult(J=z, J0=J0, offset=d, feature=np.abs(z) > tau, lam=lam_used, tau=float(tau),
                           iterations=it, converged=ok)


def faces_from_feature_vertices(F: np.ndarray, feature_vertex: np.ndarray) -> np.ndarray:
    """(m,) 0/1 float: faces with at least two feature vertices (an edge along the feature)."""
    return (np.asarray(feature_vertex, dtype=bool)[F].sum(axis=1) >= 2).astype(np.float64)


def dihedral_feature_faces(N: np.ndarray, edge_nb: np.ndarray, angle_deg: float = 30.0) -> np.ndarray:
    """(m,) 0/1 float: faces whose normal differs from an edge-adjacent face's
    normal by more than ``angle_deg``."""
    m = len(N)
    i, k = np.nonzero(edge_nb >= 0)
    cos = np.einsum("ij,ij->i", N[i], N[edge_nb[i, k]])
    out = np.zeros(m)
    out[i[cos < np.cos(np.radians(angle_deg))]] = 1.0
    return out


def l1_feature_faces(V: np.ndarray, F: np.ndarray, lam: float | None = None,
                     tau: float = DEFAULT_TAU) -> tuple[np.ndarray, L1FeatureResult]:
    """(m,) 0/1 float feature faces (at least two l1 feature vertices) and the
    vertex result of :func:`l1_feature_vertices`."""
    res = l1_feature_vertices(V, F, lam=lam, tau=tau)
    return faces_from_feature_vertices(F, res.feature), res
