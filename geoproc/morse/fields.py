"""The scalar field a Morse computation runs on, from a --field specification."""

from __future__ import annotations

import os
import re
import unicodedata

import numpy as np

from geoproc.errors import InputError
from geoproc.fileio import read_input_bytes
from geoproc.mesh import Mesh
from geoproc.mesh.validate import npy_vertex_values, require_vertex_field, scalar_vertex_properties

COORDINATES = {"x": 0, "y": 1, "z": 2}
CURVATURES = ("mean-curvature", "gaussian-curvature")


def mean_curvature(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) mean curvature (k1 + k2) / 2 per vertex, in 1/length, from libigl's
    quadric-fitting principal curvatures (``igl.principal_curvature``, its
    sign convention: positive on a sphere whose faces wind outwards).

    The faces are first turned to agree with their neighbours, each connected
    part keeping the winding of most of its faces
    (:func:`geoproc.mesh.orientation.consistent_orientation`): the fit reads
    the sign from each face's winding, and an icosphere with 30 % of its
    faces stored the other way round read from -7.3 to 4.5 for 1.10 to 1.12.
    """
    import igl

    from geoproc.mesh.orientation import consistent_orientation

    Fo = consistent_orientation(F)[0]
    _, _, k1, k2, _ = igl.principal_curvature(np.ascontiguousarray(V), np.ascontiguousarray(Fo))
    return 0.5 * (np.asarray(k1) + np.asarray(k2))


def gaussian_curvature(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) pointwise Gaussian curvature per vertex, in 1/length^2: libigl's
    angle defect (``2 pi`` minus the angles around the vertex) divided by the
    vertex's Voronoi area; 0 where that area is 0 (a vertex no face uses).

    On a boundary the angle defect measures how the boundary turns, not the
    surface's curvature: the interior formula gave the straight edge of a flat
    unit square pi / area (2513 on a 21 x 21 grid), and ``pi`` minus the angles
    (the boundary convention of geometry-central) still gives its corners and
    a jagged cut through a sphere values from -392 to 835. A boundary vertex
    takes the Voronoi-area-weighted mean of its interior neighbours' values
    instead; one with none (a corner of a grid patch, a vertex between two
    boundary edges of one face) then takes that of its neighbours that have a
    value, repeatedly; 0 where no interior vertex is reachable (a strip one
    face wide).
    """
    import igl

    from geoproc.mesh.topology import boundary_vertices, edge_adjacency_matrix, unique_edges

    V = np.ascontiguousarray(V)
    F = np.ascontiguousarray(F)
    K = np.asarray(igl.gaussian_curvature(V, F), dtype=np.float64)
    M = igl.massmatrix(V, F, igl.MassMatrixType.MASSMATRIX_TYPE_VORONOI)
    # libigl sizes the mass matrix by the largest face index: unused vertices
    # stored last (kept by --no-clean) have no entry there
    area = np.zeros(len(V))
    area[:M.shape[0]] = M.diagonal()
    K = np.divide(K, area, out=np.zeros_like(K), where=area > 0)
    b = boundary_vertices(F)
    if len(b):
        known = np.ones(len(V), dtype=bool)
        known[b] = False
        E = unique_edges(F)[0]
        E = E[E[:, 0] != E[:, 1]]
        A = edge_adjacency_matrix(E, len(V))[b]
        K[b] = 0.0
        todo = np.ones(len(b), dtype=bool)
        while todo.any():  # from the interior outwards, one ring of boundary vertices at a time
            w = A @ (area * known)
            reach = todo & (w > 0)
            if not reach.any():
                break
            K[b[reach]] = (A[reach] @ (area * known * K)) / w[reach]
            known[b[reach]] = True
            todo &= ~reach
    return K


def computes_curvature(mesh: Mesh, spec: str) -> bool:
    """Whether ``spec`` names a curvature :func:`vertex_field` computes: one of
    :data:`CURVATURES` that is not a vertex property of ``mesh`` (a property
    stored under that name is the field; it had been shadowed by the
    computed curvature without a word)."""
    return spec in CURVATURES and spec not in mesh.vertex_fields


def field_name(spec: str, stored: bool = False) -> str:
    """The vertex property name the field is written under in the output PLY.

    A property keeps its name (``stored``: ``spec`` is the mesh's vertex
    property, even one named as a curvature); ``x``/``y``/``z`` become
    ``x_value`` etc. (``x``, ``y``, ``z`` are the coordinates); computed
    curvatures become ``mean_curvature`` / ``gaussian_curvature``; a ``.npy``
    file gives its stem (``x.npy``, ``y.npy``, ``z.npy`` also become
    ``x_value`` etc.).
    """
    if spec in COORDINATES:
        return f"{spec}_value"
    if stored and not spec.lower().endswith(".npy"):
        return spec
    if spec in CURVATURES:
        return spec.replace("-", "_")
    if spec.lower().endswith(".npy"):
        stem = os.path.splitext(os.path.basename(spec))[0]
        stem = unicodedata.normalize("NFKD", stem).encode("ascii", "ignore").decode()  # é.npy: e, not _
        name = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "field"
        return f"{name}_value" if name in COORDINATES else name
    return spec


def vertex_field(mesh: Mesh, spec: str, data: bytes | None = None) -> np.ndarray:
    """Resolve ``spec`` to one finite value per vertex.

    Parameters
    ----------
    mesh : Mesh
        The triangle mesh.
    spec : str
        A per-vertex property of the mesh (e.g. ``distance`` from
        ``geoproc geodesic``), ``x``, ``y`` or ``z``, a ``.npy`` file holding one
        value per vertex, or ``mean-curvature`` / ``gaussian-curvature``
        (libigl's, unless the mesh stores a vertex property of that name,
        which is read instead; a ``.npy`` name is always read as the file).
    data : bytes, optional
        The ``.npy`` file's content when the caller has read it (else it is read here).

    Returns
    -------
    (n,) float64 array

    Raises
    ------
    InputError
        Unknown property, unreadable ``.npy``, wrong length, or non-finite values.
    """
    if spec in COORDINATES:
        values = mesh.V[:, COORDINATES[spec]]
    elif spec == "mean-curvature" and computes_curvature(mesh, spec):
        values = mean_curvature(mesh.V, mesh.F)
    elif spec == "gaussian-curvature" and computes_curvature(mesh, spec):
        values = gaussian_curvature(mesh.V, mesh.F)
    elif spec.lower().endswith(".npy"):
        if data is None:
            data = read_input_bytes(spec, "field file (.npy)")
        values = npy_vertex_values(data, mesh, spec)
        return require_vertex_field(mesh, values, field_name(spec), path=spec)
    elif spec in mesh.vertex_fields:
        values = mesh.vertex_fields[spec]
        if values.ndim != 1:
            raise InputError(mesh.log.path or None, f"vertex property '{spec}' has {values.shape[1]} "
                             "components; a scalar field is needed")
    else:
        raise InputError(
            mesh.log.path or None,
            f"no vertex property '{spec}' (scalar properties: {scalar_vertex_properties(mesh)}); use a property name, "
            "x, y, z, a .npy file, mean-curvature or gaussian-curvature",
        )
    return require_vertex_field(mesh, values, spec)
