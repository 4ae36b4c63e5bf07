"""Checks a method runs before it starts; each raises a one-line InputError.

The topology queries are imported where they are used: reading a mesh needs
only the index checks here, and the command line reads (and refuses) files
before any compiled kernel is needed."""

from __future__ import annotations

import io
import os

import numpy as np

from geoproc.errors import InputError, frame_error
from geoproc.mesh.mesh import LoadLog, Mesh


def mesh_arrays(V, F, path: str | None = None, allow_point_cloud: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Positions and triangles as the library's functions take them, checked.

    Parameters
    ----------
    V : array-like (n, 3) of real numbers; F : array-like (m, 3) of integers
        (any integer dtype, a list, any memory layout).
    path : str, optional
        Named in the error.
    allow_point_cloud : bool
        Accept no faces.

    Returns
    -------
    (n, 3) C-contiguous float64 positions and (m, 3) C-contiguous int64 triangles;
    InputError for another shape or dtype, non-finite or overflowing
    coordinates, or face indices outside ``0..n-1``
    (:func:`geoproc.mesh.read.validate_arrays`).
    """
    from geoproc.mesh.read import validate_arrays

    V = np.asarray(V)
    if np.iscomplexobj(V) or not (np.issubdtype(V.dtype, np.integer) or np.issubdtype(V.dtype, np.floating)):
        raise InputError(path, f"vertex positions must be real numbers, not {V.dtype}")
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(path, f"vertex positions must have shape (n, 3), not {V.shape}")
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = triangle_array(F, path)
    validate_arrays(V, F, path, allow_point_cloud)
    return V, F


def triangle_array(F, path: str | None = None) -> np.ndarray:
    """(m, 3) C-contiguous int64 triangles from an array-like of integers (any
    integer dtype, a list, any layout; no rows when empty); InputError for
    another shape or dtype. Indices are checked against the vertex count by
    :func:`require_indices_below`."""
    F = np.asarray(F)
    if F.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if not np.issubdtype(F.dtype, np.integer):
        raise InputError(path, f"face indices must be integers, not {F.dtype}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise InputError(path, f"faces must have shape (m, 3) (triangles), not {F.shape}")
    return np.ascontiguousarray(F, dtype=np.int64)


def require_indices_below(F: np.ndarray, n: int, path: str | None = None) -> None:
    """InputError naming the first face with an index outside ``0..n-1``."""
    if len(F) == 0:
        return
    out = (F < 0) | (F >= n)
    if out.any():
        f = int(np.flatnonzero(out.any(axis=1))[0])
        raise InputError(path, f"face index out of range: face {f} references vertex {int(F[f][out[f]][0])}, "
                               f"but there are {n} vertices (0-based)")


def require_triangle_mesh(mesh: Mesh) -> None:
    """Refuse a point cloud or a mesh whose faces all have zero area."""
    from geoproc.mesh.topology import face_areas

    path = mesh.log.path or None
    if mesh.is_point_cloud:
        raise InputError(path, "is a point cloud (no faces); this method needs a triangle mesh")
    # the first faces nearly always settle it; the whole mesh only when they are all flat
    if not (face_areas(mesh.V, mesh.F[:4096]) > 0).any() and not (face_areas(mesh.V, mesh.F) > 0).any():
        raise InputError(path, "degenerate mesh: every face has zero area")


def require_triangle_frames(V: np.ndarray, F: np.ndarray, path: str | None,
                            frame_files: list[str] | None = None) -> None:
    """Refuse an animation (V of shape (frames, n, 3), shared triangles F)
    any of whose frames has no face of nonzero area, naming the first such
    frame: its file when ``frame_files`` (one per frame) is given, else its index."""
    from geoproc.mesh.topology import face_areas

    if len(F) == 0:
        raise InputError(path, "has no faces; this method needs a triangle mesh")
    for t in range(len(V)):
        if not (face_areas(V[t], F) > 0).any():
            raise frame_error(path, t, "degenerate mesh: every face has zero area", frame_files)


def require_edge_manifold(F: np.ndarray, path: str | None, why: str = "", log: LoadLog | None = None,
                          keeps_flat_faces: bool = True) -> None:
    """Refuse a face that repeats a vertex (its edges would count twice) or an
    edge shared by more than two faces, naming the first; ``why`` ends the
    message (``"; denoising needs ..."``). ``log``, the mesh's load log: the
    message then says which of those faces the merge of coincident positions
    made (:attr:`LoadLog.collapsed_faces`), which the file stores with three
    distinct vertices, and, where the caller ``keeps_flat_faces`` (takes
    faces of zero area, as those are once stored apart), that ``--no-clean``
    keeps them apart."""
    from geoproc.mesh.topology import duplicate_faces, nonmanifold_edges, repeated_corner_faces

    F = np.asarray(F).reshape(-1, 3)
    rep = np.flatnonzero(repeated_corner_faces(F))
    if len(rep):
        k = int(rep[0])
        one = len(rep) == 1
        merged = ""
        if log is not None and log.collapsed_faces:
            c = log.collapsed_faces
            which = ("it" if one else "all of them" if c == len(rep)
                     else f"{c} of them (first: face {log.first_collapsed_face})")
            out = "--no-clean keeps the stored vertices" if keeps_flat_faces else "an edge of length zero"
            merged = f"; merging coincident positions on loading made {which} ({out})"
        raise InputError(path, f"{len(rep)} face{'' if one else 's'} repeat{'s' if one else ''} a vertex "
                               f"(first: face {k}, vertices {' '.join(str(int(i)) for i in F[k])}){merged}{why}")
    bad_e = nonmanifold_edges(F)
    if len(bad_e):
        a, b = (int(x) for x in bad_e[0])
        dup = duplicate_faces(F)
        twice = ""
        if len(dup):  # the likely cause, which the edge count alone had not named
            k = int(dup[0])
            first = int(np.flatnonzero((np.sort(F[:k], axis=1) == np.sort(F[k])).all(axis=1))[0])
            twice = (f"; {len(dup)} face{'' if len(dup) == 1 else 's'} repeat{'s' if len(dup) == 1 else ''} "
                     f"the corners of an earlier one (first: face {k}, as face {first})")
        raise InputError(path, f"non-manifold: {len(bad_e)} edges have more than two faces "
                               f"(first: edge {a}-{b}){twice}{why}")


def require_manifold(mesh: Mesh, why: str = "", keeps_flat_faces: bool = True) -> None:
    """Refuse a mesh with a repeated-vertex face or a non-manifold edge or
    vertex, naming the first one (``keeps_flat_faces`` as for :func:`require_edge_manifold`)."""
    require_edge_manifold(mesh.F, mesh.log.path or None, why, mesh.log, keeps_flat_faces)
    require_vertex_manifold(mesh, why)


def require_vertex_manifold(mesh: Mesh, why: str = "") -> None:
    """Refuse a mesh with a vertex where separate fans of faces meet, naming the
    first; ``why`` ends the message."""
    from geoproc.mesh.topology import nonmanifold_vertices

    bad_v = nonmanifold_vertices(mesh.F, len(mesh.V))
    if len(bad_v):
        raise InputError(
            mesh.log.path or None, f"non-manifold: {len(bad_v)} vertices join separate fans of faces "
            f"(first: vertex {int(bad_v[0])}){why}"
        )


def require_vertex_field(mesh: Mesh, values: np.ndarray, name: str, path: str | None = None) -> np.ndarray:
    """Check a per-vertex scalar field of ``mesh`` (:func:`vertex_field_values`);
    ``path`` names the file in errors (default: the mesh's). Returns float64 (n,)."""
    return vertex_field_values(values, len(mesh.V), name, path or mesh.log.path or None)


def _require_integers_apart(values: np.ndarray, a: np.ndarray, name: str, path: str | None) -> None:
    """InputError when integers beyond 2^53 (int64, uint64) that differ become
    equal as doubles (``a``): the field's order, which decides its critical
    points, would change."""
    wide = (values > 2**53) | (values < -(2**53))
    if not wide.any():
        return
    distinct, after = len(np.unique(values)), len(np.unique(a))
    if after < distinct:
        raise InputError(path, f"field '{name}' has integers beyond 2^53, where doubles cannot tell them apart: "
                               f"its {distinct} distinct values become {after}; subtract a constant (its "
                               "minimum, say) first")


def vertex_field_values(values, n: int, name: str, path: str | None = None) -> np.ndarray:
    """Check a scalar field on ``n`` vertices: real numbers, one per vertex, all
    finite, spanning a finite range (max - min, which persistence and relative
    thresholds need). Returns float64 (n,); InputError naming ``path`` and the
    field ``name`` otherwise."""
    values = np.asarray(values)
    if values.dtype.kind not in "fiub":
        raise InputError(path, f"field '{name}' must hold real numbers, got dtype {values.dtype}")
    if values.dtype.kind == "f" and values.dtype.itemsize > 8:  # long double: may not fit float64
        wide = np.isfinite(values) & (np.abs(values) > np.finfo(np.float64).max)
        if wide.any():
            raise InputError(
                path, f"field '{name}' has {int(wide.sum())} values beyond the float64 range "
                f"(first: vertex {int(np.flatnonzero(wide.reshape(-1))[0])}); rescale it")
    a = np.asarray(values, dtype=np.float64).reshape(-1)
    if len(a) != n:
        raise InputError(path, f"field '{name}' has {len(a)} values for {n} vertices")
    if values.dtype.kind in "iu":
        _require_integers_apart(values.reshape(-1), a, name, path)
    bad = ~np.isfinite(a)
    if bad.any():
        unreached = (a[bad] == np.inf).all()  # as geodesic writes where no source reaches
        raise InputError(
            path, f"field '{name}' has {int(bad.sum())} non-finite values "
            f"(first: vertex {int(np.flatnonzero(bad)[0])})"
            + ("; all +inf, as geodesic writes on the parts of a mesh its sources do not reach: give a "
               "source on every connected part" if unreached else "")
        )
    if len(a) and a.max() / 2 - a.min() / 2 > np.finfo(np.float64).max / 2:
        raise InputError(path, f"field '{name}' spans more than 1.8e308 (max - min overflows); rescale it")
    return a


def npy_vertex_values(data: bytes, mesh: Mesh, path: str) -> np.ndarray:
    """The values of a ``.npy`` file's bytes ``data`` meant as one per vertex
    of ``mesh``: a 1-D array, or 2-D with one row or column, as stored (any
    dtype; the caller checks the values). InputError naming ``path`` when the
    bytes are not a NumPy array (a pickle is never loaded), or when the file
    holds one value per vertex stored in the mesh's file where loading merged
    or dropped some (the message says how many and names --no-clean); other
    lengths are left to the caller's check."""
    if data and not data.startswith(b"\x93NUMPY"):  # np.load reads any other bytes as a pickle, then refuses it
        raise InputError(path, "cannot read field: not a NumPy .npy file (it does not start with \\x93NUMPY)")
    try:
        values = np.load(io.BytesIO(data), allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:  # EOFError: an empty file
        raise InputError(path, f"cannot read field: {exc or type(exc).__name__}") from None
    if values.ndim != 1 and not (values.ndim == 2 and 1 in values.shape):
        raise InputError(path, f"field must hold one value per vertex, got shape {values.shape}")
    log = mesh.log
    if values.size != len(mesh.V) and log.cleaned and values.size == log.stored_vertices != len(mesh.V):
        # one value per stored vertex: loading merged or dropped some (which ones is the file's order)
        raise InputError(path, f"field has {values.size} values, one per vertex stored in "
                               f"{os.path.basename(log.path) or 'the mesh'}, but loading merged "
                               f"{log.merged_vertices} and dropped {log.removed_unreferenced} unreferenced, "
                               f"leaving {len(mesh.V)}; pass --no-clean to keep every stored vertex")
    return values


def scalar_vertex_properties(mesh: Mesh) -> str:
    """The names of the mesh's one-value-per-vertex properties, sorted and
    joined by commas (``none`` when there is none), for messages."""
    return ", ".join(sorted(k for k, v in mesh.vertex_fields.items() if v.ndim == 1)) or "none"
