"""Gaussian, impulsive and outlier noise on vertex positions.

The noise scale is relative: ``sigma`` is in units of the mean edge length of a
mesh, or of the mean nearest-neighbour distance of a point cloud, so one number
means the same on every model (the protocol of the denoising literature).

libigl, scipy's k-d tree and the topology kernels are imported by the functions
that use them: the command line checks its options with :class:`NoiseSpec`
before it loads them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoproc.errors import InputError, UsageError, frame_error
from geoproc.mesh.clean import unique_rows
from geoproc.mesh.read import MAX_COORDINATE
from geoproc.mesh.validate import mesh_arrays

DIRECTIONS = ("normal", "random")
"""Directions of the Gaussian noise: along the vertex normals (the benchmark
protocol) or along random unit vectors."""


@dataclass(frozen=True)
class NoiseSpec:
    """What :func:`perturb_positions` adds.

    Attributes
    ----------
    sigma : float
        Standard deviation of the Gaussian displacement, in units of
        :func:`noise_scale` (0 for none).
    direction : {"normal", "random"}
        Along the unit vertex normal, or along a uniformly random unit direction.
    impulsive : float
        The fraction of the vertices that gets the Gaussian displacement: 1 (the
        default) every vertex; below 1 that many chosen at random (impulsive
        noise), 0 none. (0 had meant every vertex.)
    outliers : float
        Fraction of the vertices moved uniformly inside a ball of radius
        ``outlier_range`` times the bounding-box diagonal (flagged as outliers).
    outlier_range : float
        See ``outliers``.
    """

    sigma: float = 0.0
    direction: str = "normal"
    impulsive: float = 1.0
    outliers: float = 0.0
    outlier_range: float = 0.02

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and self.sigma >= 0):
            raise UsageError(f"noise sigma must be a finite number >= 0, not {self.sigma}")
        for name in ("impulsive", "outliers"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise UsageError(f"{name} is a fraction in [0, 1], not {value}")
        if not (np.isfinite(self.outlier_range) and self.outlier_range >= 0):
            raise UsageError(f"outlier_range must be a finite number >= 0, not {self.outlier_range}")


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n, 3) unit area-weighted vertex normals of a triangle mesh (libigl), its
    faces first oriented consistently (a face stored the other way round would
    cancel its neighbours' normals and tilt the noise sideways); vertices
    without a usable normal (no face uses them, or their faces' normals
    cancel) get a zero row. The sign of each normal is arbitrary."""
    import igl

    from geoproc.mesh.orientation import consistent_orientation

    V = np.ascontiguousarray(V, dtype=np.float64)  # libigl takes native float64 (not lists, not big-endian)
    F = np.ascontiguousarray(F, dtype=np.int64)
    N = igl.per_vertex_normals(V, consistent_orientation(F)[0], igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
    N = np.asarray(N, dtype=np.float64)
    bad = ~np.isfinite(N).all(axis=1) | (np.linalg.norm(N, axis=1) < 0.5)
    N[bad] = 0.0
    return N


def point_cloud_normals(P: np.ndarray, k: int = 16) -> np.ndarray:
    """(n, 3) unit normals of a point cloud: the least-variance direction of each
    point's k nearest distinct neighbours (unoriented). Copies of a point and
    its near copies (:func:`geoproc.mesh.spacing.near_copy_groups`, as the
    noise unit counts them) share one normal, taken among the other groups:
    on a sheet whose points were clumps of 15 near copies, the neighbours had
    been the clump's own jitter, and the noise went a median 45 degrees off
    the surface normal."""
    from scipy.spatial import cKDTree

    U, inverse, _, first, group = _copy_groups(P, k)
    R = U[first]
    k = min(k, len(R))
    _, idx = cKDTree(R).query(R, k=k, workers=-1)
    Q = R[idx] - R[idx].mean(axis=1, keepdims=True)
    _, W = np.linalg.eigh(np.einsum("nki,nkj->nij", Q, Q))
    return W[:, :, 0][group][inverse]


def noise_scale(V: np.ndarray, F: np.ndarray) -> float:
    """Unit of ``sigma``: mean edge length of a mesh, or mean nearest-neighbour
    distance of a point cloud (``F`` with no rows), over its distinct points:
    a point stored twice is not its own neighbour at distance 0, and a near
    copy (closer than 1e-4 of the typical distance to the 16th neighbour; a
    cloud stored twice, once rounded to float32) is not its neighbour either,
    as :func:`geoproc.denoise.outliers.rpca_outliers` counts them (it had made
    the unit 2.6e-8 of the cloud's spacing). Each group of near copies counts
    once in the mean, as a point stored many times does (five near copies of
    a dense half had weighted that half six times)."""
    from geoproc.mesh.spacing import nearest_distinct_distances
    from geoproc.mesh.topology import mean_edge_length

    V, F = mesh_arrays(V, F, allow_point_cloud=True)
    if len(F):
        return mean_edge_length(V, F)
    U, _, dist, first, _ = _copy_groups(V, 16)
    return float(nearest_distinct_distances(dist)[first].mean()) if len(U) >= 2 else 0.0


def _copy_groups(P: np.ndarray, k: int):
    """The distinct points U of a cloud P (n, 3) and each point's row there
    (``inverse``), their distances (len(U), min(k, len(U))) to their nearest
    points (themselves first), and their groups of near copies
    (:func:`geoproc.mesh.spacing.near_copy_groups`, closer than
    ``COPY_DISTANCE`` of the median distance to the farthest listed neighbour):
    each group's first point in U and each point's group. All points at one
    place, or fewer than two distinct points (no distances then): every point
    its own group."""
    from scipy.spatial import cKDTree

    from geoproc.mesh.spacing import COPY_DISTANCE, near_copy_groups

    U, inverse = unique_rows(P)
    if len(U) < 2:
        return U, inverse, None, np.arange(len(U)), np.arange(len(U))
    dist, idx = cKDTree(U).query(U, k=min(k, len(U)), workers=-1)
    far = float(np.median(dist[:, -1]))
    first, group = (near_copy_groups(idx, dist, COPY_DISTANCE * far) if far > 0
                    else (np.arange(len(U)), np.arange(len(U))))
    return U, inverse, dist, first, group


def perturb_positions(
    V: np.ndarray, F: np.ndarray, spec: NoiseSpec, rng: np.random.Generator, path: str | None = None,
    scale: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Add noise to one set of positions.

    Parameters
    ----------
    V : (n, 3) float64 positions; F : (m, 3) triangles, or no rows for a point cloud.
    spec : NoiseSpec
    rng : numpy Generator (the only source of randomness: the same state gives
        the same output).
    path : str, optional
        File name for error messages.
    scale : float, optional
        :func:`noise_scale` of V and F (length units), when the caller has it;
        computed here otherwise.

    Returns
    -------
    V_noisy : (n, 3) float64
    outlier : (n,) float64, 1.0 on the vertices moved as outliers.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy Generator (np.random.default_rng(seed)), not {type(rng).__name__}")
    V, F = mesh_arrays(V, F, path, allow_point_cloud=True)
    n = len(V)
    if spec.direction not in DIRECTIONS:
        raise InputError(path, f"unknown noise direction '{spec.direction}' (normal or random)")
    if len(F) == 0 and len(unique_rows(V)[0]) < 3:
        raise InputError(path, "a point cloud needs at least 3 distinct points (the noise unit is their "
                         "spacing, the normals their least-variance direction)")
    out = np.array(V, dtype=np.float64, copy=True)
    outlier = np.zeros(n)
    with np.errstate(over="ignore", invalid="ignore"):  # too large a noise is refused below
        _add_noise(out, outlier, V, F, spec, rng, scale)
    big = float(np.abs(out).max()) if out.size else 0.0
    if not big <= MAX_COORDINATE:
        far = f"as far as {big:.3g}" if np.isfinite(big) else "to non-finite positions"
        given = " / ".join([f"--noise {spec.sigma:g}"] * (spec.sigma > 0)
                           + [f"--outlier-range {spec.outlier_range:g}"] * (spec.outliers > 0))
        raise UsageError(f"{given} move{'s' if ' / ' not in given else ''} vertices {far}, "
                         f"beyond the +-{MAX_COORDINATE:.0e} a mesh may span; use "
                         f"{'smaller values' if ' / ' in given else 'a smaller value'}")
    return out, outlier


def _random_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) unit vectors, uniform on the sphere."""
    D = rng.standard_normal((n, 3))
    D /= np.maximum(np.linalg.norm(D, axis=1, keepdims=True), 1e-300)
    return D


def _add_noise(out: np.ndarray, outlier: np.ndarray, V: np.ndarray, F: np.ndarray, spec: NoiseSpec,
               rng: np.random.Generator, scale: float | None = None) -> None:
    """Add ``spec``'s displacements to ``out`` (n, 3) in place and set ``outlier`` (n,)."""
    n = len(V)
    if spec.sigma > 0:
        scale = noise_scale(V, F) if scale is None else scale
        if spec.direction == "normal":
            D = vertex_normals(V, F) if len(F) else point_cloud_normals(V)
        else:
            D = _random_directions(rng, n)
        amount = rng.standard_normal(n) * spec.sigma * scale
        if spec.impulsive < 1:  # (every vertex draws no choice: the default's bytes as they were)
            chosen = np.zeros(n, dtype=bool)
            chosen[rng.permutation(n)[: int(round(spec.impulsive * n))]] = True
            amount[~chosen] = 0.0
        none = ~D.any(axis=1)
        if none.any():  # no normal to move along (drawn last: the other vertices keep their noise)
            D[none] = _random_directions(rng, int(none.sum()))
        out += D * amount[:, None]
    if spec.outliers > 0:
        from geoproc.mesh.topology import used_bbox_diagonal  # (scipy: loaded when outliers ask)

        diag = used_bbox_diagonal(V, F)  # a stray vertex kept by --no-clean does not widen it
        idx = np.sort(rng.permutation(n)[: int(round(spec.outliers * n))])
        u = rng.standard_normal((len(idx), 3))
        u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
        radius = spec.outlier_range * diag * rng.random(len(idx)) ** (1.0 / 3.0)
        out[idx] += u * radius[:, None]
        outlier[idx] = 1.0


def outlier_flags(values: np.ndarray, shape: tuple[int, ...], path: str | None = None,
                  frame_files: list[str] | None = None) -> np.ndarray:
    """An ``outlier`` property read back as flags.

    Parameters
    ----------
    values : array of shape ``shape`` (or with a trailing axis of 1), 1.0 on
        outliers and 0.0 elsewhere (values above 0.5 count as outliers).
    shape : (n,) for a mesh or cloud, (frames, n) for an animation.
    path : str, optional
        File name for error messages.
    frame_files : list of str, optional
        For an animation read from a folder, its frame files: a frame with
        non-finite values is named by its file (else by its index).

    Returns
    -------
    bool array of ``shape``; InputError when the values have another shape or are not finite.
    """
    flags = np.asarray(values, dtype=np.float64)
    if flags.ndim == len(shape) + 1 and flags.shape[-1] == 1:
        flags = flags[..., 0]
    if flags.shape != tuple(shape):
        raise InputError(path, f"'outlier' property has shape {flags.shape}; expected {tuple(shape)}")
    if not np.isfinite(flags).all():
        what = "'outlier' property has non-finite values (0 marks an inlier, 1 an outlier)"
        if flags.ndim == 2:  # an animation: name the first frame that has one
            raise frame_error(path, int(np.flatnonzero(~np.isfinite(flags).all(axis=1))[0]), what, frame_files)
        raise InputError(path, what)
    return flags > 0.5
