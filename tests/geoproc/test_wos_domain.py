"""Domains: JSON loading, validation, orientation; mask images traced to loops."""

import json

import numpy as np
import pytest

from geoproc.errors import InputError
from geoproc.wos.domain import build_domain, load_domain_json, loop_offsets, loop_signed_area, loop_signed_areas
from geoproc.wos.mask import load_domain_mask, read_mask, trace_mask
from tests.conftest import load_fixture_module


def _load_wos_fixtures():
    """fixtures/wos_fixtures.py, loaded the way conftest loads make_fixtures."""
    return load_fixture_module("wos_fixtures")


wf = _load_wos_fixtures()


def test_orientation_outer_ccw_holes_cw_and_area():
    # hole given counter-clockwise, outer clockwise: both must be flipped
    outer = [[0, 0], [0, 4], [4, 4], [4, 0]]
    hole = [[1, 1], [2, 1], [2, 2], [1, 2]]
    d = build_domain([outer, hole])
    assert loop_signed_area(d.loops[0]) == pytest.approx(16.0)
    assert loop_signed_area(d.loops[1]) == pytest.approx(-1.0)
    assert d.area == pytest.approx(15.0)
    # the domain lies on the left of every segment: left normals point inside
    mid = (d.A + d.B) / 2
    E = d.B - d.A
    left = np.c_[-E[:, 1], E[:, 0]] / np.linalg.norm(E, axis=1)[:, None]
    assert d.contains(mid + 1e-3 * left).all()
    assert not d.contains(mid - 1e-3 * left).any()


def test_neumann_flags_follow_reversed_loops(tmp_path):
    # clockwise rectangle: bottom edge written as segment 2 ((2,0)->(0,0)), top as segment 0
    doc = {"loops": [[[0, 1], [2, 1], [2, 0], [0, 0]]], "neumann": [[0, 0], [0, 2]]}
    p = tmp_path / "r.json"
    p.write_text(json.dumps(doc))
    d = load_domain_json(str(p))
    ys = (d.A[:, 1] + d.B[:, 1]) / 2
    horizontal = d.A[:, 1] == d.B[:, 1]
    assert set(np.flatnonzero(d.neumann)) == set(np.flatnonzero(horizontal))
    assert sorted(ys[d.neumann]) == [0.0, 1.0]


@pytest.mark.parametrize("loop, mark", [
    ([[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]], 4),  # the closing copy back to the first vertex
    ([[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]], 1),  # a repeated vertex
])
def test_a_neumann_mark_on_a_zero_length_segment_is_refused(tmp_path, loop, mark):
    # such a mark named no segment and was dropped with it: a Dirichlet problem without a word
    p = tmp_path / "m.json"
    p.write_text(json.dumps({"loops": [loop], "neumann": [[0, mark]]}))
    with pytest.raises(InputError, match=f"segment {mark} of loop 0 runs from a vertex to a copy of itself"):
        load_domain_json(str(p))
    p.write_text(json.dumps({"loops": [loop], "neumann": [[0, mark - 1]]}))  # a real segment is marked
    assert load_domain_json(str(p)).has_neumann


def test_zero_length_segment_flags_stay_on_their_segments():
    # vertex 2 repeats vertex 1: segment 1 has zero length, segment 2 is the right edge
    loop = [[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]]
    d = build_domain([loop], [np.array([0, 1, 0, 0, 0], bool)])
    assert len(d.A) == 4 and not d.has_neumann  # the zero-length segment took no real one with it
    d = build_domain([loop], [np.array([0, 0, 1, 0, 0], bool)])
    right = np.flatnonzero(d.neumann)
    assert len(right) == 1
    assert {tuple(d.A[right[0]]), tuple(d.B[right[0]])} == {(1.0, 0.0), (1.0, 1.0)}


def _segment_values(d):
    """{(start point, end point): (start value, end value)} of a domain's segments."""
    return {(tuple(a), tuple(b)): tuple(v) for a, b, v in zip(d.A.tolist(), d.B.tolist(), d.values.tolist(),
                                                               strict=True)}


