"""Every metric the library hands a subcommand is among the names the
subcommand declares (its ``METRICS``), on the paths the command-line tests do
not all take: every denoise method and feature rule, both dynamic
coherences, every geodesic method and every wos-solve method."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from geoproc.denoise import denoise_mesh
from geoproc.denoise.dynamic import denoise_animation
from geoproc.denoise.mesh_denoise import DenoiseParams
from geoproc.denoise.metrics import reference_metrics
from geoproc.denoise.outliers import detection_scores
from geoproc.geodesic.compare import compare_to_reference
from geoproc.geodesic.distance import METHODS as GEODESIC_METHODS
from geoproc.geodesic.distance import geodesic_distance
from geoproc.wos.domain import build_domain
from geoproc.wos.expression import parse_expression
from geoproc.wos.solve import METHODS as WOS_METHODS
from geoproc.wos.solve import solve_laplace
from geoproc_cli import denoise, geodesic, wos_solve
from tests.conftest import load_fixture_module


def _scalars(d: dict) -> set[str]:
    return {k for k, v in d.items() if np.isscalar(v) or v is None}


def _text(d: dict) -> set[str]:
    return {k for k, v in d.items() if isinstance(v, str)}


@pytest.mark.parametrize("method", ["bilateral", "guided", "rpca"])
@pytest.mark.parametrize("features", ["dihedral", "l1"])
def test_denoise_mesh_metrics_are_declared(method, features):
    Vn, F, V = load_fixture_module("denoise_fixtures").noisy_cube(n=4, sigma=0.3, seed=0)
    res = denoise_mesh(Vn, F, method, DenoiseParams(features=features))
    names = _scalars(res.info) | set(reference_metrics(res.V, Vn, F, V)) | set(detection_scores(
        np.array([True, False]), np.array([True, True])))
    assert names - set(denoise.METRICS) == set()
    assert _text(res.info) <= set(denoise.TEXT_METRICS)


@pytest.mark.parametrize("coherence", ["heights", "normals"])
def test_denoise_dynamic_metrics_are_declared(coherence):
    Vn, F, _ = load_fixture_module("denoise_fixtures").noisy_cube(n=3, sigma=0.3, seed=0)
    frames = np.stack([Vn * (1 + 0.01 * t) for t in range(3)])
    _, info = denoise_animation(frames, F, coherence=coherence)
    assert _scalars(info) - set(denoise.METRICS) == set()
    assert _text(info) <= set(denoise.TEXT_METRICS)


@pytest.mark.parametrize("method", GEODESIC_METHODS)
def test_geodesic_metrics_are_declared(method):
    if method == "log-splitting" and importlib.util.find_spec("clarabel") is None:
        pytest.skip("log-splitting needs clarabel (the test extra)")
    V, F = load_fixture_module().icosphere(1)
    res = geodesic_distance(V, F, [0], method, steps=1)
    names = _scalars(res.stats) | set(compare_to_reference(res.distance, res.distance))
    assert names - set(geodesic.METRICS) == set()
    assert _text(res.stats) <= set(geodesic.TEXT_METRICS)


@pytest.mark.parametrize("method", WOS_METHODS)
def test_wos_metrics_are_declared(method):
    square = build_domain([[[0, 0], [1, 0], [1, 1], [0, 1]]])
    res = solve_laplace(square, parse_expression("x"), method=method, walks=2, grid=6, kernels=4, fit_walks=2,
                        npass_steps=2, npass_batch=2, npass_walks=2, exact=True)
    assert set(res.metrics) - set(wos_solve.METRICS) == set()
    assert _text(res.metrics) == set()  # wos-solve declares no text metric


def _gated(needs: dict) -> set[str]:
    return {m for names in needs.values() for m in names}


@pytest.mark.parametrize("method", ["bilateral", "guided", "rpca"])
@pytest.mark.parametrize("features", ["dihedral", "l1"])
def test_denoise_checks_refused_early_are_not_reported_by_that_mode(method, features):
    # a --check on a metric the run's options cannot report is refused before the input is read;
    # the metrics the run does report must never be among those
    Vn, F, V = load_fixture_module("denoise_fixtures").noisy_cube(n=4, sigma=0.3, seed=0)
    res = denoise_mesh(Vn, F, method, DenoiseParams(features=features))
    reported = _scalars(res.info) | {"vertices", "faces"}
    mesh = denoise.Choices(denoise.MESH, method, features, False, None)
    assert reported & _gated(denoise._metric_needs(mesh)) == set()
    with_reference = reported | set(reference_metrics(res.V, Vn, F, V))
    assert with_reference & _gated(denoise._metric_needs(mesh._replace(reference="clean.ply"))) == set()
    frames = np.stack([Vn * (1 + 0.01 * t) for t in range(3)])
    for coherence in ("heights", "normals"):
        _, info = denoise_animation(frames, F, method, coherence=coherence, params=DenoiseParams(features=features))
        assert (_scalars(info) | {"frames", "vertices", "faces"}) & _gated(
            denoise._metric_needs(mesh._replace(mode=denoise.DYNAMIC))) == set()


def test_denoise_metric_groups_cover_every_metric_once():
    names = [m for _, _, group in denoise.MODE_METRICS for m in group]
    assert sorted(names) == sorted(denoise.METRICS) and len(names) == len(set(names))
    names = [m for _, _, group in geodesic.METHOD_METRICS for m in group]
    assert set(names) <= set(geodesic.METRICS) and len(names) == len(set(names))


@pytest.mark.parametrize("method", WOS_METHODS)
def test_wos_checks_refused_early_are_not_reported_by_that_method(method):
    square = build_domain([[[0, 0], [1, 0], [1, 1], [0, 1]]])
    res = solve_laplace(square, parse_expression("x"), method=method, walks=2, grid=6, kernels=4, fit_walks=2,
                        npass_steps=2, npass_batch=2, npass_walks=2, exact=True)
    assert set(res.metrics) & _gated(wos_solve._metric_needs(True, method)) == set()
    assert _gated(wos_solve._metric_needs(False, method)) <= set(wos_solve.METRICS)
    gated = _gated(wos_solve._metric_needs(False, method))
    assert ({"fit_seconds"} <= gated) == (method == "naive") and ({"refine_steps"} <= gated) == (method != "npass")
