"""Explicit, reported clean-up applied after reading a mesh."""

from __future__ import annotations

import numpy as np

from geoproc.mesh.mesh import LoadLog, Mesh


def merge_coincident_vertices(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge vertices with bit-identical positions.

    UVs and normals are ignored, so an OBJ that was split at UV seams becomes one
    connected surface. The first occurrence (lowest index) of each position is
    kept and the order of first occurrences is preserved.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array

    Returns
    -------
    V2 : (k, 3) float array
        Unique positions, k <= n.
    F2 : (m, 3) int array
        Faces re-indexed into V2.
    keep : (k,) int array
        Index into V of each kept vertex (``V2 == V[keep]``).
    """
    group = position_groups(V)
    first = np.full(group.max() + 1 if len(V) else 0, len(V), dtype=np.int64)
    np.minimum.at(first, group, np.arange(len(V)))
    order = np.argsort(first, kind="stable")  # groups sorted by first occurrence
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    keep = first[order]
    return V[keep], rank[group][F], keep


def position_groups(V: np.ndarray) -> np.ndarray:
    """(n,) label per vertex; equal labels exactly when positions are equal.

    The rows are sorted by a 64-bit hash of their coordinates (-0.0 read as
    0.0, which compares equal to it), so equal positions end up side by side;
    should two different positions share a hash, a lexicographic sort of the
    coordinates decides instead.
    """
    if len(V) == 0:
        return np.zeros(0, dtype=np.int64)
    V = np.ascontiguousarray(V, dtype=np.float64)
    h = row_hashes(V)
    order = np.argsort(h, kind="stable")
    Vs = V[order]
    new = np.ones(len(V), dtype=bool)
    new[1:] = (Vs[1:] != Vs[:-1]).any(axis=1)
    hs = h[order]
    if (new[1:] & (hs[1:] == hs[:-1])).any():  # two positions share a hash
        return unique_rows(V)[1]
    group = np.empty(len(V), dtype=np.int64)
    group[order] = np.cumsum(new) - 1
    return group


def repeated_positions(V: np.ndarray) -> int:
    """How many vertices of V (n, 3) sit at a position a lower index takes
    (n minus the number of distinct positions; :func:`position_groups`)."""
    return len(V) - (int(position_groups(V).max()) + 1) if len(V) else 0


def unique_rows(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``P`` (n, d) in lexicographic order and, for each
    row, the index of its copy among them: ``np.unique(P, axis=0,
    return_inverse=True)``, the same arrays, from one ``lexsort`` (about three
    times faster on 700k points than numpy's structured-row sort).

    Returns
    -------
    U : (k, d) float64 distinct rows; inverse : (n,) int64 with ``U[inverse] == P``.
    """
    P = np.ascontiguousarray(P, dtype=np.float64)
    if len(P) == 0:
        return P.copy(), np.zeros(0, dtype=np.int64)
    order = np.lexsort(P.T[::-1])
    S = P[order]
    new = np.ones(len(S), dtype=bool)
    new[1:] = (S[1:] != S[:-1]).any(axis=1)
    inverse = np.empty(len(P), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return S[new], inverse


def _mix64(z: np.ndarray) -> np.ndarray:
    """The splitmix64 finalizer: every input bit reaches every output bit."""
    z = z ^ (z >> np.uint64(30))
    z *= np.uint64(0xBF58476D1CE4E5B9)
    z ^= z >> np.uint64(27)
    z *= np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def row_hashes(V: np.ndarray) -> np.ndarray:
    """(n,) uint64 hash of each row of an (n, 3) float64 array, equal for
    equal rows (-0.0 hashes as 0.0)."""
    bits = (V + 0.0).view(np.uint64)  # + 0.0 turns -0.0 into 0.0
    h = _mix64(bits[:, 0])
    h = _mix64(h ^ bits[:, 1])
    return _mix64(h ^ bits[:, 2])


def remove_unreferenced_vertices(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drop vertices that no face uses.

    Returns ``(V2, F2, keep)`` with ``V2 == V[keep]`` and F2 re-indexed.
    """
    used = np.zeros(len(V), dtype=bool)
    used[F.reshape(-1)] = True
    keep = np.flatnonzero(used)
    remap = np.full(len(V), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return V[keep], remap[F], keep


def clean_mesh(mesh: Mesh) -> Mesh:
    """Merge coincident positions, then drop unreferenced vertices.

    Per-vertex fields follow the kept vertex (the first of each merged group).
    A point cloud (no faces) is left as it is: nothing references its points.
    The counts are recorded in ``mesh.log``, with the faces that merging made
    repeat a vertex (``collapsed_faces``; kept, as every face is).

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    Mesh
        A new mesh; the input is not modified.
    """
    log = LoadLog(**mesh.log.as_dict())
    log.cleaned = True
    if mesh.is_point_cloud:
        return Mesh(mesh.V, mesh.F, dict(mesh.vertex_fields), dict(mesh.face_fields), log)
    from geoproc.mesh.topology import repeated_corner_faces

    V, F, keep1 = merge_coincident_vertices(mesh.V, mesh.F)
    log.merged_vertices = len(mesh.V) - len(V)
    if log.merged_vertices:
        collapsed = np.flatnonzero(repeated_corner_faces(F) & ~repeated_corner_faces(mesh.F))
        log.collapsed_faces = len(collapsed)
        log.first_collapsed_face = int(collapsed[0]) if len(collapsed) else -1
    V, F, keep2 = remove_unreferenced_vertices(V, F)
    log.removed_unreferenced = len(keep1) - len(keep2)
    keep = keep1[keep2]
    fields = {k: v[keep] for k, v in mesh.vertex_fields.items()}
    return Mesh(V, F, fields, dict(mesh.face_fields), log)


def split_nonmanifold_vertices(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Give every fan of faces its own vertex (a bowtie's two fans become two
    vertices at the same position). The corners fall into the same vertices
    as with MeshLab's ``meshing_repair_non_manifold_vertices`` at
    ``vertdispratio=0`` run until it changes nothing (one run leaves part of
    a vertex with three or more fans joined), which gives no map back to the
    input's vertices.

    A vertex with one fan (or none) keeps its index; each further fan of a
    vertex gets a new vertex appended, in order of the input vertex and then
    of the fan's first corner, so the numbering does not depend on anything
    but V and F. Unlike ``igl.split_nonmanifold``, faces are not split apart
    where their orientations disagree: only the vertices are split, and an
    edge shared by more than two faces stays so.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array

    Returns
    -------
    V2 : (n2, 3) float array
        ``V[source]``.
    F2 : (m, 3) int array
        The same faces on the split vertices.
    source : (n2,) int array
        The input vertex of each output vertex (``source[:n]`` is ``0..n-1``).
    """
    from geoproc.mesh.topology import corner_fans

    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    n = len(V)
    count, label = corner_fans(F, n)
    corner_vertex = F.reshape(-1)
    first = np.full(count, F.size, dtype=np.int64)
    np.minimum.at(first, label, np.arange(F.size))  # each fan's first corner
    fan_vertex = corner_vertex[first]
    order = np.lexsort((first, fan_vertex))  # fans by vertex, then by first corner
    later = np.ones(count, dtype=bool)
    later[order[np.r_[True, fan_vertex[order[1:]] != fan_vertex[order[:-1]]]]] = False  # a vertex's first fan
    new_index = fan_vertex.copy()
    extra = order[later[order]]
    new_index[extra] = n + np.arange(len(extra))
    source = np.concatenate([np.arange(n), fan_vertex[extra]])
    return V[source], new_index[label].reshape(-1, 3), source
