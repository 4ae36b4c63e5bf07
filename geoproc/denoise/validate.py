"""Input checks of the denoising methods (one-line InputErrors)."""

from __future__ import annotations

import numpy as np

from geoproc.errors import InputError
from geoproc.mesh.topology import nonmanifold_edges


def require_edge_manifold(F: np.ndarray, path: str | None) -> None:
    """Refuse edges shared by more than two faces: the patches and the edge
    saliency of the guided filter need at most two faces per edge."""
    bad = nonmanifold_edges(F)
    if len(bad):
        a, b = (int(x) for x in bad[0])
        raise InputError(path, f"non-manifold: {len(bad)} edges have more than two faces "
                         f"(first: edge {a}-{b}); denoising needs at most two faces per edge")


def require_same_connectivity(F: np.ndarray, n: int, F_ref: np.ndarray, n_ref: int, path: str | None) -> None:
    """Refuse a reference whose vertex count or faces differ from the input's."""
    if n_ref != n or F_ref.shape != F.shape or (F_ref != F).any():
        raise InputError(path, f"reference connectivity differs from the input ({n_ref} vertices, "
                         f"{len(F_ref)} faces vs {n}, {len(F)}); load both with the same --no-clean setting")