@pytest.mark.parametrize("reverse", [False, True])
def test_a_repeated_vertex_with_two_values_is_a_jump(reverse):
    # the unit square with 0 on the bottom edge and 1 on the other three: the jumps sit at
    # (1, 0), given twice, and at (0, 0), the closing copy; given clockwise, the loop is
    # turned round and each value must stay on its edge. The second copies and their
    # values used to be dropped, which made the sides ramps from 0 to 1.
    loop = [[0, 0], [1, 0], [1, 0], [1, 1], [0, 1], [0, 0]]
    values = [0, 0, 1, 1, 1, 1]
    if reverse:
        loop, values = loop[::-1], values[::-1]
    got = _segment_values(build_domain([loop], values=[values]))
    want = {((0, 0), (1, 0)): (0, 0), ((1, 0), (1, 1)): (1, 1), ((1, 1), (0, 1)): (1, 1),
            ((0, 1), (0, 0)): (1, 1)}
    assert got == want  # stored counter-clockwise either way


def test_values_without_repeats_are_linear_along_the_segments():
    d = build_domain([[[0, 0], [2, 0], [2, 1], [0, 1]]], values=[[1.0, 2.0, 3.0, 4.0]])
    assert _segment_values(d) == {((0, 0), (2, 0)): (1, 2), ((2, 0), (2, 1)): (2, 3), ((2, 1), (0, 1)): (3, 4),
                                  ((0, 1), (0, 0)): (4, 1)}


@pytest.mark.parametrize("offset", [0.0, 1e8, 1e12])
def test_area_far_from_the_origin(offset):
    # the shoelace sum about the origin lost a unit square at 1e8 (zero area)
    # and gave 2.7e8 at 1e12
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) + offset
    assert build_domain([square]).area == pytest.approx(1.0, rel=1e-9)


def _regular_polygon(n, r, centre, ccw=True):
    t = 2 * np.pi * np.arange(n) / n * (1 if ccw else -1)
    return np.stack([centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)], axis=1)


def test_loop_signed_areas_of_regular_polygons():
    # the area of a regular n-gon of circumradius r is n r^2 sin(2 pi / n) / 2,
    # negative when it runs clockwise; loops of 3 to 1000 vertices, far from the origin too
    cases = [(3, 1.0, (0, 0), True), (4, 2.0, (1e6, -3e6), False), (7, 0.5, (-2, 5), True),
             (1000, 3.0, (1e8, 1e8), False), (5, 1e-3, (0.25, 0.75), True)]
    loops = [_regular_polygon(n, r, c, ccw) for n, r, c, ccw in cases]
    exact = np.array([(1 if ccw else -1) * n * r * r * np.sin(2 * np.pi / n) / 2 for n, r, _, ccw in cases])
    np.testing.assert_allclose(loop_signed_areas(loops), exact, rtol=1e-9)
    np.testing.assert_allclose([loop_signed_area(L) for L in loops], exact, rtol=1e-9)


def test_the_domain_keeps_its_own_copy_of_the_loops():
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    closed = np.vstack([sq, sq[:1]])  # the first vertex repeated at the end
    d, e = build_domain([sq]), build_domain([closed])
    sq *= 2.0
    closed *= 2.0
    assert d.area == pytest.approx(1.0) and e.area == pytest.approx(1.0)
    assert d.loops[0].max() == 1.0 and e.loops[0].max() == 1.0


def test_loop_offsets():
    start, nxt = loop_offsets(np.array([3, 1, 4]))
    assert start.tolist() == [0, 3, 4]
    assert nxt.tolist() == [1, 2, 0, 3, 5, 6, 7, 4]


@pytest.mark.parametrize("height,collinear", [(1e-3, False), (1e-9, False), (1e-13, True), (0.0, True)])
def test_thin_triangles_against_the_collinearity_threshold(height, collinear):
    # a triangle of base 1 and height h: its centred vertices have a smaller singular
    # value of h / sqrt(6) ~ 0.41 h, against the threshold 1e-12 * span * sqrt(3) ~ 1.7e-12
    tri = [[0.0, 0.0], [1.0, 0.0], [0.5, height]]
    if collinear:
        with pytest.raises(InputError, match="collinear"):
            build_domain([tri])
    else:
        assert build_domain([tri]).area == pytest.approx(height / 2, rel=1e-6)


