"""RPCA (inexact ALM) against exactly known low-rank + sparse decompositions and
numpy's SVD."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.denoise.rpca import randomized_svd, rpca, shrink, svt


def _low_rank_plus_sparse(n, rank, density, seed, magnitude=5.0, shape=None):
    rng = np.random.default_rng(seed)
    p, q = shape or (n, n)
    L = rng.standard_normal((p, rank)) @ rng.standard_normal((rank, q))
    S = np.zeros((p, q))
    mask = rng.random((p, q)) < density
    S[mask] = rng.choice([-1.0, 1.0], mask.sum()) * magnitude
    return L, S


@pytest.mark.parametrize("n,rank", [(100, 5), (200, 10)])
def test_recovers_synthetic_low_rank_plus_sparse(n, rank):
    # the regime of exact recovery (Candes et al. 2011): rank << n, 5 % sparse corruption
    L, S = _low_rank_plus_sparse(n, rank, 0.05, seed=n)
    res = rpca(L + S)
    assert res.converged
    assert np.linalg.norm(res.P - L) / np.linalg.norm(L) < 1e-6
    assert np.linalg.norm(res.S - S) / np.linalg.norm(S) < 1e-6
    assert np.linalg.matrix_rank(res.P, tol=1e-6 * np.linalg.norm(L, 2)) == rank


def test_a_matrix_four_times_taller_than_wide_recovers_through_the_gram_route(monkeypatch):
    # 13 to 1 (457 frames of a 6034-face animation) had paid a full SVD every iteration: 1.57 s
    # against 0.08 s; recovery as the full SVD gives it
    L, S = _low_rank_plus_sparse(0, 5, 0.05, seed=3, shape=(1200, 100))
    monkeypatch.setattr(np.linalg, "svd", lambda *a, **k: pytest.fail("full SVD"))
    res = rpca(L + S)
    assert res.converged
    assert np.linalg.norm(res.P - L) / np.linalg.norm(L) < 1e-6
    assert np.linalg.norm(res.S - S) / np.linalg.norm(S) < 1e-6


def test_partial_svd_path_recovers_too():
    L, S = _low_rank_plus_sparse(300, 5, 0.05, seed=7)
    res = rpca(L + S, partial_svd_above=50)  # randomized partial SVD with adaptive rank
    assert np.linalg.norm(res.P - L) / np.linalg.norm(L) < 1e-6


def test_partial_svd_path_reaches_the_full_svd_objective_on_noisy_data():
    # with dense noise the rank kept grows every iteration: a partial SVD of too
    # few triplets dropped singular values above the threshold, and stopped at an
    # objective 3e-5 above the full SVD's on this matrix
    L, S = _low_rank_plus_sparse(0, 15, 0.05, seed=3, shape=(200, 150))
    D = L / np.sqrt(15) + S + 0.01 * np.random.default_rng(4).standard_normal(L.shape)
    lam = 1 / np.sqrt(200)

    def objective(res):
        return np.linalg.svd(res.P, compute_uv=False).sum() + lam * np.abs(res.S).sum()

    partial, full = rpca(D, partial_svd_above=50), rpca(D, partial_svd_above=10**6)
    assert abs(objective(partial) / objective(full) - 1) < 1e-6


def test_stopping_rule_residual():
    L, S = _low_rank_plus_sparse(80, 3, 0.05, seed=2)
    D = L + S
    res = rpca(D, tol=1e-7)
    assert np.linalg.norm(D - res.P - res.S) <= 1e-7 * np.linalg.norm(D)


def test_batched_thin_matches_single_matrix_solves():
    rng = np.random.default_rng(0)
    D = rng.standard_normal((40, 12, 3)) + 3.0 * rng.standard_normal((40, 1, 3))
    batch = rpca(D)
    for i in range(0, 40, 7):
        one = rpca(D[i])  # the generic numpy path
        assert np.allclose(batch.P[i], one.P, atol=1e-9)
        assert np.allclose(batch.S[i], one.S, atol=1e-9)
    wide = rpca(np.swapaxes(D, 1, 2))
    assert np.allclose(np.swapaxes(wide.P, 1, 2), batch.P, atol=1e-9)


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1e-80, 1e80, 1e150, 1e300])
def test_batched_thin_is_scale_free(scale):
    # the Jacobi test summed squared Gram entries (the data's 4th power): beyond about
    # 1e+-77 they overflowed or underflowed, the iteration stopped at once and P was
    # 0.35 off while reporting convergence
    rng = np.random.default_rng(0)
    D = np.stack([np.outer(rng.standard_normal(10), rng.standard_normal(3)) for _ in range(4)])
    D[:, 2, 1] += 5.0
    ref = rpca(D)
    got = rpca(D * scale)
    assert got.converged
    np.testing.assert_allclose(got.P / scale, ref.P, rtol=0, atol=1e-12 * np.abs(ref.P).max())


def test_svt_matches_svd_formula():
    rng = np.random.default_rng(1)
    for shape in [(50, 10, 3), (50, 6, 6), (1, 400, 12), (1, 120, 30), (1, 30, 120)]:  # the last two: 4 to 1
        X = rng.standard_normal(shape)
        tau = rng.random(shape[0]) * 2
        U, s, Vt = np.linalg.svd(X, full_matrices=False)
        ref = (U * np.maximum(s - tau[:, None], 0.0)[:, None, :]) @ Vt
        assert np.allclose(svt(X, tau), ref, atol=1e-10)


def test_shrink_and_randomized_svd():
    assert np.allclose(shrink(np.array([-3.0, -0.5, 0.2, 2.0]), 1.0), [-2.0, 0.0, 0.0, 1.0])
    rng = np.random.default_rng(3)
    X = rng.standard_normal((300, 8)) @ rng.standard_normal((8, 200))
    _, s, _ = randomized_svd(X, 8)
    assert np.allclose(s, np.linalg.svd(X, compute_uv=False)[:8], rtol=1e-8)


def test_randomized_svd_power_iterations_resolve_a_flat_spectrum():
    # singular values 1/sqrt(i): with no gap after the 8th, the plain range finder
    # is off by about 0.3 s_8 and one power iteration by about 0.03 s_8
    # (Halko et al. 2011, sec. 4.5); the default two leave under 0.006 s_8 here
    rng = np.random.default_rng(5)
    U, _ = np.linalg.qr(rng.standard_normal((400, 200)))
    V, _ = np.linalg.qr(rng.standard_normal((300, 200)))
    s = 1.0 / np.sqrt(np.arange(1, 201))
    X = (U * s) @ V.T
    for seed in range(5):
        _, t, _ = randomized_svd(X, 8, seed=seed)
        assert np.abs(t - s[:8]).max() <= 0.01 * s[7]


def test_package_name_is_the_function_even_after_the_module_is_imported():
    import importlib

    import geoproc.denoise as pkg

    importlib.import_module("geoproc.denoise.rpca")
    importlib.import_module("geoproc.denoise.mesh_denoise")  # imports the submodule too
    assert callable(pkg.rpca) and pkg.rpca is rpca


@pytest.mark.parametrize("D, kwargs, message", [
    (np.zeros((0, 5)), {}, "with entries"),
    (np.ones(5), {}, "got shape"),
    (np.ones((5, 5)) + 1j, {}, "real matrix"),
    (np.where(np.eye(5) > 0, np.nan, 1.0), {}, "finite entries"),
    (np.where(np.eye(5, 3)[None] > 0, np.nan, 1.0), {}, "finite entries"),  # a batch of thin matrices
    (np.ones((5, 5)), {"lam": -1.0}, "lam must be > 0"),
    (np.ones((5, 5)), {"rho": 0.5}, "rho must be > 1"),
])
def test_bad_input_is_refused(D, kwargs, message):
    with pytest.raises(ValueError, match=message):
        rpca(D, **kwargs)
