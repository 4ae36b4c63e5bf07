"""Which metrics a run reports is known from its options before any input is
read: for every mode of ``denoise`` and every method (and log-ode solver) of
``geodesic``, the metrics a real run reports and the metrics a ``--check``
is refused on up front are complements within the command's ``METRICS``,
save those that depend on the input's content."""

from __future__ import annotations

import json

import numpy as np
import pytest

from geoproc.mesh import Mesh, load_mesh, save_mesh
from geoproc_cli import denoise, geodesic
from tests.cli.test_metric_names import _gated

# the 'outlier' property of the input decides these; no option does
NEEDS_OUTLIER_PROPERTY = {"precision", "recall", "f1", "true_outliers"}


def _reported(cli, command, *args, tmp_path):
    rep = tmp_path / "r.json"
    p = cli(command, *args, "--report", rep, "-q")
    assert p.returncode == 0, p.stderr
    return set(json.loads(rep.read_text())["metrics"])


GEODESIC_RUNS = [("exact", "lu"), ("heat", "lu"), ("varadhan", "lu"), ("log-heat", "lu"),
                 ("log-ode", "lu"), ("log-ode", "newton"), ("log-ode", "cvxpy"), ("log-splitting", "lu")]


@pytest.mark.parametrize("method,solver", GEODESIC_RUNS)
def test_geodesic_reports_exactly_the_metrics_its_options_allow(cli, fixture_dir, tmp_path, method, solver):
    if method == "log-splitting":
        pytest.importorskip("clarabel", reason="log-splitting needs clarabel (the test extra)")
    if solver == "cvxpy":
        pytest.importorskip("cvxpy", reason="--solver cvxpy needs cvxpy (the test extra)")
    extra = ["--solver", solver] if method == "log-ode" else []
    reported = _reported(cli, "geodesic", fixture_dir / "icosphere.ply", "-s", "0", "-m", method, *extra,
                         "--reference", "exact", "-o", tmp_path / "d.ply", tmp_path=tmp_path)
    gated = _gated(geodesic._metric_needs(method, solver, "exact"))
    assert reported & gated == set()
    assert set(geodesic.METRICS) - reported - gated == set()
    # without --reference its metrics are gated too, and still none the run reports
    assert _gated(geodesic._metric_needs(method, solver, None)) - gated == set(geodesic.REFERENCE_METRICS)


@pytest.fixture(scope="module")
def denoise_inputs(make_fixtures, tmp_path_factory):
    """A noisy sphere with its clean copy, a cloud with an 'outlier' property, and
    an animation of the sphere (clean and noisy)."""
    d = tmp_path_factory.mktemp("gates")
    V, F = make_fixtures.icosphere(2)
    rng = np.random.default_rng(0)
    save_mesh(d / "clean.ply", Mesh(V, F))
    save_mesh(d / "noisy.ply", Mesh(V + 0.01 * rng.standard_normal(V.shape), F))
    P = rng.standard_normal((400, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    flag = np.zeros(len(P))
    flag[:40] = 1
    P[:40] *= 1.3
    save_mesh(d / "cloud.ply", Mesh(P, np.zeros((0, 3), int), {"outlier": flag}))
    frames = np.stack([V * (1 + 0.1 * t) for t in range(4)])
    np.savez(d / "anim.npz", vertices=frames, faces=F)
    noisy = frames + 0.01 * rng.standard_normal(frames.shape)
    np.savez(d / "anim_noisy.npz", vertices=noisy, faces=F)
    moved = np.zeros(frames.shape[:2])
    moved[:, :10] = 1
    noisy[:, :10] *= 1.3
    np.savez(d / "anim_outliers.npz", vertices=noisy, faces=F, outlier=moved)
    return d


DENOISE_RUNS = [
    # (mode, method, features, refined, with reference, input, extra options)
    (denoise.MESH, "guided", "dihedral", False, False, "noisy.ply", []),
    (denoise.MESH, "rpca", "l1", False, True, "noisy.ply", ["--method", "rpca", "--features", "l1"]),
    (denoise.MESH, "bilateral", "dihedral", False, True, "noisy.ply", ["--method", "bilateral", "--rounds", "0"]),
    (denoise.CLOUD, "guided", "dihedral", False, False, "cloud.ply", ["--outliers"]),
    (denoise.CLOUD, "guided", "dihedral", True, False, "cloud.ply", ["--outliers", "--refined"]),
    (denoise.MOVING_CLOUD, "guided", "dihedral", True, False, "anim_outliers.npz", ["--outliers", "--refined"]),
    (denoise.DYNAMIC, "guided", "dihedral", False, False, "anim_noisy.npz", ["--dynamic"]),
    (denoise.DYNAMIC, "guided", "dihedral", False, True, "anim_noisy.npz", ["--dynamic"]),
]


@pytest.mark.parametrize("mode,method,features,refined,with_reference,name,extra", DENOISE_RUNS)
def test_denoise_reports_exactly_the_metrics_its_options_allow(cli, denoise_inputs, tmp_path, mode, method,
                                                               features, refined, with_reference, name, extra):
    src = denoise_inputs / name
    animation = name.endswith(".npz")
    assert denoise.denoise_mode(str(src), "--outliers" in extra, "--dynamic" in extra) == mode
    reference = str(denoise_inputs / ("anim.npz" if animation else "clean.ply")) if with_reference else None
    args = [*extra, *(["--reference", reference] if reference else [])]
    reported = _reported(cli, "denoise", src, *args, "-o", tmp_path / ("o.npz" if animation else "o.ply"),
                         tmp_path=tmp_path)
    gated = _gated(denoise._metric_needs(denoise.Choices(mode, method, features, refined, reference)))
    assert reported & gated == set()
    assert set(denoise.METRICS) - reported - gated == set()
    if mode == denoise.CLOUD:  # the same cloud without its 'outlier' property: only those four go
        plain = tmp_path / "plain.ply"
        save_mesh(plain, Mesh(load_mesh(src, clean=False).V, np.zeros((0, 3), int)))
        bare = _reported(cli, "denoise", plain, *args, "-o", tmp_path / "p.ply", tmp_path=tmp_path)
        assert reported - bare == NEEDS_OUTLIER_PROPERTY