def test_many_nested_loops_are_oriented_by_depth():
    # a 20 x 20 array of squares inside one frame, each holding a smaller square:
    # depth 0 counter-clockwise, 1 clockwise, 2 counter-clockwise
    frame = [[-1, -1], [41, -1], [41, 41], [-1, 41]]
    loops = [frame]
    for i in range(20):
        for j in range(20):
            x, y = 2 * i, 2 * j
            loops.append([[x, y], [x, y + 1.5], [x + 1.5, y + 1.5], [x + 1.5, y]])  # clockwise as given
            loops.append([[x + .5, y + .5], [x + 1, y + .5], [x + 1, y + 1], [x + .5, y + 1]])  # ccw
    d = build_domain(loops)
    signs = np.sign([loop_signed_area(L) for L in d.loops])
    assert signs[0] == 1 and (signs[1::2] == -1).all() and (signs[2::2] == 1).all()
    assert d.area == pytest.approx(42 * 42 - 400 * (1.5 ** 2 - 0.5 ** 2))


def test_contains_matches_matplotlib_per_loop():
    # the banded even-odd test against matplotlib's point-in-path test, XORed over
    # the loops (the test it replaced); the grid rows run through the squares'
    # corners, where the half-open rule counts a vertex once
    from matplotlib.path import Path

    frame = [[-1, -1], [41, -1], [41, 41], [-1, 41]]
    loops = [frame]
    for i in range(20):
        for j in range(20):
            x, y = 2 * i, 2 * j
            loops.append([[x, y], [x + 0.75, y - 0.25], [x + 1.5, y], [x + 1.5, y + 1.5], [x, y + 1.5]])
            loops.append([[x + .5, y + .5], [x + 1, y + .5], [x + 1, y + 1], [x + .5, y + 1]])
    d = build_domain(loops)
    g = np.linspace(-2, 42, 353)
    rng = np.random.default_rng(0)
    P = np.vstack([np.stack(np.meshgrid(g + 0.01, g), -1).reshape(-1, 2), rng.uniform(-2, 42, (20000, 2))])
    expected = np.zeros(len(P), dtype=bool)
    for L in d.loops:
        expected ^= Path(L).contains_points(P)
    # points on a horizontal segment are on the boundary, where either answer holds
    flat = d.A[:, 1] == d.B[:, 1]
    lo, hi = np.minimum(d.A[flat, 0], d.B[flat, 0]), np.maximum(d.A[flat, 0], d.B[flat, 0])
    on = ((P[:, 1, None] == d.A[flat, 1]) & (P[:, 0, None] >= lo) & (P[:, 0, None] <= hi)).any(axis=1)
    got = d.contains(P)
    assert got.sum() > 0.4 * len(P) and on.sum() > 1000 and np.array_equal(got[~on], expected[~on])
    # far off every band (1e300 / height had overflowed the band index and read outside it)
    assert not d.contains(np.array([[np.nan, 1.0], [1.0, np.nan], [0.0, 1e9], [0.0, 1e300], [0.0, -1e300],
                                    [1e300, 20.0], [-np.inf, 20.0]])).any()


def test_contains_a_point_an_ulp_under_the_top_edge():
    # (py - y0) / height rounded above the band count for such a point: it was skipped
    hits = 0
    for n in range(3, 120):
        xs = np.linspace(0, 1, n)
        d = build_domain([np.r_[np.c_[xs, np.full(n, -1.0)], [[1, 1e-3], [0, 1e-3]]]])
        hits += bool(d.contains(np.array([[0.5, np.nextafter(1e-3, -1)]]))[0])
    assert hits == 117


def test_contains_bands_follow_the_short_axis():
    # tall slots (a comb turned on its side) had been listed in nearly every horizontal
    # band: memory grew as the square of their number
    from matplotlib.path import Path

    from geoproc.wos.domain import BAND_COPIES, segment_bands

    slots = [[[x, 1], [x, 99], [x + 0.5, 99], [x + 0.5, 1]] for x in np.arange(1, 999, 1.0)]
    d = build_domain([[[0, 0], [1000, 0], [1000, 100], [0, 100]], *slots])
    bands = segment_bands(d.A, d.B)
    assert list(bands.cols) == [1, 0] and len(bands.seg) <= BAND_COPIES * len(d.A)
    P = np.random.default_rng(2).uniform(0, 100, (5000, 2)) * [10, 1]
    expected = np.zeros(len(P), dtype=bool)
    for L in d.loops:
        expected ^= Path(L).contains_points(P)
    assert np.array_equal(d.contains(P), expected)


