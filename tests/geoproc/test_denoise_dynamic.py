"""Animation I/O and dynamic denoising (Algorithm 4) against the clean frames."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.animation import Animation, animation_to_bytes, load_animation
from geoproc.denoise import denoise_errors, denoise_mesh
from geoproc.denoise.dynamic import coherent_normals, denoise_animation
from geoproc.errors import InputError
from geoproc.mesh import Mesh, save_mesh
from tests.conftest import load_fixture_module


@pytest.fixture(scope="module")
def dfx():
    return load_fixture_module("denoise_fixtures")


def _theta(V, F, V_ref):
    return float(np.mean([denoise_errors(V[t], F, V_ref[t])["mean_normal_angle_deg"] for t in range(len(V))]))


@pytest.mark.slow
def test_dynamic_beats_frame_by_frame(dfx):
    Vn, F, V = dfx.noisy_wave(frames=6)
    static = np.stack([denoise_mesh(Vn[t], F).V for t in range(len(Vn))])
    dynamic, info = denoise_animation(Vn, F)
    assert info["rpca_converged"]
    assert _theta(dynamic, F, V) < 0.95 * _theta(static, F, V)
    assert _theta(dynamic, F, V) < 0.35 * _theta(Vn, F, V)


def test_coherent_normals_of_a_rigid_motion_are_exact(make_fixtures):
    # a rotation about a fixed axis: every frame's normals are c_t u + s_t v + w,
    # rank 3 over 20 frames, so RPCA gives them back unchanged (nothing sparse)
    from scipy.spatial.transform import Rotation

    V0, F = make_fixtures.torus()
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    V = np.stack([Rotation.from_rotvec(a * axis).apply(V0) for a in np.linspace(0, 3.0, 20)])
    N, info = coherent_normals(V, F)
    assert info["low_rank"] == 3
    from geoproc.denoise.face_geometry import face_normals_and_areas

    for t in range(len(V)):
        assert np.allclose(N[t], face_normals_and_areas(V[t], F)[0], atol=1e-6)


def test_npz_roundtrip_and_deterministic_bytes(tmp_path, dfx):
    V, F = dfx.wave_animation(3)
    data = animation_to_bytes(Animation(V, F, {"outlier": np.zeros(V.shape[:2])}))
    assert data == animation_to_bytes(Animation(V, F, {"outlier": np.zeros(V.shape[:2])}))
    (tmp_path / "a.npz").write_bytes(data)
    a = load_animation(tmp_path / "a.npz")
    assert np.array_equal(a.V, V) and np.array_equal(a.F, F) and "outlier" in a.fields


def test_folder_of_frames(tmp_path, make_fixtures):
    V, F = make_fixtures.icosphere(1)
    for t in range(3):
        save_mesh(tmp_path / f"frame{t:03d}.ply", Mesh(V * (1 + 0.1 * t), F))
    a = load_animation(tmp_path)
    assert a.V.shape == (3, len(V), 3)
    save_mesh(tmp_path / "frame003.ply", Mesh(V, F[:, [0, 2, 1]]))
    with pytest.raises(InputError, match="different connectivity"):
        load_animation(tmp_path)


def test_npz_errors(tmp_path):
    np.savez(tmp_path / "nofaces.npz", vertices=np.zeros((2, 3, 3)))
    with pytest.raises(InputError, match="missing array 'faces'"):
        load_animation(tmp_path / "nofaces.npz")
    F = np.array([[[0, 1, 2]], [[0, 2, 1]]])
    np.savez(tmp_path / "differ.npz", vertices=np.zeros((2, 3, 3)), faces=F)
    with pytest.raises(InputError, match="different connectivity"):
        load_animation(tmp_path / "differ.npz")
