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


def require_manifold(mesh: Mesh) -> None:
    """Refuse a mesh with a non-manifold edge or vertex, naming the first one."""
    path = mesh.log.path or None
    bad_e = nonmanifold_edges(mesh.F)
    if len(bad_e):
        a, b = (int(x) for x in bad_e[0])
        raise InputError(
            path, f"non-manifold: {len(bad_e)} edges have more than two faces (first: edge {a}-{b})"
        )
    bad_v = nonmanifold_vertices(mesh.F, len(mesh.V))
    if len(bad_v):
        raise InputError(
            path, f"non-manifold: {len(bad_v)} vertices join separate fans of faces "
            f"(first: vertex {int(bad_v[0])})"
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