def test_contains_decides_by_exact_sides_far_from_the_origin():
    # a polygon 0.02 across at 1e12 from the origin, where a coordinate's ulp is 1.2e-4:
    # the side of a segment is the sign of a cross product; comparing with the ray's
    # rounded intersection had put points an ulp off the boundary on the wrong side
    from fractions import Fraction

    rng = np.random.default_rng(4)
    t = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    L = 1e12 + 1e-2 * np.c_[np.cos(t), np.sin(t)] * rng.uniform(0.7, 1.0, (16, 1))
    d = build_domain([L])
    P = d.A[rng.integers(len(d.A), size=3000)] + rng.integers(-3, 4, (3000, 2)) * np.spacing(1e12)

    def exact(px, py):  # even-odd with half-open ends, None on the boundary
        odd = False
        for a, b in zip(d.A, d.B, strict=True):
            ax, ay, bx, by, x, y = map(Fraction, (*a, *b, px, py))
            if (ay > y) != (by > y):
                side = (bx - ax) * (y - ay) - (by - ay) * (x - ax)
                if side == 0:
                    return None
                odd ^= (side > 0) == (by > ay)
            elif (ay == y == by and min(ax, bx) <= x <= max(ax, bx)) or (x, y) in ((ax, ay), (bx, by)):
                return None
        return odd

    truth = [exact(*p) for p in P]
    known = np.array([e is not None for e in truth])
    assert known.sum() > 1000
    assert np.array_equal(d.contains(P)[known], np.array([e for e in truth if e is not None]))


@pytest.mark.parametrize("loops,match", [
    ([[[0, 0], [1, 1], [1, 0], [0, 1]]], "intersects itself"),
    ([[[0, 0], [2, 0], [2, 2], [0, 2]], [[1, 1], [3, 1], [3, 3], [1, 3]]], "loops 0 and 1 intersect"),
    ([[[0, 0], [1, 0]]], "open or degenerate"),
    ([[[0, 0], [1, 0], [2, 0]]], "zero area"),
    ([[[0, 0], [1, 0], [float("nan"), 1]]], "non-finite"),
    ([[[0, 0], [2, 0], [2, 2], [0, 2]], [[1, 0], [1.5, 1], [0.5, 1]]], "intersect"),
])
def test_bad_loops_raise_input_error(loops, match):
    with pytest.raises(InputError, match=match):
        build_domain(loops)


def test_generated_domains_are_valid():
    for name, dom, _ in wf.domains():
        d = build_domain(dom["loops"])
        assert d.area > 0, name


@pytest.mark.parametrize("radius,hole", [(30.0, 0.0), (40.0, 15.0)])
def test_mask_traces_to_pixel_area(tmp_path, radius, hole):
    mask = wf.disk_mask(100, radius, hole)
    path = tmp_path / "m.png"
    wf.write_mask(path, mask)
    assert np.array_equal(read_mask(str(path)), mask)
    d = load_domain_mask(str(path))
    assert len(d.loops) == (2 if hole else 1)
    # marching squares at the 0.5 level: traced area equals the pixel count up to the
    # corner cuts along the outline (well under 1 % here)
    assert d.area == pytest.approx(mask.sum(), rel=0.01)
    assert d.area == pytest.approx(np.pi * (radius**2 - hole**2), rel=0.02)


def test_mask_coordinates_are_pixel_units_y_up():
    mask = np.zeros((10, 20), bool)
    mask[1:3, 4:9] = True  # rows 1-2 (top of the image), columns 4-8
    (L,) = trace_mask(mask)
    assert L[:, 0].min() == pytest.approx(4.0, abs=0.5) and L[:, 0].max() == pytest.approx(9.0, abs=0.5)
    assert L[:, 1].min() == pytest.approx(7.0, abs=0.5) and L[:, 1].max() == pytest.approx(9.0, abs=0.5)


def test_mask_image_round_trip_keeps_orientation(tmp_path):
    mask = np.zeros((12, 20), bool)
    mask[2:5, 3:15] = True  # a wide bar near the top
    path = tmp_path / "bar.png"
    wf.write_mask(path, mask)
    assert np.array_equal(read_mask(str(path)), mask)
    d = load_domain_mask(str(path))
    lo, hi = d.bbox
    assert d.area == pytest.approx(36.0, rel=0.02)
    assert hi[0] - lo[0] > hi[1] - lo[1]  # wider than tall
    assert lo[1] > 6  # near the top (y up)


