"""Gradient and divergence on the intrinsic Delaunay triangulation, for meshes with slivers.

The extrinsic face gradient of a triangle scales with the inverse of its
heights: on a sliver (a corner angle near 0 or 180 degrees) it is
ill-conditioned, and in the heat method the Poisson solution spikes there. The
intrinsic Delaunay triangulation (edge flips on the same surface, libigl's
``intrinsic_delaunay_cotmatrix``) has the same vertices and no such triangles.
Each intrinsic triangle is known by its three edge lengths; it is laid out in
its own 2D frame, where the gradient of a piecewise-linear function is a 2D
vector per face. Its divergence ``D = -G^T A`` satisfies ``D G = L`` with ``L``
the intrinsic Delaunay Laplacian, the pairing the Poisson step needs.
"""

from __future__ import annotations

import numpy as np

from geoproc.geodesic.names import OPERATORS
from geoproc.geodesic.operators import (
    cotan_laplacian,
    integrated_divergence,
    intrinsic_delaunay_mesh,
    smallest_angles,
    stack_gradient_coefficients,
)

SLIVER_ANGLE_DEG = 5.0
"""A face with a corner angle below this (degrees) counts as a sliver."""
SLIVER_SHARE = 0.005
"""``operators="auto"`` goes intrinsic when at least this share of faces are slivers."""
NEGATIVE_WEIGHT_SHARE = 0.05
"""``operators="auto"`` also goes intrinsic when at least this share of the cotan
Laplacian's off-diagonal weight is negative (:func:`negative_weight_share`): a
mesh stretched or sheared into obtuse, non-Delaunay triangles without slivers.
The shared meshes read 0.0002 (fandisk) to 0.047 (camelhead); fandisk stretched
4 times along x reads 0.105, and its heat error was 6.7 times the intrinsic one."""
POISSON_NEEDLE_ANGLE = 1e-6
"""Below this corner angle (radians) the extrinsic Poisson step loses its accuracy
(:data:`geoproc.geodesic.distance.NEEDLE_ANGLE`): ``auto`` goes intrinsic on a mesh
with such a face, however few."""


def sliver_share(V: np.ndarray, F: np.ndarray, angle_deg: float = SLIVER_ANGLE_DEG) -> float:
    """Share of faces (0..1) whose smallest corner angle is below ``angle_deg``
    degrees (degenerate faces count)."""
    return _sliver_share(smallest_angles(V, F), angle_deg)


def _sliver_share(angle: np.ndarray, angle_deg: float = SLIVER_ANGLE_DEG) -> float:
    return float(np.mean(~(angle >= np.radians(angle_deg))))


def negative_weight_share(L) -> float:
    """Share (0..1) of the off-diagonal weight of a Laplacian ``L`` (sparse, n x n,
    off-diagonal entries the edge weights) that is negative: 0 on a Delaunay
    mesh, growing with how far and how often its triangles break the Delaunay
    condition (``cot a + cot b < 0`` across an edge)."""
    C = L.tocoo()
    w = C.data[C.row != C.col]
    total = float(np.abs(w).sum())
    return float(-w[w < 0].sum() / total) if total > 0 else 0.0


def intrinsic_gradient_coefficients(l: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradient weights and areas of triangles given by their edge lengths.

    Each face is laid out in its own 2D frame, corner 0 at the origin and
    corner 1 on the x axis; the gradient of the hat function of corner c is
    the edge opposite c turned by 90 degrees, over twice the area.

    Parameters
    ----------
    l : (m, 3) float array
        Edge lengths (length unit), ``l[f, c]`` opposite corner c.

    Returns
    -------
    coef : (2, m, 3) float array
        ``grad f`` on face k, axis a of its frame, is ``sum_c coef[a, k, c] f[k-th face's corner c]``
        (1 / length unit); zero on zero-area faces.
    area : (m,) float array
        Face areas (area unit).
    """
    m = len(l)
    l0, l1, l2 = l[:, 0], l[:, 1], l[:, 2]
    x = (l2 * l2 + l1 * l1 - l0 * l0) / (2.0 * l2)
    y = np.sqrt(np.maximum(l1 * l1 - x * x, 0.0))
    P = np.stack([np.zeros((m, 2)), np.c_[l2, np.zeros(m)], np.c_[x, y]], axis=1)  # (m, 3, 2)
    area = 0.5 * l2 * y
    inv = np.divide(1.0, 2.0 * area, out=np.zeros(m), where=area > 0)
    coef = np.empty((2, m, 3))
    for c in range(3):
        e = P[:, (c + 2) % 3] - P[:, (c + 1) % 3]
        coef[0, :, c], coef[1, :, c] = -e[:, 1] * inv, e[:, 0] * inv
    return coef, area


def face_operators_triangulation(V: np.ndarray, F: np.ndarray, operators: str, angles=smallest_angles,
                                 cotan=None):
    """The intrinsic Delaunay mesh (:func:`geoproc.geodesic.operators.intrinsic_delaunay_mesh`;
    None where it does not apply, callers then keep extrinsic operators) when
    ``operators`` asks for it, else None.

    ``operators``: ``"extrinsic"`` (None), ``"intrinsic"``, or ``"auto"``
    (intrinsic when at least :data:`SLIVER_SHARE` of the faces are slivers, a
    face has an angle below :data:`POISSON_NEEDLE_ANGLE`, or at least
    :data:`NEGATIVE_WEIGHT_SHARE` of the cotan Laplacian's off-diagonal weight
    is negative). ``angles``: the function that gives the faces' smallest
    angles (a compiled one for the log methods). ``cotan``: a function that
    returns the cotan Laplacian of (V, F), called only when ``auto`` needs it
    (the caller's own, which caches it; built here when None).
    """
    if operators not in OPERATORS:
        raise ValueError(f"unknown operators {operators!r}")
    if operators == "auto":
        angle = angles(V, F)
        if not (_sliver_share(angle) >= SLIVER_SHARE or angle.min(initial=np.pi) < POISSON_NEEDLE_ANGLE
                or negative_weight_share(cotan_laplacian(V, F) if cotan is None else cotan())
                >= NEGATIVE_WEIGHT_SHARE):
            return None
    if operators in ("auto", "intrinsic"):
        return intrinsic_delaunay_mesh(V, F, boundary_negatives=True)
    return None


def intrinsic_face_operators(Fi: np.ndarray, l: np.ndarray, n: int, face_share: float = 1.0):
    """Gradient weights (2, m, 3), gradient (2m, n) and integrated divergence
    ``-G^T diag(face_share area)`` (n, 2m) of the triangulation ``(Fi, l)`` (n
    vertices), with ``D G`` its cotan Laplacian times ``face_share`` (0.5 for
    the faces of a doubled cover folded onto the mesh, see
    :class:`geoproc.geodesic.operators.IntrinsicMesh`)."""
    coef, area = intrinsic_gradient_coefficients(l)
    G = stack_gradient_coefficients(coef, Fi, n)
    return coef, G, integrated_divergence(G, face_share * area)
