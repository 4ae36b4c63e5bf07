"""Input checks of the denoising methods (one-line InputErrors)."""

from __future__ import annotations

import numpy as np

from geoproc.errors import InputError
from geoproc.mesh.topology import face_areas, face_list_renumbering
from geoproc.mesh.validate import require_edge_manifold


def require_denoisable(F: np.ndarray, path: str | None) -> None:
    """Refuse faces that repeat a vertex and edges shared by more than two
    faces: the patches and the edge saliency of the guided filter need at
    most two faces per edge."""
    require_edge_manifold(F, path, "; denoising needs at most two faces per edge")


CORNER_ORDERS = ((0, 1, 2), (0, 2, 1), (2, 1, 0), (1, 0, 2), (1, 2, 0), (2, 0, 1))
"""The orders in which a reference's faces may list their corners, as the
input's: the same, reversed (a file written with the other winding), or
turned."""


def reference_in_input_order(F: np.ndarray, n: int, F_ref: np.ndarray, V_ref: np.ndarray,
                             path: str | None, counts_hint: str = "") -> np.ndarray:
    """Reference positions numbered as the input's vertices.

    The reference must be the same mesh as the input: the same faces in the
    same order. Its vertices may be numbered differently (an STL copy of the
    input, whose merged vertices follow the order of first use); they are then
    renumbered to match (:func:`geoproc.mesh.topology.face_list_renumbering`).
    Its faces may list their corners in another order (:data:`CORNER_ORDERS`,
    the same for every face: a file written with the other winding); the
    metrics use the input's faces on the reference positions, so the winding
    of the reference does not matter.

    Parameters
    ----------
    F : (m, 3) int input faces over ``n`` vertices.
    F_ref : (m', 3) int reference faces.
    V_ref : (..., n', 3) float reference positions (one mesh, or frames of one).
    counts_hint : appended to the error when the counts differ (how the caller
        may have loaded the two differently).

    Returns
    -------
    (..., n, 3) float: ``V_ref`` with its vertices in the input's order.

    Raises
    ------
    InputError
        When the counts differ, the face lists differ beyond a renumbering, or
        every reference face has zero area (in some frame): its normals, and so
        every metric against it, would mean nothing.
    """
    n_ref = V_ref.shape[-2]
    P = V_ref.reshape(-1, n_ref, 3)
    if (np.ptp(P, axis=1).max(axis=1) == 0).any():
        raise InputError(path, "the reference is degenerate: all its vertices coincide (in some frame)")
    if n_ref != n or len(F_ref) != len(F):
        raise InputError(path, f"reference connectivity differs from the input ({n_ref} vertices, "
                         f"{len(F_ref)} faces vs {n}, {len(F)}): it must be the same mesh, with the same faces "
                         f"in the same order{counts_hint}")
    for t in range(len(P)):
        if not (face_areas(P[t], F_ref) > 0).any():
            where = f" (frame {t})" if V_ref.ndim == 3 else ""
            raise InputError(path, f"the reference is degenerate{where}: every face has zero area")
    if np.array_equal(np.sort(F_ref, axis=1), np.sort(F, axis=1)):
        return V_ref  # the same faces, perhaps with other windings: the metrics use the input's
    for corners in CORNER_ORDERS:
        r = face_list_renumbering(F, n, F_ref[:, corners], n_ref)
        if r is not None:
            return V_ref[..., r, :]
    raise InputError(path, f"reference connectivity differs from the input: the same counts ({n} vertices, "
                     f"{len(F)} faces) but other faces, even with its vertices renumbered or its "
                     "faces' corners reordered")