def _write_image(path, pixels, channels, fmt="uint8", spec_edit=None, attributes=()):
    import OpenImageIO as oiio

    pixels = np.asarray(pixels, dtype=np.float32)
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], getattr(oiio, fmt.upper()))
    spec.channelnames = channels
    if spec_edit:
        spec_edit(spec)
    for name, value in attributes:
        spec.attribute(name, value)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    out.write_image(pixels)
    out.close()


def test_mask_is_the_first_channel_that_is_not_alpha_with_alpha_associated(tmp_path):
    # an OpenEXR file lists its channels by name, so a grey image with alpha read A first
    # and an opaque image was all foreground
    mask = np.zeros((8, 8), bool)
    mask[2:6, 2:6] = True
    grey_alpha = np.stack([mask, np.ones((8, 8))], axis=2)
    _write_image(tmp_path / "ya.exr", grey_alpha, ("Y", "A"), fmt="float")
    assert np.array_equal(read_mask(str(tmp_path / "ya.exr")), mask)
    # a white cut-out on a transparent background is its shape (the value times alpha)
    cutout = np.stack([np.ones((8, 8))] * 3 + [mask], axis=2)
    _write_image(tmp_path / "cut.png", cutout, ("R", "G", "B", "A"))
    assert np.array_equal(read_mask(str(tmp_path / "cut.png")), mask)


def test_mask_covers_the_display_window_as_displayed(tmp_path):
    # an OpenEXR data window smaller than the image was traced in its own coordinates,
    # and a TIFF orientation tag was ignored
    def window(spec):
        spec.x, spec.y, spec.full_x, spec.full_y, spec.full_width, spec.full_height = 20, 4, 0, 0, 32, 32

    square = np.zeros((8, 8, 1))
    square[2:6, 2:6] = 1  # rows 6-9, columns 22-25 of the 32 x 32 image
    _write_image(tmp_path / "dw.exr", square, ("Y",), fmt="float", spec_edit=window)
    got = read_mask(str(tmp_path / "dw.exr"))
    want = np.zeros((32, 32), bool)
    want[6:10, 22:26] = True
    assert np.array_equal(got, want)
    corner = np.zeros((8, 8, 1))
    corner[:2, :3] = 1  # top left as stored; orientation 3 displays it turned by 180 degrees
    _write_image(tmp_path / "o.tif", corner, ("Y",), attributes=[("Orientation", 3)])
    assert np.array_equal(read_mask(str(tmp_path / "o.tif")), corner[::-1, ::-1, 0] > 0.5)



