"""Connected parts of a mesh grouped by the length of their edges.

The noise estimate and the filter's kernels are lengths in mean edge lengths
of the whole mesh. A mesh made of parts meshed at very different scales (a
part a thousandth the size of the rest, a two-triangle floor two thousand
units wide) mixes them: the small part pulled the estimate to "clean", and
the noisy rest was handed back unchanged. :func:`denoise_mesh` denoises each
group of parts of about one scale on its own.
"""

from __future__ import annotations

import numpy as np

from geoproc.mesh.topology import unique_edges, vertex_components

SCALE_RATIO = 4.0
"""Parts whose mean edge lengths are within this factor of the group's
smallest share a group (teapot's three parts differ by 1.78)."""


def scale_groups(V: np.ndarray, F: np.ndarray, ratio: float = SCALE_RATIO) -> np.ndarray:
    """(m,) int64 group of each face of the mesh (V (n, 3), F (m, 3)): its
    connected parts sorted by their mean edge length (length unit), a new
    group starting where a part's exceeds ``ratio`` times the group's first.
    Groups are numbered by increasing edge length from 0; a mesh of one
    scale is one group (all zeros). A part whose edges all have length 0 (its
    vertices at one place) has no scale: it joins the group of the smallest
    part that has one (alone it had been refused, its faces coinciding)."""
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if not len(F):
        return np.zeros(0, dtype=np.int64)
    count, part = vertex_components(F, len(V))
    if count < 2:
        return np.zeros(len(F), dtype=np.int64)
    E = unique_edges(F)[0]
    length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    edges = np.bincount(part[E[:, 0]], minlength=count)
    mean = np.bincount(part[E[:, 0]], weights=length, minlength=count) / np.maximum(edges, 1)
    order = np.argsort(mean, kind="stable")
    order = order[mean[order] > 0]  # the parts with a scale; the others stay in group 0
    group_of_part = np.zeros(count, dtype=np.int64)
    group, first = 0, None
    for c in order.tolist():
        if first is not None and mean[c] > ratio * first:
            group += 1
            first = None
        if first is None:
            first = mean[c]
        group_of_part[c] = group
    return group_of_part[part[F[:, 0]]]
