"""mesh_info and the topology queries, checked against trimesh and libigl."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import trimesh

from geoproc.mesh import Mesh, load_mesh, mesh_info
from geoproc.mesh.topology import (
    COMPILED_FANS_FROM,
    boundary_edges,
    count_boundary_loops,
    duplicate_faces,
    faces_with_distinct_corners,
    fans_by_sorting,
    fans_compiled,
    orientation_status,
    unique_edges,
    vertex_components,
    vertex_fans,
)

KNOWN = {
    # fixture: (components, boundary_loops, euler, genus, nonmanifold edges, nonmanifold vertices)
    "icosphere.ply": (1, 0, 2, 0, 0, 0),
    "torus.ply": (1, 0, 0, 1, 0, 0),
    "grid.ply": (1, 1, 1, None, 0, 0),
    "cube.ply": (1, 0, 2, 0, 0, 0),
    "bowtie.obj": (1, 2, 1, None, 0, 1),
    "fin.obj": (1, 2, 1, None, 1, 0),
}


@pytest.mark.parametrize("name", sorted(KNOWN))
def test_known_answers_on_fixtures(fixture_dir, name):
    info = mesh_info(load_mesh(fixture_dir / name))
    got = (
        info["components"],
        info["boundary_loops"],
        info["euler_characteristic"],
        info["genus"],
        info["nonmanifold_edges"],
        info["nonmanifold_vertices"],
    )
    assert got == KNOWN[name]


def test_degenerate_face_is_counted(fixture_dir):
    info = mesh_info(load_mesh(fixture_dir / "zero_area.off"))
    assert info["degenerate_faces"] == 1
    assert info["faces"] == 9


def test_a_vertex_no_face_uses_moves_neither_the_box_nor_the_degenerate_cut(tmp_path):
    # with --no-clean, one stray vertex at (1e6, 1e6, 1e6) took the diagonal from 1.73 to
    # 1.7e6, and with it the area cut-off of degenerate_faces (1e-12 of its square) past
    # a small real triangle's
    path = tmp_path / "stray.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 0 1e-3\nv 1e-3 0 0\nv 1e6 1e6 1e6\n"
                    "f 1 2 3\nf 1 3 4\nf 1 5 6\n")
    info = mesh_info(load_mesh(path, clean=False))
    assert info["unreferenced_vertices"] == 1
    assert info["bbox_diagonal"] == pytest.approx(np.sqrt(3), rel=1e-15)
    assert info["degenerate_faces"] == 0  # the small triangle: area 5e-7, not below 1e-12 x 3
    trimesh_box = trimesh.Trimesh(load_mesh(path).V, load_mesh(path).F).bounds
    assert info["bbox_diagonal"] == pytest.approx(np.linalg.norm(trimesh_box[1] - trimesh_box[0]), rel=1e-15)


def test_cube_fixture_is_outward_and_closed(fixture_dir):
    m = load_mesh(fixture_dir / "cube.ply")
    tm = trimesh.Trimesh(m.V, m.F, process=False)
    assert tm.is_watertight and tm.is_winding_consistent
    assert tm.volume == pytest.approx(8.0, rel=1e-12)  # positive: outward normals


def test_point_cloud_info(fixture_dir):
    info = mesh_info(load_mesh(fixture_dir / "points.ply"))
    assert info["point_cloud"] is True
    assert info["vertices"] == 200 and info["faces"] == 0
    assert info["genus"] is None and info["edges"] is None


def test_non_orientable_moebius_strip():
    n, w = 12, 0.3
    t = 2 * np.pi * np.arange(n) / n
    V = np.empty((2 * n, 3))
    for k, s in enumerate((-w, w)):  # vertex 2i + k sits at angle t_i, offset s
        V[k::2] = np.column_stack([(1 + s * np.cos(t / 2)) * np.cos(t),
                                   (1 + s * np.cos(t / 2)) * np.sin(t), s * np.sin(t / 2)])
    a, b = 2 * np.arange(n), 2 * np.arange(n) + 1
    F = []
    for i in range(n - 1):
        F += [[a[i], a[i + 1], b[i + 1]], [a[i], b[i + 1], b[i]]]
    F += [[a[-1], b[0], a[0]], [a[-1], a[0], b[-1]]]  # the half twist closes the strip
    F = np.array(F)
    orientable, consistent = orientation_status(F)
    assert orientable is False and consistent is False
    info = mesh_info(Mesh(V, F))
    assert info["boundary_loops"] == 1 and info["euler_characteristic"] == 0
    assert info["genus"] is None and info["edge_manifold"] and info["vertex_manifold"]


def test_flipped_face_is_orientable_but_inconsistent(make_fixtures):
    V, F = make_fixtures.icosphere(1)
    F = F.copy()
    F[0] = F[0, ::-1]
    orientable, consistent = orientation_status(F)
    assert orientable is True and consistent is False


def _shared_meshes(shared_data):
    return sorted((shared_data / "meshes").iterdir())


def test_against_trimesh_and_libigl_on_shared_meshes(shared_data):
    for path in _shared_meshes(shared_data):
        mesh = load_mesh(path)
        info = mesh_info(mesh)
        V, F = mesh.V, mesh.F
        tm = trimesh.Trimesh(V, F, process=False)
        where = path.name
        assert info["edges"] == len(tm.edges_unique), where
        assert info["euler_characteristic"] == igl.euler_characteristic(F), where
        n_comp = len(np.unique(igl.vertex_components(F)))
        assert info["components"] == n_comp, where
        assert info["components"] == len(trimesh.graph.connected_components(tm.edges)), where
        assert info["mean_edge_length"] == pytest.approx(tm.edges_unique_length.mean(), rel=1e-12), where
        assert info["bbox_diagonal"] == pytest.approx(np.linalg.norm(tm.extents), rel=1e-12), where
        igl_vertex_manifold = bool(np.all(igl.is_vertex_manifold(F)))
        assert info["vertex_manifold"] == igl_vertex_manifold or not info["edge_manifold"], where
        igl_edge_manifold = bool(igl.is_edge_manifold(F)[0])
        ours = info["edge_manifold"] and bool(info["consistently_oriented"])
        assert ours == igl_edge_manifold, where
        if info["edge_manifold"] and info["vertex_manifold"]:
            assert info["boundary_loops"] == len(igl.boundary_loop_all(F)), where
        if info["closed"] and info["edge_manifold"]:
            assert info["consistently_oriented"] == tm.is_winding_consistent, where


def test_known_shared_topology(shared_data):
    expect = {"bunny.off": 0, "fertility.off": 4, "armadillo.obj": 0, "spot.obj": 0, "fandisk.off": 0}
    for name, genus in expect.items():
        assert mesh_info(load_mesh(shared_data / "meshes" / name))["genus"] == genus, name
    camel = mesh_info(load_mesh(shared_data / "meshes" / "camelhead.off"))
    assert camel["boundary_loops"] == 1 and camel["genus"] is None
    cow = mesh_info(load_mesh(shared_data / "meshes" / "cow.obj"))
    assert cow["euler_characteristic"] == 1 and cow["genus"] is None


def test_unique_edges_counts_faces_per_edge(make_fixtures):
    V, F = make_fixtures.grid(5)
    E, edge_of, count = unique_edges(F)
    assert len(E) == 2 * 4 * 5 + 4 * 4  # horizontal + vertical + diagonals
    assert (count == 1).sum() == 16 and (count == 2).sum() == len(E) - 16
    assert np.array_equal(np.sort(F[:, :2], axis=1), E[edge_of.reshape(-1, 3)[:, 0]])
    assert count_boundary_loops(F) == 1


def test_boundary_edges_are_the_edges_of_one_face_on_random_soups():
    from collections import Counter

    rng = np.random.default_rng(5)
    for _ in range(300):  # repeated indices, non-manifold edges, duplicate faces
        F = rng.integers(0, rng.integers(1, 9), size=(rng.integers(0, 12), 3))
        count = Counter(tuple(sorted((int(f[k]), int(f[(k + 1) % 3])))) for f in F for k in range(3))
        expected = sorted(e for e, c in count.items() if c == 1)
        assert boundary_edges(F).tolist() == [list(e) for e in expected]


def test_faces_with_distinct_corners_keeps_the_proper_triangles_in_order():
    F = np.array([[0, 1, 2], [3, 3, 4], [2, 1, 3], [5, 6, 5], [4, 7, 7], [1, 2, 4]])
    assert faces_with_distinct_corners(F).tolist() == [[0, 1, 2], [2, 1, 3], [1, 2, 4]]
    assert faces_with_distinct_corners(np.zeros((0, 3), int)).shape == (0, 3)
    assert faces_with_distinct_corners(F.ravel()).tolist() == [[0, 1, 2], [2, 1, 3], [1, 2, 4]]


def test_duplicate_faces_are_named_in_info_and_in_the_manifold_refusal():
    from geoproc.errors import InputError
    from geoproc.mesh.validate import require_edge_manifold

    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [3, 1, 0], [1, 2, 3], [2, 1, 0]])
    assert duplicate_faces(F).tolist() == [4, 5, 6]  # same corners, any order or winding
    assert duplicate_faces(F[:4]).tolist() == [] and duplicate_faces(np.zeros((0, 3), int)).tolist() == []
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    info = mesh_info(Mesh(V, F[:5]))  # a tetrahedron with one face stored twice
    assert (info["duplicate_faces"], info["nonmanifold_edges"], info["closed"]) == (1, 3, True)
    assert mesh_info(Mesh(V, F[:4]))["duplicate_faces"] == 0
    with pytest.raises(InputError, match=r"3 edges have more than two faces \(first: edge 0-1\); 1 face repeats "
                                         r"the corners of an earlier one \(first: face 4, as face 1\)"):
        require_edge_manifold(F[:5], "t.obj")


def test_vertex_fans_and_components_of_disjoint_parts(make_fixtures):
    V1, F1 = make_fixtures.icosphere(1)
    V2, F2 = make_fixtures.torus(nu=8, nv=6)
    F = np.concatenate([F1, F2 + len(V1)])
    n = len(V1) + len(V2)
    count, labels = vertex_components(F, n)
    assert count == 2 and set(labels[: len(V1)]) == {0} and set(labels[len(V1):]) == {1}
    assert (vertex_fans(F, n) == 1).all()


def _fans_by_search(F, n):
    """Fans per vertex by graph search: a vertex's corners are linked when
    they lie on one undirected edge."""
    out = np.zeros(n, dtype=int)
    for v in range(n):
        corners = [(f, k) for f in range(len(F)) for k in range(3) if F[f, k] == v]
        keys = []
        for f, k in corners:
            nxt, prv = F[f, (k + 1) % 3], F[f, (k + 2) % 3]
            keys.append({nxt, prv})
        seen = set()
        for i in range(len(corners)):
            if i in seen:
                continue
            out[v] += 1
            stack = [i]
            seen.add(i)
            while stack:
                j = stack.pop()
                for q in range(len(corners)):
                    if q not in seen and keys[j] & keys[q]:
                        seen.add(q)
                        stack.append(q)
    return out


@pytest.mark.parametrize("count_fans", [vertex_fans, fans_by_sorting, fans_compiled])
def test_vertex_fans_match_a_graph_search_on_random_soups(make_fixtures, count_fans):
    # vertex_fans sorts below COMPILED_FANS_FROM corners and runs the compiled loop above:
    # both ways are checked here on every case
    rng = np.random.default_rng(3)
    for faces in (16, 60):  # valences up to 16, and above (the compiled loop's sorted path)
        for _ in range(75):  # repeated indices, non-manifold edges and vertices, unused vertices
            n = int(rng.integers(3, 10))
            F = rng.integers(0, n, (int(rng.integers(1, faces)), 3))
            assert np.array_equal(count_fans(F, n + 1), _fans_by_search(F, n + 1))
    V, F = make_fixtures.icosphere(1)  # two spheres sharing one vertex: a bowtie
    two = np.concatenate([F, np.where(F == 0, 0, F + len(V))])
    fans = count_fans(two, 2 * len(V))
    assert fans[0] == 2 and fans[len(V)] == 0 and (np.delete(fans, [0, len(V)]) == 1).all()
    k = 100_000  # two discs fanned around one shared centre: valence 400,000 (seconds, not hours)
    ring = np.arange(1, k + 1)
    disc = np.column_stack([np.zeros(k, dtype=int), ring, np.roll(ring, -1)])
    fans = count_fans(np.concatenate([disc, np.where(disc == 0, 0, disc + k)]), 2 * k + 1)
    assert fans[0] == 2 and (fans[1:] == 1).all()
    assert not count_fans(np.zeros((0, 3), dtype=np.int64), 3).any()


def test_the_two_fan_counts_agree_on_a_large_mesh(make_fixtures):
    # above COMPILED_FANS_FROM corners vertex_fans runs the compiled loop; sorting
    # gives the same counts
    V, F = make_fixtures.torus(nu=460, nv=440)  # 404,800 faces
    assert F.size >= COMPILED_FANS_FROM
    n = len(V)
    F = np.concatenate([F, np.where(F == 0, 0, F + n)])  # a second copy sharing vertex 0: a bowtie there
    fans = vertex_fans(F, 2 * n)
    assert np.array_equal(fans, fans_by_sorting(F, 2 * n))
    assert fans[0] == 2 and fans[n] == 0 and (np.delete(fans, [0, n]) == 1).all()


def test_face_list_renumbering_recovers_a_permutation(make_fixtures):
    from geoproc.mesh.topology import face_list_renumbering

    V, F = make_fixtures.icosphere(2)
    n = len(V)
    perm = np.random.default_rng(0).permutation(n)  # input vertex i is reference vertex perm[i]
    F_in = np.argsort(perm)[F]
    r = face_list_renumbering(F_in, n, F, n)
    assert r is not None and np.array_equal(r, perm) and np.array_equal(r[F_in], F)
    assert np.array_equal(face_list_renumbering(F, n, F, n), np.arange(n))
    # corners rotated in one face, two faces swapped, other counts: no renumbering
    rotated = F.copy()
    rotated[5] = rotated[5, [1, 2, 0]]
    assert face_list_renumbering(rotated, n, F, n) is None
    assert face_list_renumbering(F[[1, 0, *range(2, len(F))]], n, F, n) is None
    assert face_list_renumbering(F, n + 1, F, n) is None and face_list_renumbering(F[1:], n, F, n) is None


def test_face_list_renumbering_pairs_unused_vertices_in_order():
    from geoproc.mesh.topology import face_list_renumbering

    F_in = np.array([[0, 1, 2]])
    F_ref = np.array([[3, 2, 0]])
    r = face_list_renumbering(F_in, 5, F_ref, 5)
    assert np.array_equal(r, [3, 2, 0, 1, 4])
    # two input vertices onto one reference vertex: not one-to-one
    assert face_list_renumbering(np.array([[0, 1, 2], [0, 2, 3]]), 4, np.array([[0, 1, 2], [0, 2, 1]]), 4) is None


@pytest.mark.parametrize("dtype", [np.int16, np.int32, np.uint32])
def test_edges_do_not_depend_on_the_faces_integer_type(make_fixtures, dtype):
    # edge keys i * n + j were formed in the faces' own type: int32 overflowed past 46,341
    # vertices (mean edge length 0.0 on one triangle numbered from 50,000), int16 past 181
    from geoproc.mesh.topology import mean_edge_length

    n = 50_003 if dtype != np.int16 else 3_000
    V = np.zeros((n, 3))
    V[-3:] = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    F = np.array([[n - 3, n - 2, n - 1]])
    assert mean_edge_length(V, F.astype(dtype)) == mean_edge_length(V, F) == pytest.approx((2 + np.sqrt(2)) / 3)
    E, _, count = unique_edges(F.astype(dtype))
    assert sorted(map(tuple, E.tolist())) == [(n - 3, n - 2), (n - 3, n - 1), (n - 2, n - 1)]


def test_mean_edge_length_counts_each_edge_once():
    # a unit square of two triangles: four sides and one diagonal, (4 + sqrt 2) / 5; counted
    # per half-edge the diagonal would weigh twice, (4 + 2 sqrt 2) / 6
    from geoproc.mesh.topology import mean_edge_length

    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    assert mean_edge_length(V, F) == pytest.approx((4 + np.sqrt(2)) / 5, rel=1e-15)


def _klein_bottle(nu=12, nv=10):
    """A closed, non-orientable grid: (i, nv) is glued to (-i mod nu, 0) (Euler characteristic 0)."""
    idx = lambda i, j: (i % nu) * nv + j if j < nv else ((-i) % nu) * nv  # noqa: E731
    F = []
    for i in range(nu):
        for j in range(nv):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            F += [[a, b, c], [a, c, d]]
    V = np.random.default_rng(0).standard_normal((nu * nv, 3))
    return V, np.array(F)


def test_genus_and_euler_characteristic_by_hand(make_fixtures):
    V, F = make_fixtures.icosphere(1)
    # two spheres: chi = 2 + 2, genus 0 (genus = (2 * components - chi) / 2)
    two = mesh_info(Mesh(np.vstack([V, V + 5]), np.vstack([F, F + len(V)])))
    assert (two["components"], two["euler_characteristic"], two["genus"]) == (2, 4, 0)
    # a vertex no face uses is not part of the surface: chi stays 2
    extra = mesh_info(Mesh(np.vstack([V, [[9.0, 9.0, 9.0]]]), F))
    assert (extra["euler_characteristic"], extra["genus"]) == (2, 0)
    # a Klein bottle is closed and manifold with chi = 0 but has no genus (not orientable)
    Vk, Fk = _klein_bottle()
    k = mesh_info(Mesh(Vk, Fk))
    assert (k["components"], k["boundary_loops"], k["euler_characteristic"]) == (1, 0, 0)
    assert k["nonmanifold_edges"] == k["nonmanifold_vertices"] == 0
    assert k["orientable"] is False and k["genus"] is None


@pytest.mark.parametrize("extra", [[3, 3, 3], [3, 3, 0]])
def test_faces_repeating_a_corner_are_left_out_of_the_topology(extra):
    # an STL facet whose corners merged: its "edge" from a vertex to itself had counted as a
    # non-manifold (or boundary) edge of length 0, and a closed tetrahedron read as open
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], extra])
    info = mesh_info(Mesh(V, F))
    assert info["faces"] == 5 and info["degenerate_faces"] == 1 and info["edges"] == 6
    assert info["closed"] and info["edge_manifold"] and info["vertex_manifold"] and info["genus"] == 0
    assert info["euler_characteristic"] == 2 and info["boundary_loops"] == 0
    assert info["mean_edge_length"] == pytest.approx((3 + 3 * np.sqrt(2)) / 6, rel=1e-12)


def test_mean_edge_length_skips_faces_that_repeat_a_corner():
    # a closed tetrahedron plus an STL facet whose corners merged, [0, 0, 1]: its edge
    # from vertex 0 to itself had counted with length 0 (1.035 for the tetrahedron's
    # (3 + 3 sqrt 2) / 6 = 1.207), and so had perturb's noise unit
    from geoproc.mesh.topology import mean_edge_length
    from geoproc.perturb.noise import noise_scale

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2], [0, 0, 1]])
    expected = (3 + 3 * np.sqrt(2)) / 6
    assert mean_edge_length(V, F) == pytest.approx(expected, rel=1e-15)
    assert noise_scale(V, F) == pytest.approx(expected, rel=1e-15)
    assert mean_edge_length(V, F[4:]) == 0.0  # no edge at all


def test_a_mesh_whose_faces_all_repeat_a_corner_has_no_surface_topology():
    # every face collapsed to a point once coincident vertices merge: the empty surface had
    # read closed, manifold, orientable, of genus 0
    V = np.zeros((1, 3))
    F = np.array([[0, 0, 0], [0, 0, 0]])
    info = mesh_info(Mesh(V, F))
    assert info["faces"] == 2 and info["edges"] == 0 and info["components"] == 0
    for key in ("genus", "closed", "edge_manifold", "vertex_manifold", "orientable", "consistently_oriented"):
        assert info[key] is None, key