def test_mask_reads_only_the_data_window_of_a_huge_display_window(tmp_path):
    # a 4 kB OpenEXR may declare a display window of 2.5e9 pixels: reading all of
    # it (float32, then traced) took gigabytes; only the data window holds pixels
    import subprocess
    import sys

    H = W = 50_000

    def window(spec):
        spec.x, spec.y, spec.full_x, spec.full_y, spec.full_width, spec.full_height = 20, 4, 0, 0, W, H

    square = np.zeros((8, 8, 1))
    square[2:6, 2:6] = 1  # rows 6-9, columns 22-25 of the display window
    path = tmp_path / "huge.exr"
    _write_image(path, square, ("Y",), fmt="float", spec_edit=window)
    script = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))\n"
        "from geoproc.wos.mask import load_domain_mask\n"
        "d = load_domain_mask(sys.argv[1])\n"
        "lo, hi = d.bbox\n"
        "print(*lo, *hi, d.area)\n"
    )
    done = subprocess.run([sys.executable, "-c", script, str(path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    x0, y0, x1, y1, area = map(float, done.stdout.split())
    assert (x0, x1) == (22.0, 26.0)
    assert (y0, y1) == pytest.approx((H - 10.0, H - 6.0), abs=0.5)
    assert area == pytest.approx(16.0, rel=0.1)

def test_mask_without_foreground(tmp_path):
    path = tmp_path / "empty.png"
    wf.write_mask(path, np.zeros((16, 16), bool))
    with pytest.raises(InputError, match="no foreground"):
        load_domain_mask(str(path))
    # a black shape on a transparent background: the message says what reads as foreground
    import OpenImageIO as oiio

    rgba = np.zeros((16, 16, 4), np.uint8)
    rgba[4:12, 4:12, 3] = 255  # opaque black square, transparent elsewhere
    out = oiio.ImageOutput.create(str(tmp_path / "black.png"))
    out.open(str(tmp_path / "black.png"), oiio.ImageSpec(16, 16, 4, oiio.UINT8))
    out.write_image(rgba)
    out.close()
    with pytest.raises(InputError, match="times alpha\\): a dark shape on a light or transparent background reads"):
        load_domain_mask(str(tmp_path / "black.png"))


def test_files_that_are_neither_json_nor_an_image(tmp_path):
    from geoproc.wos.load import load_domain

    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError) as err:
        load_domain(str(mesh))
    assert err.value.problem == "neither a JSON domain nor an image OpenImageIO can read (no reader for '.obj' files)"
    with pytest.raises(InputError) as err:  # the image reader alone does not speak of JSON domains
        read_mask(str(mesh))
    assert err.value.problem == "not an image OpenImageIO can read (no reader for '.obj' files)"
    bad = tmp_path / "b.png"
    bad.write_bytes(b"not a png at all")
    with pytest.raises(InputError) as err:
        load_domain(str(bad))
    assert err.value.problem.startswith("cannot read image: ") and str(bad) not in err.value.problem


def test_a_json_domain_with_a_byte_order_mark_is_json_whatever_its_name(tmp_path):
    # the content test did not skip the mark: the same bytes were refused as d.txt
    from geoproc.wos.load import load_domain

    path = tmp_path / "d.txt"
    path.write_bytes(b"\xef\xbb\xbf" + b'{"loops": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}')
    assert load_domain(str(path)).area == 1.0
    assert load_domain("-", path.read_bytes()).area == 1.0


def test_parts_of_nested_and_separate_loops():
    sq = lambda c, r: [[c[0] - r, c[1] - r], [c[0] + r, c[1] - r], [c[0] + r, c[1] + r], [c[0] - r, c[1] + r]]  # noqa: E731
    # outer, its hole, an island in the hole, the island's hole, a second component
    loops = [sq((0, 0), 4), sq((0, 0), 3), sq((0, 0), 2), sq((0, 0), 1), sq((10, 0), 1)]
    order = [3, 0, 4, 2, 1]  # any order of the loops
    d = build_domain([np.array(loops[k], float) for k in order])
    outer = {k: i for i, k in enumerate(order)}
    assert d.part_of.tolist() == [outer[{3: 2, 0: 0, 4: 4, 2: 2, 1: 0}[k]] for k in order]


def test_first_crossing_is_the_first_of_a_sweep_along_x():
    # the banded search against every pair: the crossing pair of lowest rank (segments
    # ranked by smallest x), then lowest rank of the other segment
    from geoproc.wos.domain import _crossing, _first_crossing

    rng = np.random.default_rng(1)
    found = 0
    for trial in range(40):
        loops = []
        for _ in range(rng.integers(1, 4)):
            n = int(rng.integers(5, 40))
            t = np.sort(rng.uniform(0, 2 * np.pi, n))
            r = rng.uniform(0.5, 1.5, n) * (1 + (rng.random(n) < 0.1) * rng.uniform(-1.8, 0, n))
            loops.append(np.c_[r * np.cos(t), r * np.sin(t)] + rng.uniform(-1.5, 1.5, 2))
        A = np.concatenate(loops)
        count = np.array([len(L) for L in loops], dtype=np.int64)
        start, nxt = loop_offsets(count)
        B = A[nxt]
        loop_of = np.repeat(np.arange(len(loops)), count)
        rank = np.empty(len(A), dtype=np.int64)
        rank[np.argsort(np.minimum(A, B)[:, 0], kind="stable")] = np.arange(len(A))
        expected = min(((rank[i], rank[j], min(i, j), max(i, j)) for i in range(len(A)) for j in range(len(A))
                        if rank[i] < rank[j] and _crossing(A, B, loop_of, count, i, j)), default=None)
        got = _first_crossing(A, B, loop_of, start, count)
        assert got == ((-1, -1) if expected is None else expected[2:]), trial
        found += expected is not None
    assert 10 < found < 40
