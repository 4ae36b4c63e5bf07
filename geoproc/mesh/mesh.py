"""The in-memory mesh (or point cloud) with named per-vertex and per-face fields."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class LoadLog:
    """What happened between the bytes on disk and the :class:`Mesh` in memory.

    Attributes
    ----------
    path : str
        The file read (``"-"`` for standard input).
    format : str
        ``"obj"``, ``"ply"``, ``"off"`` or ``"stl"``.
    stored_vertices, stored_faces : int
        Counts as stored in the file (faces after triangulation).
    triangulated_polygons : int
        Polygons with more than three corners that were split into triangles (fan).
    merged_vertices : int
        Vertices removed by merging coincident positions.
    removed_unreferenced : int
        Vertices removed because no face used them.
    collapsed_faces : int
        Faces stored with three distinct vertices that repeat one once
        coincident positions are merged (two corners at one position: an edge
        of length zero), and ``first_collapsed_face`` the first of them (-1
        when none): a method that needs a manifold refuses them, and its
        message says the merge made them.
    cleaned : bool
        False when the mesh was kept as stored (``--no-clean``).
    sha256 : str
        Hex SHA-256 of the bytes parsed ("" when the mesh was not read from bytes):
        what a report records, without reading the file a second time.
    unread_properties : list of str
        PLY properties stored in the file but not read into fields, as
        ``"vertex nbrs"`` or ``"face texcoord"``: list properties (other than
        the face's vertex indices), face properties when the file also
        holds triangle strips, and other elements than vertex, face and
        tristrips with rows (``"element edge"``). Only scalar properties travel.
        For OBJ and OFF, what they store beyond positions and faces:
        ``"texture coordinates (vt)"``, ``"vertex colours (C)"``...
    """

    path: str = ""
    format: str = ""
    stored_vertices: int = 0
    stored_faces: int = 0
    triangulated_polygons: int = 0
    merged_vertices: int = 0
    removed_unreferenced: int = 0
    collapsed_faces: int = 0
    first_collapsed_face: int = -1
    cleaned: bool = True
    sha256: str = ""
    unread_properties: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """Plain-dict form, for reports."""
        return {k: list(v) if isinstance(v, list) else v for k, v in self.__dict__.items()}


@dataclass
class Mesh:
    """A triangle mesh, or a point cloud when ``F`` has no rows.

    Attributes
    ----------
    V : (n, 3) float64 array
        Vertex positions, in the file's length unit.
    F : (m, 3) int64 array
        Triangles as vertex indices, counter-clockwise seen from outside; shape
        (0, 3) for a point cloud.
    vertex_fields : dict of str to (n,) or (n, k) numeric array
        Named per-vertex values (PLY vertex properties other than x, y, z), in
        the type they were stored in (uint8 colours, float32, ...) or float64
        when computed; convert before arithmetic.
    face_fields : dict of str to (m,) or (m, k) numeric array
        Named per-face values (PLY face properties other than the index list),
        typed as ``vertex_fields``.
    log : LoadLog
        How the mesh was read and cleaned.
    """

    V: np.ndarray
    F: np.ndarray
    vertex_fields: dict[str, np.ndarray] = field(default_factory=dict)
    face_fields: dict[str, np.ndarray] = field(default_factory=dict)
    log: LoadLog = field(default_factory=LoadLog)

    def __post_init__(self) -> None:
        V, F = np.asarray(self.V), np.asarray(self.F)
        for name, a in (("V", V), ("F", F)):  # no reshaping of other shapes into rows of 3
            if a.size and (a.ndim != 2 or a.shape[1] != 3):
                raise ValueError(f"Mesh.{name} must have shape (k, 3), not {a.shape}")
        if F.size and not np.issubdtype(F.dtype, np.integer) and not np.array_equal(F, np.round(F)):
            raise ValueError("Mesh.F must hold integer vertex indices")
        self.V = np.ascontiguousarray(V, dtype=np.float64).reshape(-1, 3)
        self.F = np.ascontiguousarray(F, dtype=np.int64).reshape(-1, 3)

    @property
    def is_point_cloud(self) -> bool:
        """True when the mesh has vertices and no faces."""
        return len(self.F) == 0

    @property
    def n_vertices(self) -> int:
        return len(self.V)

    @property
    def n_faces(self) -> int:
        return len(self.F)

    def copy(self) -> Mesh:
        """Deep copy (arrays and field dicts)."""
        return Mesh(
            self.V.copy(),
            self.F.copy(),
            {k: v.copy() for k, v in self.vertex_fields.items()},
            {k: v.copy() for k, v in self.face_fields.items()},
            LoadLog(**self.log.as_dict()),
        )
