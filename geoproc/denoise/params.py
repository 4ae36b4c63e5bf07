"""Parameters of :func:`geoproc.denoise.mesh_denoise.denoise_mesh`.

A module of its own, free of numerical code, so that the command line can
check and hold its options before it loads the filters.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class DenoiseParams:
    """Parameters of :func:`geoproc.denoise.mesh_denoise.denoise_mesh` (None: chosen from the mesh).

    Attributes
    ----------
    outer_iterations : int
        Rounds of (normal filtering, vertex update).
    normal_iterations : int
        Filter passes per round.
    vertex_iterations : int
        Vertex-update sweeps per round.
    sigma_r : float
        Range kernel width on normal differences (chord length, 0..2).
    sigma_s_scale : float
        Spatial kernel width as a multiple of the mean distance between the
        centroids of edge-adjacent faces (None: from the schedule, 1 to 2).
    pin_boundary : bool
        Keep boundary vertices fixed.
    patch_size : int
        Faces per patch in the RPCA matrices (``rpca`` only).
    features : {"l1", "dihedral", "none"}
        How the per-face ``feature`` output is found: ``dihedral`` (default)
        where the filtered normal differs from an edge neighbour's by more than
        ``feature_angle_deg``; ``l1`` from the support of the l1-sparse normal
        Laplacian of the result (:func:`geoproc.denoise.features.l1_feature_vertices`,
        faces with two feature vertices; its F1 against the clean creases of
        the benchmark pairs is lower on SharpSphere0.3 and Bunny0.2 and about
        equal elsewhere, see ``bench/denoise_features.py``); ``none``: all 0
        (callers that need only the positions).
    feature_tau : float
        ``l1``: cut on the sparse normal Laplacian, in local mean edge lengths.
    feature_angle_deg : float
        ``dihedral``: the angle in degrees.
    unfold_rounds : int
        After each round's vertex update, at most this many umbrella
        relaxations of the vertices of folded faces
        (:func:`geoproc.denoise.vertex_update.unfold_faces`); 0 turns the
        repair off.
    fidelity : float
        Data term of the vertex update: every sweep also pulls each vertex
        by this fraction of its distance back towards its input position
        (:func:`geoproc.denoise.vertex_update.update_vertices`). Faces the fit
        would squash between the two sides of a crease keep more of their
        shape; 0 is the plain fit of Sun et al.
    input_side : bool
        Before the last fit, a face whose target is more than 90 degrees from
        its own input normal takes the neighbourhood target closest to that
        normal, when one lies within 90 degrees
        (:func:`geoproc.denoise.crease_targets.input_side_targets`): the
        filter had put it on the far side of a crease sharper than a right
        angle.
    guidance_mix : float
        ``guided`` only: each pass's guidance is the patch guidance blended with
        the normals themselves by this weight (0: the patch guidance alone, as
        Zhang et al.; 1: the normals, the plain bilateral filter). None: from
        the noise level and the mesh's shape (:func:`default_schedule`).
    crease_repair : bool
        Before the last fit, repair the faces the fit squashed against a
        crease (:func:`geoproc.denoise.crease_targets.bisect_collapsed_targets`,
        after a first fit; on finely meshed surfaces also narrow guided passes
        and a second fit). None: with the ``guided`` method at strong noise
        (roughness at least 0.18).
    """

    outer_iterations: int | None = None
    normal_iterations: int | None = None
    vertex_iterations: int = 10
    sigma_r: float | None = None
    sigma_s_scale: float | None = None
    pin_boundary: bool = False
    patch_size: int = 10
    features: str = "dihedral"
    feature_tau: float = 0.12
    feature_angle_deg: float = 30.0
    unfold_rounds: int = 5
    fidelity: float = 0.005
    input_side: bool = True
    guidance_mix: float | None = None
    crease_repair: bool | None = None
