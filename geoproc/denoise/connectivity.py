"""What the mesh denoisers need from the faces alone, built once per connectivity.

:func:`geoproc.denoise.mesh_denoise.denoise_mesh` builds it for its mesh; an
animation (:func:`geoproc.denoise.dynamic.denoise_animation`) builds it once and
passes it to every frame, whose faces are the same.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from geoproc.denoise.face_geometry import face_centroids, face_edge_neighbors, face_ring_csr
from geoproc.denoise.guidance import patch_interior_edges
from geoproc.denoise.validate import require_denoisable
from geoproc.mesh.locality import inverse_permutation, morton_order
from geoproc.mesh.orientation import consistent_orientation


@dataclass(eq=False)
class FaceConnectivity:
    """Faces of one mesh, turned consistently, with their neighbourhoods.

    Attributes
    ----------
    faces : (m, 3) int64 the faces as given.
    n : int
        Number of vertices.
    F : (m, 3) int64 the faces turned to agree with their edge neighbours
        (:func:`geoproc.mesh.orientation.consistent_orientation`).
    flip : (m,) bool faces that were turned.
    edge_nb : (m, 3) int64 :func:`geoproc.denoise.face_geometry.face_edge_neighbors` of F.
    """

    faces: np.ndarray
    n: int
    F: np.ndarray
    flip: np.ndarray
    edge_nb: np.ndarray
    _work: tuple | None = field(default=None, repr=False)

    @cached_property
    def ring(self) -> tuple[np.ndarray, np.ndarray]:
        """The faces sharing a vertex with each face, as CSR (indptr, indices)
        (:func:`geoproc.denoise.face_geometry.face_ring_csr`, one ring), built on first use."""
        return face_ring_csr(self.F, self.n, 1)

    @cached_property
    def inside(self) -> tuple[np.ndarray, np.ndarray]:
        """The edges inside every ring patch
        (:func:`geoproc.denoise.guidance.patch_interior_edges`), built on first use."""
        return patch_interior_edges(self.ring, self.edge_nb)

    def renumbered(self, vertex_order: np.ndarray, face_order: np.ndarray) -> FaceConnectivity:
        """The same connectivity with vertex ``vertex_order[i]`` as vertex i and
        face ``face_order[k]`` as face k (both (n,) and (m,) permutations)."""
        inv = inverse_permutation(vertex_order)
        nb = self.edge_nb[face_order]  # the corners keep their order: the same neighbours, renamed
        return FaceConnectivity(faces=inv[self.faces[face_order]], n=self.n, F=inv[self.F[face_order]],
                                flip=self.flip[face_order],
                                edge_nb=np.where(nb >= 0, inverse_permutation(face_order)[nb], -1))

    def work_order(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray, FaceConnectivity]:
        """``(vertex_order, face_order, renumbered)``: vertices and faces along a
        Z-order curve (:func:`geoproc.mesh.locality.morton_order`) of the
        positions ``V`` (n, 3), and :meth:`renumbered` in that order, where the
        filters run with their neighbours close in memory. Computed from the
        first positions given and kept: the frames of an animation share it."""
        if self._work is None:
            vo = morton_order(V)
            fo = morton_order(face_centroids(V, self.F))
            self._work = (vo, fo, self.renumbered(vo, fo))
        return self._work

    def matches(self, F: np.ndarray, n: int) -> bool:
        """Whether this was built from faces ``F`` over ``n`` vertices."""
        return n == self.n and np.array_equal(F, self.faces)


def face_connectivity(F: np.ndarray, n: int) -> FaceConnectivity:
    """Check the faces for denoising (:func:`geoproc.denoise.validate.require_denoisable`)
    and build their :class:`FaceConnectivity`.

    Parameters
    ----------
    F : (m, 3) int64 triangles over ``n`` vertices (indices already checked in range).
    n : int
        Number of vertices.
    """
    faces = np.ascontiguousarray(F, dtype=np.int64)
    require_denoisable(faces, None)
    Fo, flip = consistent_orientation(faces)
    return FaceConnectivity(faces=faces, n=int(n), F=Fo, flip=flip, edge_nb=face_edge_neighbors(Fo))
