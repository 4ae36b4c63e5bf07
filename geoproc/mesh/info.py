"""Topological and geometric summary of a mesh (``geoproc info``)."""

from __future__ import annotations

import numpy as np

from geoproc.mesh.clean import repeated_positions
from geoproc.mesh.mesh import Mesh
from geoproc.mesh.topology import (
    count_boundary_loops,
    degenerate_faces,
    duplicate_faces,
    faces_with_distinct_corners,
    nonmanifold_vertices,
    orientation_status,
    referenced_vertices,
    unique_edges,
    used_bbox_diagonal,
    vertex_components,
)


def mesh_info(mesh: Mesh) -> dict:
    """Counts, topology flags and sizes of a mesh or point cloud.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    dict
        ``vertices, faces, edges`` (unique undirected), ``components`` (vertices joined by edges, a bowtie is one;
        over referenced vertices), ``boundary_edges, boundary_loops``,
        ``euler_characteristic`` (V - E + F, V counting referenced vertices;
        the topology entries count the faces with three distinct corners
        only, a face repeating one being a degenerate face),
        ``genus`` (closed, orientable, edge- and vertex-manifold meshes only, summed
        over components: (2C - chi) / 2; else None), ``closed, edge_manifold,
        vertex_manifold, orientable, consistently_oriented``,
        ``nonmanifold_edges, nonmanifold_vertices, degenerate_faces,
        duplicate_faces`` (faces with the corners of an earlier face, in any order),
        ``duplicate_vertices`` (vertices at a position already taken by a lower index),
        ``unreferenced_vertices, mean_edge_length`` (length unit),
        ``bbox_diagonal`` (length unit; of the vertices the faces use, of every
        point for a point cloud), ``vertex_properties, face_properties``
        (names), ``unread_properties`` (what the file stores that is not read, as
        :attr:`geoproc.mesh.mesh.LoadLog.unread_properties`), ``point_cloud``.
        Topology entries are None for a point cloud, and ``genus`` to
        ``consistently_oriented`` when no face has three distinct corners.
    """
    V, F = mesh.V, mesh.F
    n = len(V)
    diag = used_bbox_diagonal(V, F)
    duplicates = repeated_positions(V)
    info: dict = {
        "vertices": n,
        "faces": len(F),
        "point_cloud": mesh.is_point_cloud,
        "duplicate_vertices": int(duplicates),
        "bbox_diagonal": diag,
        "vertex_properties": sorted(mesh.vertex_fields),
        "face_properties": sorted(mesh.face_fields),
        "unread_properties": list(mesh.log.unread_properties),
    }
    if mesh.is_point_cloud:
        info.update(dict.fromkeys(
            ["edges", "components", "boundary_edges", "boundary_loops", "euler_characteristic",
             "genus", "closed", "edge_manifold", "vertex_manifold", "orientable",
             "consistently_oriented", "nonmanifold_edges", "nonmanifold_vertices",
             "degenerate_faces", "duplicate_faces", "mean_edge_length"]))
        info["unreferenced_vertices"] = 0
        return info
    # the topology of the faces with three distinct corners: a face that repeats one (an STL
    # facet whose corners merged) bounds no surface, and its "edge" from a vertex to itself
    # had counted as a non-manifold or boundary edge of length 0 (a closed tetrahedron with
    # such a facet read as open, not edge-manifold, mean edge length 1.035 for 1.207);
    # degenerate_faces counts it
    Ft = faces_with_distinct_corners(F)
    edges = unique_edges(Ft)
    E, _, count = edges
    n_used = int(referenced_vertices(Ft, n).sum())
    n_comp, _ = vertex_components(Ft, n)
    nm_e = int((count > 2).sum())
    nm_v = len(nonmanifold_vertices(Ft, n))
    orientable, oriented = orientation_status(Ft, edges)
    n_boundary = int((count == 1).sum())
    chi = n_used - len(E) + len(Ft)
    closed = n_boundary == 0
    manifold = nm_e == 0 and nm_v == 0
    genus = None
    if closed and manifold and orientable and (2 * n_comp - chi) % 2 == 0:
        genus = (2 * n_comp - chi) // 2
    lengths = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    info.update(
        edges=len(E),
        components=n_comp,
        boundary_edges=n_boundary,
        boundary_loops=count_boundary_loops(Ft, edges),
        euler_characteristic=int(chi),
        genus=genus,
        closed=bool(closed),
        edge_manifold=nm_e == 0,
        vertex_manifold=nm_v == 0,
        orientable=bool(orientable) if nm_e == 0 else None,
        consistently_oriented=bool(oriented) if nm_e == 0 else None,
        nonmanifold_edges=nm_e,
        nonmanifold_vertices=nm_v,
        degenerate_faces=len(degenerate_faces(V, F, diagonal=diag)),
        duplicate_faces=len(duplicate_faces(Ft)),
        unreferenced_vertices=n - int(referenced_vertices(F, n).sum()),
        mean_edge_length=float(lengths.mean()) if len(lengths) else 0.0,
    )
    if not len(Ft):  # every face collapsed: no surface to be closed, manifold or of a genus
        info.update(dict.fromkeys(["genus", "closed", "edge_manifold", "vertex_manifold", "orientable",
                                   "consistently_oriented"]))
    return info


def worst_frame_counts(frames: np.ndarray, F: np.ndarray) -> dict:
    """An animation's geometry counts over every frame, where its first
    frame's :func:`mesh_info` would miss them (a face collapsed in frame 3
    alone had read 0): ``degenerate_faces`` and ``duplicate_vertices``, each
    the most of any frame of ``frames`` (T, n, 3) with triangles F (m, 3;
    none for a moving point cloud, which has no ``degenerate_faces`` entry:
    its first frame's null stands), and ``worst_frame``: the first frame with
    the most degenerate faces, or where no frame has any, the first with the
    most duplicate vertices; -1 when no frame has either. (Both counts had
    been read from one frame, the worst by degenerate faces first, so more
    duplicates in another frame were missed.)"""
    degenerate = np.array([len(degenerate_faces(V, F, diagonal=used_bbox_diagonal(V, F))) if len(F) else 0
                           for V in frames], dtype=np.int64)
    duplicates = np.array([repeated_positions(V) for V in frames], dtype=np.int64)
    by = degenerate if degenerate.max(initial=0) > 0 else duplicates
    worst = int(np.argmax(by)) if by.max(initial=0) > 0 else -1
    counts = {"duplicate_vertices": int(duplicates.max(initial=0)), "worst_frame": worst}
    return {"degenerate_faces": int(degenerate.max(initial=0)), **counts} if len(F) else counts
