"""Checks a method runs before it starts; each raises a one-line InputError."""

from __future__ import annotations

import numpy as np

from geoproc.errors import InputError
from geoproc.mesh.mesh import Mesh
from geoproc.mesh.topology import face_areas, nonmanifold_edges, nonmanifold_vertices


def require_triangle_mesh(mesh: Mesh) -> None:
    """Refuse a point cloud or a mesh whose faces all have zero area."""
    path = mesh.log.path or None
    if mesh.is_point_cloud:
        raise InputError(path, "is a point cloud (no faces); this method needs a triangle mesh")
    if not (face_areas(mesh.V, mesh.F) > 0).any():
        raise InputError(path, "degenerate mesh: every face has zero area")


def require_triangle_frames(V: np.ndarray, F: np.ndarray, path: str | None) -> None:
    """Refuse an animation (V of shape (frames, n, 3), shared triangles F)
    any of whose frames has no face of nonzero area, naming the first such frame."""
    if len(F) == 0:
        raise InputError(path, "has no faces; this method needs a triangle mesh")
    for t in range(len(V)):
        if not (face_areas(V[t], F) > 0).any():
            raise InputError(path, f"frame {t}: degenerate mesh: every face has zero area")


def require_edge_manifold(F: np.ndarray, path: str | None, why: str = "") -> None:
    """Refuse a face that repeats a vertex (its edges would count twice) or an
    edge shared by more than two faces, naming the first; ``why`` ends the
    message (``"; denoising needs ..."``)."""
    F = np.asarray(F).reshape(-1, 3)
    rep = np.flatnonzero((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2]))
    if len(rep):
        k = int(rep[0])
        one = len(rep) == 1
        raise InputError(path, f"{len(rep)} face{'' if one else 's'} repeat{'s' if one else ''} a vertex "
                               f"(first: face {k}, vertices {' '.join(str(int(i)) for i in F[k])}){why}")
    bad_e = nonmanifold_edges(F)
    if len(bad_e):
        a, b = (int(x) for x in bad_e[0])
        raise InputError(path, f"non-manifold: {len(bad_e)} edges have more than two faces "
                               f"(first: edge {a}-{b}){why}")


def require_manifold(mesh: Mesh, why: str = "") -> None:
    """Refuse a mesh with a repeated-vertex face or a non-manifold edge or
    vertex, naming the first one."""
    path = mesh.log.path or None
    require_edge_manifold(mesh.F, path, why)
    bad_v = nonmanifold_vertices(mesh.F, len(mesh.V))
    if len(bad_v):
        raise InputError(
            path, f"non-manifold: {len(bad_v)} vertices join separate fans of faces "
            f"(first: vertex {int(bad_v[0])}){why}"
        )


def require_vertex_field(mesh: Mesh, values: np.ndarray, name: str, path: str | None = None) -> np.ndarray:
    """Check a per-vertex scalar field: real numbers, one per vertex, all finite,
    spanning a finite range (max - min, which persistence and relative
    thresholds need). ``path`` names the file in errors (default: the mesh's).
    Returns float64 (n,)."""
    path = path or mesh.log.path or None
    values = np.asarray(values)
    if values.dtype.kind not in "fiub":
        raise InputError(path, f"field '{name}' must hold real numbers, got dtype {values.dtype}")
    a = np.asarray(values, dtype=np.float64).reshape(-1)
    if len(a) != len(mesh.V):
        raise InputError(path, f"field '{name}' has {len(a)} values for {len(mesh.V)} vertices")
    bad = ~np.isfinite(a)
    if bad.any():
        raise InputError(
            path, f"field '{name}' has {int(bad.sum())} non-finite values "
            f"(first: vertex {int(np.flatnonzero(bad)[0])})"
        )
    if len(a) and a.max() / 2 - a.min() / 2 > np.finfo(np.float64).max / 2:
        raise InputError(path, f"field '{name}' spans more than 1.8e308 (max - min overflows); rescale it")
    return a
