"""Feature-preserving mesh denoising: filter face normals, then fit the vertices.

Three ways to filter the normals share one pipeline (:func:`denoise_mesh`):

``bilateral``
    Bilateral normal filter, range kernel on the normals themselves (Zheng et al. 2011).
``guided``
    Joint bilateral filter whose range kernel uses guidance normals from the most
    consistent patch containing each face (Zhang et al. 2015).
``rpca``
    Once per round, the guidance normals of every face's patch are stacked in a
    matrix and split by RPCA into a low-rank part (the piecewise-smooth normal
    field, used as the round's fixed guidance) and a sparse part (features and
    impulsive outliers).

Each outer iteration filters the normals ``normal_iterations`` times, then moves
the vertices to fit them (Sun et al. 2007) and recomputes the normals.

At strong noise (roughness from ``STRONG_ROUGHNESS``), ``guided`` ends differently: on
finely meshed surfaces the last round adds ``FINE_FINAL_PASSES`` guided passes
with the narrower range kernel ``FINE_FINAL_SIGMA_R`` and fits twice; then the
targets of faces the fit squashed against a crease become bisectors
(:func:`geoproc.denoise.crease_targets.bisect_collapsed_targets`) and the
vertices are fitted once more. This repair and the blend of the guidance with
the normals (``guidance_mix``) follow the input whatever the schedule; both can
be set (:class:`~geoproc.denoise.params.DenoiseParams`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from geoproc.denoise import DEFAULT_METHOD, METHODS
from geoproc.denoise.bilateral import bilateral_normal_filter, spatial_weights
from geoproc.denoise.connectivity import FaceConnectivity, face_connectivity
from geoproc.denoise.crease_targets import bisect_collapsed_targets, input_side_targets
from geoproc.denoise.face_geometry import (
    collinear_faces,
    collinear_middles,
    face_aspect,
    face_centroids,
    face_edge_neighbors,
    face_normals_and_areas,
    keep_on_segments,
    on_segments_as_stored,
)
from geoproc.denoise.features import dihedral_feature_faces, l1_feature_faces
from geoproc.denoise.guidance import guidance_normals
from geoproc.denoise.noise_level import roughness
from geoproc.denoise.params import DenoiseParams
from geoproc.denoise.patches import nearest_faces_in_ring
from geoproc.denoise.rpca import rpca
from geoproc.denoise.scale_groups import scale_groups
from geoproc.denoise.vertex_update import unfold_faces, update_vertices
from geoproc.errors import InputError, UsageError
from geoproc.mesh.clean import remove_unreferenced_vertices
from geoproc.mesh.locality import inverse_permutation
from geoproc.mesh.topology import boundary_vertices, repeated_corner_faces
from geoproc.mesh.validate import mesh_arrays


def edge_dihedral_deg(V: np.ndarray, F: np.ndarray, edge_nb: np.ndarray | None = None) -> np.ndarray:
    """Angle in degrees between the normals of the two faces at each interior
    edge (each edge once per side: (2 k,) for k interior edges)."""
    N, _ = face_normals_and_areas(V, F)
    enb = face_edge_neighbors(F) if edge_nb is None else edge_nb
    i, k = np.nonzero(enb >= 0)
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", N[i], N[enb[i, k]]), -1.0, 1.0)))


def median_dihedral_deg(V: np.ndarray, F: np.ndarray, edge_nb: np.ndarray | None = None) -> float:
    """Median angle in degrees between the normals of edge-adjacent faces.

    On a clean, reasonably fine mesh this is a few degrees; noise of
    ``sigma`` mean edge lengths along the normals raises it to about
    ``19 deg at sigma=0.2`` and ``26 deg at sigma=0.3``: a noise-level estimate
    read from the mesh itself.
    """
    ang = edge_dihedral_deg(V, F, edge_nb)
    return float(np.median(ang)) if len(ang) else 0.0


FEATURE_METHODS = ("l1", "dihedral", "none")
# the last round of the automatic strong schedule on finely meshed surfaces:
# extra guided passes with this narrower range kernel (see denoise_mesh)
FINE_FINAL_PASSES = 2
FINE_FINAL_SIGMA_R = 0.2
# the share of denoise_mesh's progress taken by the noise and shape estimates
ESTIMATE_SHARE = 0.3
STRONG_ROUGHNESS = 0.18
"""Roughness from which the guided method ends with the crease repair
(:class:`~geoproc.denoise.params.DenoiseParams` ``crease_repair``)."""


def light_schedule(rough: float, coarse_weight: float, sharp_weight: float, low: float) -> dict:
    """The schedule below the strong ramp (``rough < low``): weak noise.

    ``u = (rough - r0) / (low - r0)`` measures the noise across this range;
    ``r0`` is 0.03 on finely meshed surfaces and 0.045 on coarse ones, whose
    curvature alone reads as roughness up to about 0.045 (the clean 7k-face
    bunny). Below ``r0`` nothing is filtered; over the next 0.02 the range
    kernel widens from 0.1 (``fade``; also the width used below ``r0`` when
    the caller sets the rounds and passes itself).

    - Surfaces with creases (``sharp_weight`` 1): 3 rounds of 3 to 5 passes,
      sigma_r 0.2 to 0.35; creases stand far above weak noise, so many passes
      with a narrow kernel flatten the noise and keep them. Coarse ones move
      to 1 round of 1 pass rising to the 2 rounds of 2 passes with sigma_r
      0.8 that the strong schedule starts from on them (the teapot at 0.2
      mean edge lengths, just below ``low``, had ended at 15.85 degrees with
      the narrow passes, and at 10.11 at 0.3 with the broad ones).
    - Smooth surfaces: 1 round of 1 pass rising to 2 rounds of 2 passes;
      sigma_r 0.45 to 0.5 when finely meshed, 0.45 widening to 1 on coarse
      meshes (the strong branch's plain bilateral filter).

    Weak noise needs no guidance: the filter is the plain bilateral one
    (``guidance_mix`` 1). On finely meshed smooth surfaces the guidance comes
    in from u = 0.75 to 0.95, and coarse smooth ones move to 2 centroid
    spacings, so that the schedule meets the strong branch at ``low``. On
    coarse meshes with creases the guidance comes in over the same range, in
    proportion to the coarseness weight (the teapot at 0.2: 11.59 degrees
    with 40 new flips without it, 9.99 with 10; finely meshed ones keep the
    plain filter up to ``low``, which suits them better: with the guidance
    coming in, fandisk and the cube at 0.15 went from 1.55 and 1.25 degrees to
    1.66 and 1.37).
    """
    w, ws = coarse_weight, sharp_weight
    r0 = 0.03 + 0.015 * w
    u = float(np.clip((rough - r0) / (low - r0), 0.0, 1.0))
    fade = float(np.clip((rough - r0) / 0.02, 0.0, 1.0))
    # smooth surfaces: the same counts finely meshed or coarse, only sigma_r differs
    smooth_sigma_r = (1 - w) * (0.45 + 0.05 * u) + w * float(np.interp(u, [0.0, 0.4], [0.45, 1.0]))
    smooth = (1 + (u - 0.1), 1 + (u + 0.2), smooth_sigma_r)
    # with creases: many narrow passes when finely meshed; coarse meshes (whose curved
    # facets a narrow kernel carves into false creases) move to the broad and short
    # filter that the strong schedule starts from on them (2 rounds of 2 passes, sigma_r 0.8)
    sharp_fine = (3, 3 + 2 * u, 0.2 + 0.15 * u)
    sharp_coarse = (1 + (u - 0.1), 1 + (u + 0.2), 0.45 + 0.35 * u)
    sharp = tuple((1 - w) * a + w * b for a, b in zip(sharp_fine, sharp_coarse, strict=True))
    rounds, passes, sigma_r = ((1 - ws) * a + ws * b for a, b in zip(smooth, sharp, strict=True))
    if fade <= 0.0:
        rounds = passes = 0
    organic = w * (1.0 - ws)
    ramp = float(np.clip((u - 0.75) / 0.2, 0.0, 1.0))
    return {"outer_iterations": int(round(rounds)), "normal_iterations": int(round(passes)),
            "sigma_r": max(sigma_r * fade, 0.1), "spatial_scale": 1.0 + organic * ramp,
            "guidance_mix": 1.0 - ((1.0 - organic) * (1.0 - ws) + ws * w) * ramp, "coarse_weight": w,
            "narrow_weight": 1.0}


def default_schedule(rough: float, coarseness_deg: float = 0.0, tail_ratio: float = np.inf) -> dict:
    """Iteration counts and kernel widths from the estimated noise level and shape.

    ``rough`` is :func:`geoproc.denoise.noise_level.roughness` of the input
    (about 0.05, 0.1, 0.18, 0.25 and 0.35 for Gaussian noise of 0.05, 0.1,
    0.2, 0.3 and 0.5 mean edge lengths; below 0.05 on clean meshes).
    ``coarseness_deg`` and ``tail_ratio`` come from
    :func:`smoothed_shape`: the median dihedral angle left after a
    plain smoothing (about 1-3 degrees on finely meshed surfaces, 5-7 on
    coarse curved ones, where a narrow range kernel and many passes carve
    false creases) and the 99th percentile of those angles over the median
    (at most 9.3 on the smooth organic benchmark meshes, at least 11.4 where
    there are creases; :func:`denoise_mesh` passes
    :func:`schedule_tail_ratio`, raised where a crease share says creases);
    they set ``w = (coarseness_deg - 3.5) / 1.5`` and
    ``w_sharp = (tail_ratio - 9.5) / 1.5``, both clipped to [0, 1].

    Below ``low = 0.18 - 0.02 w_sharp`` (creases start the strong schedule
    earlier) the noise is weak: :func:`light_schedule`. From ``low`` to 0.205
    the strength ``t = (rough - low) / (0.205 - low)`` goes to strong: 5
    rounds of 10 passes with sigma_r 0.3, starting from 2 rounds of 2 passes
    with sigma_r 0.5 on smooth surfaces (smooth organic surfaces at moderate
    noise lose detail under stronger filtering) and from 3 rounds of 5
    passes with sigma_r 0.35 where there are creases (where the light
    schedule ends). Surfaces with fine detail of their own (scans; tail
    ratio 5 to 8, weight ``w_smooth`` rising from tail 4 to 5 and falling
    from 8 to 9.5; a plain sphere reads 3 to 4) go instead to the organic
    end below (2 rounds of 2 passes, sigma_r 1, 2 centroid spacings, plain
    bilateral), up to roughness 0.26, and back to the 5 x 10 passes by 0.32
    (noise of 0.5 mean edge lengths, which the short filter leaves behind):
    the narrow passes smoothed that detail away (Bunny0.2's clean scan at
    0.3: 7.90 degrees against 6.14). From 3.5 to 5 degrees of coarseness the schedule moves to
    broad and short (2 + t rounds of 2 + t passes, sigma_r 0.8 - 0.1 t).
    Coarse meshes without creases (weight ``o = w (1 - w_sharp)``) move
    further, to the organic end, a plain bilateral filter: 2 rounds of 2
    passes, sigma_r 1, a spatial kernel of 2 centroid spacings, and guidance
    normals blended with the normals themselves by ``o`` (``guidance_mix``;
    1 is the plain bilateral filter).

    Returns
    -------
    dict with ``outer_iterations``, ``normal_iterations``, ``sigma_r``,
    ``spatial_scale`` (sigma_s in centroid spacings), ``guidance_mix``,
    ``coarse_weight`` (the weight of the broad and short branch, 0 on finely
    meshed surfaces, 1 on coarse ones) and ``narrow_weight`` (the share of
    the strong schedule's last-round narrow guided passes and second fit,
    :class:`FilterPlan`: 1 on finely meshed surfaces, fading to 0 as the
    organic end takes over and as the coarseness weight goes from 0.25 to
    0.5; switched off at once they had made results up to 0.9 degrees better
    for more noise). The counts of rounds and passes are whole numbers, so
    the result still steps where they change (fertility upsampled four times
    at 0.33 and 0.34 mean edge lengths: 6.17 and 5.38 degrees, 2 x 2 passes
    then 3 x 3).
    """
    w = float(np.clip((coarseness_deg - 3.5) / 1.5, 0.0, 1.0))
    w_sharp = float(np.clip((tail_ratio - 9.5) / 1.5, 0.0, 1.0))
    low = 0.18 - 0.02 * w_sharp
    if rough < low:
        return light_schedule(rough, w, w_sharp, low)
    t = float(np.clip((rough - low) / (0.205 - low), 0.0, 1.0))
    organic = (2, 2, 1.0)
    start = [(1 - w_sharp) * a + w_sharp * b for a, b in zip((2, 2, 0.5), (3, 5, 0.35), strict=True)]
    # the strong end: many narrow passes where creases may survive or the surface is
    # plainly smooth (a sphere's tail ratio is 3 to 4), the organic filter on surfaces
    # with fine detail of their own (scans: tail ratio 5 to 8)
    # up to noise of about 0.3 mean edge lengths (roughness 0.26; at 0.5, 0.33 and up,
    # the short filter leaves too much of it)
    w_smooth = float(np.clip(min(tail_ratio - 4.0, (9.5 - tail_ratio) / 1.5), 0.0, 1.0))
    w_smooth *= float(np.clip((0.32 - rough) / 0.06, 0.0, 1.0))
    end = [w_smooth * a + (1 - w_smooth) * b for a, b in zip(organic, (5, 10, 0.3), strict=True)]
    fine = [(1 - t) * a + t * b for a, b in zip(start, end, strict=True)]
    coarse = (2 + t, 2 + t, 0.8 - 0.1 * t)
    base = tuple((1 - w) * a + w * b for a, b in zip(fine, coarse, strict=True))
    base = (round(base[0]), round(base[1]), base[2])
    o = w * (1.0 - w_sharp)
    mix = [(1 - o) * a + o * b for a, b in zip(base, organic, strict=True)]
    # the broad kernel and plain bilateral filter of the organic end, reached by
    # coarse smooth meshes (o) and by finely meshed smooth ones at strong noise (t)
    broad = o + (1.0 - o) * t * w_smooth
    return {"outer_iterations": int(round(mix[0])), "normal_iterations": int(round(mix[1])),
            "sigma_r": mix[2], "spatial_scale": 1.0 + broad, "guidance_mix": broad, "coarse_weight": w,
            "narrow_weight": (1.0 - w_smooth) * float(np.clip((0.5 - w) / 0.25, 0.0, 1.0))}


@dataclass(frozen=True)
class FilterPlan:
    """What :func:`filter_and_fit` runs: the parameters :func:`denoise_mesh`
    settles from :class:`DenoiseParams` and :func:`default_schedule`.

    Attributes
    ----------
    outer_iterations, normal_iterations : int
        Rounds, and filter passes per round.
    sigma_r : float
        Range kernel width (chord length).
    spatial_scale : float
        Spatial kernel width in mean centroid spacings.
    guidance_mix : float
        ``guided`` only: guidance blended with the normals (1: the plain bilateral filter).
    strong : bool
        End with the crease repair of the automatic schedule at strong noise.
    narrow_weight : float
        With ``strong``, on a finely meshed surface: the last round first
        runs the narrow guided passes and a second fit, their normals blended
        into the round's and the second fit's positions into the first's by
        this weight (1: taken as they are; 0: neither is run).
    """

    outer_iterations: int
    normal_iterations: int
    sigma_r: float
    spatial_scale: float
    guidance_mix: float = 0.0
    strong: bool = False
    narrow_weight: float = 0.0


# faces whose height is below this fraction of their longest edge, in the surface
# (projected onto the smoothed normals), are slivers (see :func:`smoothed_shape`);
# a regular face is near sqrt(3)/2 ~ 0.87
SLIVER_ASPECT = 0.1
# slivers are handled only when they are more than this share of the faces: noise
# alone turns a few regular faces far enough that their projection is thin (up to
# 1.8 % of the benchmark inputs' faces at 0.5 mean edge lengths, most of them not
# slivers in the clean mesh), and freeing those from the fold guard cost new flips
# (on the elephant animation 84 against 70 over 29 frames)
SLIVER_SHARE = 0.05


@dataclass(frozen=True)
class SmoothedShape:
    """What a plain smoothing of the input tells about its shape (:func:`smoothed_shape`).

    Attributes
    ----------
    coarseness_deg : float
        Median dihedral angle in degrees left after the smoothing: the
        curvature per edge that the mesh keeps once the noise is gone.
    tail_ratio : float
        99th percentile of those angles over the median: large where creases
        survive the smoothing, small on smooth curved surfaces.
    sliver : (m,) bool
        Faces whose height is below ``SLIVER_ASPECT`` of their longest edge,
        the input face projected onto the plane of its smoothed normal, when
        they are more than ``SLIVER_SHARE`` of the faces; none otherwise.
    crease_share : float
        The share of those angles above :data:`CREASE_SHARE_ANGLE` times the
        median: the edges that creases keep sharp (see :func:`schedule_tail_ratio`).
    """

    coarseness_deg: float
    tail_ratio: float
    sliver: np.ndarray
    crease_share: float = 0.0


CREASE_SHARE_ANGLE = 5.0
CREASE_SHARE_RAMP = (0.115, 0.145)
"""A mesh counts as creased as :attr:`SmoothedShape.crease_share` goes over this
range, whatever its tail ratio (:func:`schedule_tail_ratio`)."""


def schedule_tail_ratio(shape: SmoothedShape) -> float:
    """The tail ratio :func:`default_schedule` reads: the measured one, raised to
    the creased end (9.5 to 11) as the crease share goes over
    :data:`CREASE_SHARE_RAMP`. On a small mesh with creases, the 99th percentile
    falls among crease edges that the smoothing blurred, and the tail ratio
    swung with the noise's draw: the 768-face cube fixture at 0.3 mean edge
    lengths read 9.04 to 10.37 over perturb seeds 1 to 8, between the
    calibrations, and ended anywhere from 2.35 to 15.97 degrees. Its crease
    share reads 0.15 to 0.22; on the smooth organic benchmark meshes (scans
    and the coarse models) at most 0.047, on Twelve0.5Impulsive and the cube at
    0.5 (tail ratios 10.98 and 10.89) 0.101 and 0.104."""
    lo, hi = CREASE_SHARE_RAMP
    ramp = float(np.clip((shape.crease_share - lo) / (hi - lo), 0.0, 1.0))
    return max(shape.tail_ratio, 9.5 + 1.5 * ramp) if ramp > 0 else shape.tail_ratio


def smoothed_shape(V: np.ndarray, F: np.ndarray, connectivity: FaceConnectivity | None = None) -> SmoothedShape:
    """Dihedral angles and slivers left after a plain smoothing (bilateral
    normal filter with a broad range kernel, 2 rounds of 3 passes).

    ``connectivity`` is :func:`geoproc.denoise.connectivity.face_connectivity`
    of F (built here when not given); the angles are measured on its
    consistently turned faces, and ``sliver`` is in its face order.

    Slivers are judged in the surface: each input face projected onto the
    plane normal to its filtered normal. Noise along the normals turns a
    needle into a fat triangle in space, but its projection stays a needle
    (the smoothed faces themselves keep about half of a noisy needle's
    height, and showed only half of the needles). The angle statistics leave
    out the edges of slivers: a needle's normal turns with any error in its
    short side, so on a noisy fandisk with 15 % of its edges split near an
    end (a third of its faces needles) they had taken the median from 1.7 to
    6.0 degrees, and the schedule for a coarse mesh blurred its creases.
    """
    conn = face_connectivity(F, len(V)) if connectivity is None else connectivity
    enb = conn.edge_nb
    plain = FilterPlan(outer_iterations=2, normal_iterations=3, sigma_r=1.0, spatial_scale=1.0)
    r = filter_and_fit(V, conn, "bilateral", DenoiseParams(features="none"), plain)
    sliver = face_aspect(V, conn.F, r.normals) < SLIVER_ASPECT
    if not sliver.mean() > SLIVER_SHARE:
        sliver[:] = False
    # faces on a line (T-junction fillers) have their neighbours' normal, not one of their own:
    # ten of them on a noisy cube of 768 faces moved the tail ratio across the organic ramp
    # (9.40 -> 9.00), and the broad schedule that followed left theta at 13.7 degrees, not 3.0
    skip = sliver | collinear_faces(V, conn.F)
    i, k = np.nonzero(enb >= 0)  # the order of edge_dihedral_deg's angles
    ang = edge_dihedral_deg(r.V, conn.F, enb)[~skip[i] & ~skip[enb[i, k]]]
    if len(ang) == 0:
        return SmoothedShape(0.0, 0.0, sliver)
    med = float(np.median(ang))
    return SmoothedShape(med, float(np.percentile(ang, 99) / max(med, 1e-9)), sliver,
                         float((ang > CREASE_SHARE_ANGLE * med).mean()))


@dataclass
class DenoiseResult:
    """Output of :func:`denoise_mesh`.

    Attributes
    ----------
    V : (n, 3) float64 denoised positions.
    normals : (m, 3) float64 filtered face normals of the last round.
    feature : (m,) float64 1.0 on feature faces, else 0.0 (see ``DenoiseParams.features``).
    info : dict of scalars (noise estimate, parameters used).
    """

    V: np.ndarray
    normals: np.ndarray
    feature: np.ndarray
    info: dict = field(default_factory=dict)


def blend_guidance(G: np.ndarray, N: np.ndarray, mix: float) -> np.ndarray:
    """(m, 3) unit normals ``normalize((1 - mix) G + mix N)``: guidance normals G
    moved towards the filtered normals N (mix 1: the plain bilateral filter)."""
    if mix <= 0.0:
        return G
    B = (1.0 - mix) * G + mix * N
    return B / np.maximum(np.linalg.norm(B, axis=1, keepdims=True), 1e-300)


SPARSE_ROW = 1e-3
"""Length of a face's row of S (a difference of unit normals) above which the
report's ``rpca_sparse_faces`` counts the face: RPCA's iterations leave most
rows a little above zero."""


def rpca_guidance(G: np.ndarray, patch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clean guidance normals with RPCA on the patch matrices.

    For every face, the (k, 3) matrix of the guidance normals of its k nearest
    patch faces (itself first) is split into ``P + S``; the face's row of P is
    its new guidance, and the norm of its row of S its sparse (feature/outlier)
    residual. Each matrix is split in the principal axes of its normals (the
    eigenvectors of ``sum n n^T``): RPCA's sparse term is entrywise, and in
    world axes a generic rotation of the mesh moved fandisk's result by 7e-3
    of its diagonal and changed 127 feature flags.

    Parameters
    ----------
    G : (m, 3) unit guidance normals; patch : (m, k) face indices, column 0 the face.

    Returns
    -------
    guidance : (m, 3) unit normals; sparse : (m,) norm of the face's row of S.
    """
    D = G[patch]  # (m, k, 3)
    _, R = np.linalg.eigh(np.einsum("mki,mkj->mij", D, D))  # columns: the axes, which turn with the mesh
    res = rpca(np.einsum("mkc,mcd->mkd", D, R), tol=1e-7, max_iter=200)
    row = np.einsum("mcd,md->mc", R, res.P[:, 0, :])
    norm = np.linalg.norm(row, axis=1)
    ok = norm > 1e-12
    out = G.copy()
    out[ok] = row[ok] / norm[ok, None]
    return out, np.linalg.norm(res.S[:, 0, :], axis=1)


def denoise_mesh(
    V: np.ndarray,
    F: np.ndarray,
    method: str = DEFAULT_METHOD,
    params: DenoiseParams | None = None,
    progress: Callable[[float], None] | None = None,
    initial_normals: np.ndarray | None = None,
    connectivity: FaceConnectivity | None = None,
) -> DenoiseResult:
    """Denoise a triangle mesh while keeping its sharp features.

    Parameters
    ----------
    V : (n, 3) float64 noisy positions; F : (m, 3) int64 triangles (edge-manifold).
    method : {"bilateral", "guided", "rpca"}
    params : DenoiseParams, optional
        Unset entries are chosen from the estimated noise level
        (:func:`geoproc.denoise.noise_level.roughness`, :func:`default_schedule`).
    progress : callable, optional
        Called with the fraction done: after the noise and shape estimates
        (:data:`ESTIMATE_SHARE`; a third of the time on a 690k-vertex scan),
        then after every filter pass and every vertex fit.
    initial_normals : (m, 3) float64, optional
        Start the first round from these unit normals instead of the input's
        face normals (the dynamic method passes its temporally coherent normals).
    connectivity : FaceConnectivity, optional
        :func:`geoproc.denoise.connectivity.face_connectivity` of F, when the
        caller has it (the frames of an animation share it); built here otherwise.

    Returns
    -------
    DenoiseResult
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}")
    p = DenoiseParams() if params is None else params
    if p.features not in FEATURE_METHODS:
        raise ValueError(f"unknown feature method {p.features!r}")
    V, F = mesh_arrays(V, F)
    repeated = repeated_corner_faces(F)
    if repeated.any():  # no area and no normal: left out of the filter and the fit
        return _without_repeated_corner_faces(V, F, repeated, method, params, progress, initial_normals)
    groups = scale_groups(V, F)
    if groups.max(initial=0) > 0:  # parts meshed at very different scales: each group on its own
        return _by_scale_group(V, F, groups, method, params, progress, initial_normals)
    # T-junction fillers rounded off their segments by the file (pinned boundary vertices stay),
    # judged for each scale group on its own: the whole mesh's rounding, within its limit of the
    # large part's edges, had flattened faces of a part at 1/1000 scale that alone it leaves
    pinned = None
    if p.pin_boundary:
        pinned = np.zeros(len(V), dtype=bool)
        pinned[boundary_vertices(F)] = True
    V = on_segments_as_stored(V, F, pinned)
    if connectivity is None:
        connectivity = face_connectivity(F, len(V))
    elif not connectivity.matches(F, len(V)):
        raise ValueError("connectivity was built from other faces or another vertex count")
    flip = connectivity.flip
    if initial_normals is not None and flip.any():
        initial_normals = np.where(flip[:, None], -initial_normals, initial_normals)
    # everything below runs with faces and vertices renumbered along a space-filling
    # curve (their neighbours close in memory); the result is put back in the input's order
    vo, fo, conn = connectivity.work_order(V)
    Vw = V[vo]
    noise_deg = median_dihedral_deg(Vw, conn.F, conn.edge_nb)
    rough = roughness(Vw, conn.F, conn.edge_nb)
    shape = smoothed_shape(Vw, conn.F, conn) if rough >= 0.03 else None
    # measured whenever the shape is (for the slivers): with --rounds, --normal-iterations and
    # --sigma-r all given they had read 0 and none, and the default --sigma-s ignored them
    coarse, tail = (0.0, np.inf) if shape is None else (shape.coarseness_deg, shape.tail_ratio)
    sched = default_schedule(rough, coarse, np.inf if shape is None else schedule_tail_ratio(shape))
    # guided at strong noise: the last round repairs faces the fit squashed against a
    # crease; on finely meshed surfaces (the narrow-kernel branch) it first adds narrow
    # guided passes and a second fit. The guidance mix and this repair follow the input
    # whatever schedule is given: with --rounds, --normal-iterations and --sigma-r all
    # given they had been off, so the values a report records did not give its run back
    guided = method == "guided"
    strong = guided and rough >= STRONG_ROUGHNESS if p.crease_repair is None else p.crease_repair
    mix = (sched["guidance_mix"] if guided else 0.0) if p.guidance_mix is None else p.guidance_mix
    plan = FilterPlan(
        outer_iterations=sched["outer_iterations"] if p.outer_iterations is None else p.outer_iterations,
        normal_iterations=sched["normal_iterations"] if p.normal_iterations is None else p.normal_iterations,
        sigma_r=sched["sigma_r"] if p.sigma_r is None else p.sigma_r,
        spatial_scale=sched["spatial_scale"] if p.sigma_s_scale is None else p.sigma_s_scale,
        guidance_mix=mix,
        strong=strong, narrow_weight=sched["narrow_weight"])
    rounds_progress = None
    if progress is not None:
        progress(ESTIMATE_SHARE)

        def rounds_progress(done: float) -> None:
            progress(ESTIMATE_SHARE + (1.0 - ESTIMATE_SHARE) * done)
    res = filter_and_fit(Vw, conn, method, p, plan, rounds_progress,
                         None if initial_normals is None else np.asarray(initial_normals)[fo],
                         sliver=None if shape is None else shape.sliver)
    res.V = res.V[inverse_permutation(vo)]
    inv_fo = inverse_permutation(fo)
    res.normals, res.feature = res.normals[inv_fo], res.feature[inv_fo]
    res.info = {"noise_median_dihedral_deg": noise_deg, "noise_roughness": rough,
                "coarseness_deg": None if shape is None else coarse,  # (not measured on a clean mesh)
                "dihedral_tail_ratio": tail if np.isfinite(tail) else None, "reoriented_faces": int(flip.sum()),
                "sliver_faces": 0 if shape is None else int(shape.sliver.sum()), "repeated_corner_faces": 0,
                "scale_groups": 1, **res.info}
    if flip.any():  # the normals back in the input's face orientation
        res.normals = np.where(flip[:, None], -res.normals, res.normals)
    return res


def _by_scale_group(V, F, groups, method, params, progress, initial_normals) -> DenoiseResult:
    """:func:`denoise_mesh` of each group of parts (:func:`~geoproc.denoise.scale_groups.scale_groups`)
    on its own, each with the schedule its own noise gives. The info is the
    largest group's (by faces) among those that were filtered (any group's
    when none was), with the counts of faces and vertices summed over the
    groups and ``scale_groups`` the number of groups."""
    m = len(F)
    V_out, normals, feature = V.copy(), np.zeros((m, 3)), np.zeros(m)
    infos, done = [], 0.0
    for g in range(int(groups.max()) + 1):
        fg = np.flatnonzero(groups == g)
        Vg, Fg, vg = remove_unreferenced_vertices(V, F[fg])
        share = len(fg) / m
        sub_progress = None if progress is None else (lambda x, a=done, w=share: progress(a + w * x))
        res = denoise_mesh(Vg, Fg, method, params, sub_progress,
                           None if initial_normals is None else np.asarray(initial_normals)[fg])
        V_out[vg], normals[fg], feature[fg] = res.V, res.normals, res.feature
        infos.append(res.info)
        done += share
    sizes = np.bincount(groups)
    filtered = np.array([bool(i.get("outer_iterations")) for i in infos])
    if filtered.any():  # the schedule of a group that was filtered: a clean largest one read as "nothing ran"
        sizes = np.where(filtered, sizes, -1)
    info = dict(infos[int(np.argmax(sizes))])
    for key, value in info.items():  # counts of faces and vertices over the whole mesh
        if key.endswith(("_faces", "_vertices")) and isinstance(value, int | np.integer):
            info[key] = int(sum(i.get(key) or 0 for i in infos))
    info["scale_groups"] = len(infos)
    return DenoiseResult(V_out, normals, feature.astype(res.feature.dtype), info)


def _without_repeated_corner_faces(V, F, repeated, method, params, progress, initial_normals) -> DenoiseResult:
    """:func:`denoise_mesh` of the faces that do not repeat a corner; the others
    (a collapsed edge's faces, once coincident vertices are merged) get a zero
    normal and feature 0. They had made the whole mesh refused as not
    edge-manifold."""
    keep = ~repeated
    res = denoise_mesh(V, F[keep], method, params, progress,
                       None if initial_normals is None else np.asarray(initial_normals)[keep])
    normals = np.zeros((len(F), 3))
    normals[keep] = res.normals
    feature = np.zeros(len(F), dtype=np.asarray(res.feature).dtype)
    feature[keep] = res.feature
    res.normals, res.feature = normals, feature
    res.info["repeated_corner_faces"] = int(repeated.sum())
    return res


def filter_and_fit(
    V: np.ndarray,
    conn: FaceConnectivity,
    method: str,
    p: DenoiseParams,
    plan: FilterPlan,
    progress: Callable[[float], None] | None = None,
    initial_normals: np.ndarray | None = None,
    sliver: np.ndarray | None = None,
) -> DenoiseResult:
    """The rounds of :func:`denoise_mesh` once its parameters are settled.

    Parameters
    ----------
    V : (n, 3) float64 positions.
    conn : FaceConnectivity
        :func:`geoproc.denoise.connectivity.face_connectivity` of the faces;
        the filter works on its consistently turned faces ``conn.F``.
    method : {"bilateral", "guided", "rpca"}
    p : DenoiseParams
        Read for what the plan does not hold: vertex sweeps and fidelity, boundary
        pinning, patch size, fold repair, input-side step, features.
    plan : FilterPlan
    progress, initial_normals : as for :func:`denoise_mesh`.
    sliver : (m,) bool, optional
        Faces whose input normal the fold guard does not keep
        (:attr:`SmoothedShape.sliver`). The guard keeps every other face within
        90 degrees of its input normal, so that a wrong target at a crease
        cannot fold it; a sliver's input normal is set by the noise alone (a
        needle turns with any error in its short side), and holding slivers to
        it froze their vertices: on a noisy fandisk with 15 % of its edges
        split near an end the positions kept most of their noise.

    Returns
    -------
    DenoiseResult whose ``info`` holds the parameters used (not the input's
    noise statistics, which :func:`denoise_mesh` adds).
    """
    n = len(V)
    outer, inner, sigma_r = plan.outer_iterations, plan.normal_iterations, plan.sigma_r
    mix, strong = plan.guidance_mix, plan.strong
    fine = strong and plan.narrow_weight > 0.0
    F, edge_nb, ring = conn.F, conn.edge_nb, conn.ring
    fixed = None
    if p.pin_boundary:
        on_boundary = boundary_vertices(F)
        if len(on_boundary):
            fixed = np.zeros(n, dtype=bool)
            fixed[on_boundary] = True
    X = np.array(V, dtype=np.float64, copy=True)
    N, A = face_normals_and_areas(X, F)
    N_input, A_input = N.copy(), A.copy()

    middles = collinear_middles(X, F)  # T-junction fillers: their middle corner stays on its segment

    def fit(X, N):
        keep = N_input if sliver is None else np.where(sliver[:, None], N, N_input)
        X = update_vertices(X, F, N, p.vertex_iterations, fixed=fixed, keep_orientation=keep,
                            anchor=V, fidelity=p.fidelity)
        folded = 0
        if p.unfold_rounds > 0:
            X, folded = unfold_faces(X, F, N, edge_nb, fixed, keep, p.unfold_rounds)
        return keep_on_segments(X, middles, fixed), folded

    if initial_normals is not None:
        N = np.asarray(initial_normals, dtype=np.float64)
    C = face_centroids(X, F)
    i, k = np.nonzero(edge_nb >= 0)
    spacing = float(np.linalg.norm(C[i] - C[edge_nb[i, k]], axis=1).mean()) if len(i) else 1.0
    sigma_s = plan.spatial_scale * spacing
    if not spacing > 0:  # every pair of edge-adjacent faces shares its centroid
        raise InputError(None, "edge-adjacent faces have coincident centroids (mean centroid spacing 0): "
                               "the faces coincide, there is no spatial scale to filter over")
    if not sigma_s > 1e-150:  # a width whose square underflows
        raise UsageError(f"spatial kernel width {sigma_s:.3g} (--sigma-s {plan.spatial_scale:.3g} x centroid "
                         f"spacing {spacing:.3g}) is too small: its square underflows")
    patch = nearest_faces_in_ring(C, ring, p.patch_size) if method == "rpca" else None
    # guidance blended away entirely (mix 1) is the plain bilateral filter: no guidance to compute
    plain = method == "bilateral" or mix >= 1.0
    inside = None if plain else conn.inside
    total = max(outer * (inner + 1), 1)  # a round's vertex fit counts as one pass
    done = 0
    sparse = np.zeros(len(F))
    folded = 0
    changed = np.zeros(len(F), dtype=bool)
    sided = np.zeros(len(F), dtype=bool)
    for o in range(outer):
        if o:
            N, A = face_normals_and_areas(X, F)
            C = face_centroids(X, F)
        W = spatial_weights(C, A, ring, sigma_s)
        if method == "rpca":
            G_round, sparse = rpca_guidance(guidance_normals(N, A, ring, edge_nb, inside), patch)
        for _ in range(inner):
            if plain:
                G = None
            elif method == "rpca":
                G = G_round
            else:
                G = blend_guidance(guidance_normals(N, A, ring, edge_nb, inside), N, mix)
            N = bilateral_normal_filter(N, C, A, ring, sigma_s, sigma_r, G, spatial=W)
            done += 1
            if progress is not None:
                progress(done / total)
        last = o == outer - 1
        if last and fine:
            Nf = N
            for _ in range(FINE_FINAL_PASSES):
                G = guidance_normals(Nf, A, ring, edge_nb, inside)
                Nf = bilateral_normal_filter(Nf, C, A, ring, sigma_s, FINE_FINAL_SIGMA_R, G, spatial=W)
            N = Nf if plan.narrow_weight >= 1.0 else blend_guidance(Nf, N, 1.0 - plan.narrow_weight)
        if last and strong:
            X, folded = fit(X, N)
            if fine:
                X2, folded = fit(X, N)
                X = X2 if plan.narrow_weight >= 1.0 else X + plan.narrow_weight * (X2 - X)
            N, changed = bisect_collapsed_targets(X, F, N, A_input, edge_nb)
        if last and p.input_side:
            N, sided = input_side_targets(N, N_input, ring)
        X, folded = fit(X, N)
        done += 1
        if progress is not None:
            progress(done / total)
    # values that did not act are None (left out of a report): the filter's when no pass
    # ran, the vertex fit's when no round ran (a clean mesh had reported sigma_r 0.1); the
    # last round's narrow passes use sigma_s but their own sigma_r and pure guidance, so with
    # --normal-iterations 0 those two did not act (they had been reported)
    scheduled = outer > 0 and inner > 0
    filtered = scheduled or (outer > 0 and fine)
    fitted = outer > 0
    info = {
        "guidance_mix": mix if scheduled else None,
        "outer_iterations": outer,
        "normal_iterations": inner if outer > 0 else None,
        "vertex_iterations": p.vertex_iterations if fitted else None,
        "fidelity": p.fidelity if fitted and p.vertex_iterations > 0 else None,  # (it acts in the sweeps)
        "sigma_r": sigma_r if scheduled else None,
        "sigma_s": plan.spatial_scale if filtered else None,  # in centroid spacings, the unit of --sigma-s
        "sigma_s_length": sigma_s if filtered else None,
        "unfold_rounds": p.unfold_rounds if fitted else None,
        "folded_faces": folded,
        "crease_repair": bool(strong) and outer > 0,  # it runs in the last round
        "crease_bisected_faces": int(changed.sum()),
        "input_side_faces": int(sided.sum()),
    }
    if p.features == "l1":
        feature, fres = l1_feature_faces(X, F, tau=p.feature_tau)
        info.update({"feature_method": "l1", "feature_lambda": fres.lam, "feature_tau": fres.tau,
                     "feature_vertices": int(fres.feature.sum()), "feature_admm_iterations": fres.iterations})
    elif p.features == "dihedral":
        feature = dihedral_feature_faces(N, edge_nb, p.feature_angle_deg)
        info.update({"feature_method": "dihedral", "feature_angle_deg": p.feature_angle_deg})
    else:
        feature = np.zeros(len(F))
    if method == "rpca":
        info["rpca_sparse_faces"] = int((sparse > SPARSE_ROW).sum())
    if method != "guided":  # the others blend no guidance
        del info["guidance_mix"]
    return DenoiseResult(V=X, normals=N, feature=feature, info=info)
