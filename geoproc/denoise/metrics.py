"""Error of a denoised mesh against its clean reference (same connectivity)."""

from __future__ import annotations

import igl
import numpy as np

from geoproc.denoise.face_geometry import face_normals_and_areas, stored_rounding
from geoproc.denoise.scale_groups import scale_groups
from geoproc.mesh.clean import remove_unreferenced_vertices
from geoproc.mesh.topology import mean_edge_length, referenced_vertices


def face_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m, 3) unit face normals for the metrics (:func:`face_normals_and_areas`),
    faces whose corners lie on a line as stored (a T-junction filler of a
    six-decimal OBJ) taking their neighbours' normal as exact ones do: a
    rounding-error normal 90 degrees off had been counted as the largest angle.
    The rounding is judged for each scale group on its own, as the filter
    judges it (:func:`geoproc.denoise.scale_groups.scale_groups`)."""
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    groups = scale_groups(V, F)
    if groups.max(initial=0) == 0:
        return face_normals_and_areas(V, F, stored_rounding(V, F))[0]
    N = np.empty((len(F), 3))
    for g in range(int(groups.max()) + 1):
        fg = np.flatnonzero(groups == g)
        Vg, Fg, _ = remove_unreferenced_vertices(V, F[fg])
        N[fg] = face_normals_and_areas(Vg, Fg, stored_rounding(Vg, Fg))[0]
    return N


def normal_angles_deg(N: np.ndarray, N_ref: np.ndarray) -> np.ndarray:
    """(m,) angle in degrees between corresponding unit normals."""
    cos = np.clip(np.einsum("ij,ij->i", N, N_ref), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def mean_normal_angle_deg(V: np.ndarray, F: np.ndarray, V_ref: np.ndarray) -> float:
    """Mean angle in degrees between the face normals of V and of V_ref (same faces F): theta."""
    return float(normal_angles_deg(face_normals(V, F), face_normals(V_ref, F)).mean())


def flipped_faces(V: np.ndarray, F: np.ndarray, V_ref: np.ndarray) -> np.ndarray:
    """Indices of faces whose normal is more than 90 degrees from the reference."""
    return _flipped(face_normals(V, F), face_normals(V_ref, F))


def _flipped(N: np.ndarray, N_ref: np.ndarray) -> np.ndarray:
    """Indices of the rows of N (m, 3) more than 90 degrees from those of N_ref."""
    return np.flatnonzero(np.einsum("ij,ij->i", N, N_ref) < 0.0)


def new_flipped_faces(V: np.ndarray, F: np.ndarray, V_ref: np.ndarray, input_flipped: np.ndarray) -> int:
    """How many faces are flipped in V (:func:`flipped_faces` against V_ref)
    that were not already flipped in the input.

    Parameters
    ----------
    V : (n, 3) result positions; F : (m, 3) triangles; V_ref : (n, 3) reference positions.
    input_flipped : (k,) int the input's :func:`flipped_faces` against the same reference.
    """
    return int(np.setdiff1d(flipped_faces(V, F, V_ref), input_flipped).size)


def reference_metrics(V: np.ndarray, V_input: np.ndarray, F: np.ndarray, V_ref: np.ndarray) -> dict:
    """:func:`denoise_errors` of the result V, plus the input's own error
    (``input_mean_normal_angle_deg``, ``input_flipped_faces``) and the faces
    the result flipped that the input had not (``new_flipped_faces``).

    Parameters
    ----------
    V, V_input, V_ref : (n, 3) result, noisy input and clean positions; F : (m, 3) their triangles.
    """
    # each set of normals once (with its stored rounding), not once per metric
    N, N_input, N_ref = face_normals(V, F), face_normals(V_input, F), face_normals(V_ref, F)
    before = _flipped(N_input, N_ref)
    return {**_errors(V, F, V_ref, normal_angles_deg(N, N_ref)),
            "input_mean_normal_angle_deg": float(normal_angles_deg(N_input, N_ref).mean()),
            "input_flipped_faces": len(before),
            "new_flipped_faces": int(np.setdiff1d(_flipped(N, N_ref), before).size)}


def two_sided_hausdorff(V: np.ndarray, F: np.ndarray, V_ref: np.ndarray, F_ref: np.ndarray) -> float:
    """Two-sided Hausdorff distance between two surfaces, from vertices to surfaces
    (the largest vertex-to-surface distance either way), in length units.
    Vertices no face uses are not points of either surface and are left out."""
    d1, _, _ = igl.point_mesh_squared_distance(V[referenced_vertices(F, len(V))], V_ref, F_ref)
    d2, _, _ = igl.point_mesh_squared_distance(V_ref[referenced_vertices(F_ref, len(V_ref))], V, F)
    return float(np.sqrt(max(d1.max(), d2.max())))


def denoise_errors(V: np.ndarray, F: np.ndarray, V_ref: np.ndarray) -> dict:
    """The report metrics of a result against its clean reference.

    Parameters
    ----------
    V : (n, 3) result positions; F : (m, 3) triangles shared with the reference;
    V_ref : (n, 3) clean positions.

    Returns
    -------
    dict with
        mean_normal_angle_deg, max_normal_angle_deg : face normal angles (theta);
        flipped_faces : faces more than 90 degrees from the reference;
        hausdorff : two-sided Hausdorff distance / reference bounding-box diagonal;
        vertex_rmse : RMS vertex distance / reference mean edge length.
    The bounding box and the vertex distances count only the vertices some
    face uses (a vertex no face uses is not on the surface).
    """
    return _errors(V, F, V_ref, normal_angles_deg(face_normals(V, F), face_normals(V_ref, F)))


def _errors(V: np.ndarray, F: np.ndarray, V_ref: np.ndarray, ang: np.ndarray) -> dict:
    """:func:`denoise_errors` given the faces' normal angles ``ang`` (m,) in degrees."""
    used = referenced_vertices(F, len(V))
    on = V_ref[used]
    diag = float(np.linalg.norm(on.max(axis=0) - on.min(axis=0)))
    le = mean_edge_length(V_ref, F)
    return {
        "mean_normal_angle_deg": float(ang.mean()),
        "max_normal_angle_deg": float(ang.max()),
        "flipped_faces": int((ang > 90.0).sum()),
        "hausdorff": two_sided_hausdorff(V, F, V_ref, F) / diag,
        "vertex_rmse": float(np.sqrt(np.mean(np.sum((V[used] - on) ** 2, axis=1)))) / le,
    }
