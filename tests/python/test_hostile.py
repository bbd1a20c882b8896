"""The Python module on hostile arrays: wrong dtypes and shapes, strides of every kind,
read-only and broadcast arrays, NaN-only and 1e30 coordinates, empty arrays and ten million
points. Each call either gives the right answer (the labels of a plain C-contiguous copy of
the same data) or raises TypeError / ValueError naming the argument; nothing crashes, and
memory stays bounded. Needs no real data (scenes from clutterseg-synth)."""
import math

import numpy as np
import pytest

import clutterseg


@pytest.fixture(scope="module")
def scene(synth_dir):
    return clutterseg.read_pcd(str(synth_dir / "scene_0001.pcd"))


@pytest.fixture(scope="module")
def seg():
    return clutterseg.Segmenter(threads=1)


@pytest.fixture(scope="module")
def ref(seg, scene):
    """Labels of the scene from plain C-contiguous arrays."""
    return seg.segment(scene.points, scene.colors).labels


def proc_kib(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise AssertionError(f"{field} not in /proc/self/status")


def check_result(r, shape):
    """The invariants of any result: labels of the input's leading shape, ids 1..n in
    order, each object's point count equal to its labelled points, finite geometry."""
    assert r.labels.shape == shape and r.labels.dtype == np.uint32
    assert [o.id for o in r.objects] == list(range(1, len(r.objects) + 1))
    counts = np.bincount(r.labels.ravel(), minlength=len(r.objects) + 1)
    assert len(counts) == len(r.objects) + 1
    for o in r.objects:
        assert o.num_points == counts[o.id]
        assert np.all(np.isfinite(o.centroid)) and np.all(np.isfinite(o.obb_extents))


# ---- wrong dtype and shape: an exception naming the argument ---------------------------------

@pytest.mark.parametrize("dtype", [">f4", np.float16, np.float64, np.int16, np.uint16, bool,
                                   object, np.complex64, [("x", "<f4")]])
def test_points_of_another_dtype_raise_type_error_naming_points(seg, dtype):
    with pytest.raises(TypeError, match="points must have dtype float32"):
        seg.segment(np.zeros((10, 3), dtype))


@pytest.mark.parametrize("shape", [(3,), (10, 2), (10, 4), (10, 3, 1), (2, 2, 2, 3), (0,)])
def test_points_of_another_shape_raise_value_error_naming_points(seg, shape):
    with pytest.raises(ValueError, match="points must have shape"):
        seg.segment(np.zeros(shape, np.float32))


@pytest.mark.parametrize("value", [np.float32(1.0), 1.0, "points", None, [[0, 0, 1]]])
def test_points_that_are_not_arrays_raise_type_error_naming_points(seg, value):
    with pytest.raises(TypeError, match="points must be a numpy array"):
        seg.segment(value)


def test_colors_and_depth_of_another_dtype_or_shape_name_their_argument(seg, scene):
    k = clutterseg.Intrinsics()
    for dtype in (np.int8, np.uint16, ">u2", np.float32):
        with pytest.raises(TypeError, match="colors must have dtype uint8"):
            seg.segment(scene.points, scene.colors.astype(dtype))
    with pytest.raises(ValueError, match="colors must have shape"):
        seg.segment(scene.points, scene.colors.reshape(-1, 3))
    for dtype in (np.int16, np.uint32, ">u2", np.float32):
        with pytest.raises(TypeError, match="depth_mm must have dtype uint16"):
            seg.segment_depth(np.zeros((480, 640), dtype), k)
    with pytest.raises(ValueError, match=r"depth_mm must have shape \(H, W\)"):
        seg.segment_depth(np.zeros(640, np.uint16), k)


# ---- empty arrays ------------------------------------------------------------------------------

def test_empty_arrays_give_empty_results_or_name_the_argument(seg, work_dir):
    r = seg.segment(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8))
    check_result(r, (0,))
    assert r.objects == []
    for shape in ((0, 0, 3), (0, 640, 3), (480, 0, 3)):
        with pytest.raises(ValueError, match="points: .* px is not an image size"):
            seg.segment(np.zeros(shape, np.float32))
    with pytest.raises(ValueError, match="depth_mm: 0x0 px is not an image size"):
        seg.segment_depth(np.zeros((0, 0), np.uint16), clutterseg.Intrinsics())
    m = clutterseg.evaluate(np.zeros(0, np.uint32), np.zeros(0, np.uint32))
    assert m.num_gt_objects == 0 and m.f1 == 0.0
    path = work_dir / "empty.pcd"
    clutterseg.write_pcd(str(path), np.zeros((0, 3), np.float32))
    assert clutterseg.read_pcd(str(path)).points.shape == (0, 3)


# ---- layouts: non-contiguous, Fortran order, read-only, broadcast -----------------------------

def test_every_layout_gives_the_labels_of_a_contiguous_copy(seg, scene, ref):
    p, c = scene.points, scene.colors
    flipped = np.ascontiguousarray(p[::-1, ::-1])[::-1, ::-1]  # negative strides
    assert flipped.strides[0] < 0
    ro_p, ro_c = p.copy(), c.copy()
    ro_p.flags.writeable = False
    ro_c.flags.writeable = False
    channels_first = np.ascontiguousarray(np.moveaxis(p, 2, 0))
    from_planes = np.moveaxis(channels_first, 0, 2)  # last axis has the largest stride
    for points, colors in ((np.asfortranarray(p), np.asfortranarray(c)), (flipped, c),
                           (ro_p, ro_c), (from_planes, c)):
        assert np.array_equal(seg.segment(points, colors).labels, ref)
    # A broadcast array (stride 0): every pixel the same point; nothing to segment.
    same = np.broadcast_to(np.float32([0.1, 0.0, 1.0]), p.shape)
    assert not same.flags.writeable
    r = seg.segment(same)
    check_result(r, p.shape[:2])
    assert r.objects == []


def test_depth_in_fortran_order_read_only_or_strided_gives_the_same_labels(seg, scene):
    k = clutterseg.Intrinsics()
    z = scene.points[:, :, 2]
    depth = np.where(np.isfinite(z), np.round(z * 1000.0), 0).astype(np.uint16)
    want = seg.segment_depth(depth, k, scene.colors).labels
    ro = depth.copy()
    ro.flags.writeable = False
    wide = np.zeros((480, 1280), np.uint16)
    wide[:, ::2] = depth
    for d in (np.asfortranarray(depth), ro, wide[:, ::2]):
        assert np.array_equal(seg.segment_depth(d, k, np.asfortranarray(scene.colors)).labels,
                              want)


def test_labels_in_any_layout_evaluate_and_write_the_same(work_dir, scene, ref):
    gt = ref.astype(np.uint32)
    want = clutterseg.evaluate(gt, gt, scene.points)
    assert want.wov == 1.0
    ro = gt.copy()
    ro.flags.writeable = False
    for labels in (np.asfortranarray(gt), ro, gt.astype(np.int64), gt.astype(">u4")):
        m = clutterseg.evaluate(labels, gt, np.asfortranarray(scene.points))
        assert (m.wov, m.f1, m.num_gt_objects) == (want.wov, want.f1, want.num_gt_objects)
    path = work_dir / "fortran.pcd"
    clutterseg.write_pcd(str(path), np.asfortranarray(scene.points), scene.colors[::-1][::-1],
                         labels=np.asfortranarray(gt))
    back = clutterseg.read_pcd(str(path))
    assert np.array_equal(back.labels, gt)
    assert np.array_equal(back.points, scene.points, equal_nan=True)


# ---- hostile values ---------------------------------------------------------------------------

def test_nan_only_and_inf_only_frames_are_empty(seg):
    for value in (np.nan, np.inf, -np.inf):
        for shape in ((480, 640, 3), (100_000, 3)):
            r = seg.segment(np.full(shape, value, np.float32))
            check_result(r, shape[:-1])
            assert r.objects == [] and not r.labels.any()


def test_1e30_coordinates_are_never_labelled_and_leave_the_rest_alone(seg, scene, ref):
    for value in (1e30, -1e30, 3e38):
        r = seg.segment(np.full((480, 640, 3), value, np.float32))
        check_result(r, (480, 640))
        assert r.objects == []
    # 1,000 pixels of the scene moved to 1e30 (x, y or z): none of them is labelled, and
    # every object found is finite; the other pixels keep most of their labels.
    p = scene.points.copy()
    rng = np.random.default_rng(3)
    idx = rng.choice(p.shape[0] * p.shape[1], 1000, replace=False)
    flat = p.reshape(-1, 3)
    flat[idx, rng.integers(0, 3, idx.size)] = 1e30
    r = seg.segment(p, scene.colors)
    check_result(r, (480, 640))
    assert not r.labels.reshape(-1)[idx].any()
    assert len(r.objects) > 0
    keep = np.ones(flat.shape[0], bool)
    keep[idx] = False
    assert np.mean((r.labels.reshape(-1) > 0)[keep] == (ref.reshape(-1) > 0)[keep]) > 0.95


def test_1e30_coordinates_round_trip_through_pcd_and_evaluate(work_dir):
    points = np.full((10, 3), 1e30, np.float32)
    points[1] = -3e38
    path = work_dir / "huge.pcd"
    for encoding in ("ascii", "binary", "binary_compressed"):
        clutterseg.write_pcd(str(path), points, encoding=encoding)
        assert np.array_equal(clutterseg.read_pcd(str(path)).points, points)
    m = clutterseg.evaluate(np.ones(10, np.uint32), np.ones(10, np.uint32), points)
    assert math.isfinite(m.wov) and m.wov == 1.0


# ---- size: ten million points, bounded memory -------------------------------------------------

def test_ten_million_points_segment_with_bounded_memory(scene):
    """Ten million points (the scene tiled 33 times, 1 mm noise): labelled like any cloud,
    with the segmenter's working memory far below the input's size times ten (measured:
    about 40 MiB above the 120 MB input on a 2-core machine)."""
    flat = scene.points.reshape(-1, 3)
    reps = -(-10_000_000 // flat.shape[0])
    big = np.tile(flat, (reps, 1))[:10_000_000]
    big += np.random.default_rng(0).normal(0, 0.001, big.shape).astype(np.float32)
    seg = clutterseg.Segmenter(threads=2)
    before = proc_kib("VmHWM")
    r = seg.segment(big)
    grown = proc_kib("VmHWM") - before
    check_result(r, (10_000_000,))
    assert len(r.objects) > 0
    assert grown < 10 * big.nbytes // 1024, f"peak RSS grew by {grown} KiB"
    # The same segmenter still gives a fresh segmenter's labels on an ordinary frame.
    assert np.array_equal(seg.segment(scene.points).labels,
                          clutterseg.Segmenter(threads=1).segment(scene.points).labels)


def test_points_beyond_the_frame_limit_are_refused_before_allocating(seg):
    # 4097 x 4097 pixels: over the 4096 x 4096 frame limit; a broadcast array costs nothing.
    huge = np.broadcast_to(np.float32([0, 0, 1]), (4097, 4097, 3))
    with pytest.raises(ValueError, match="points: .*exceeds"):
        seg.segment(huge)
    flat = np.broadcast_to(np.float32([0, 0, 1]), (4096 * 4096 + 1, 3))
    with pytest.raises(ValueError, match="points: "):
        seg.segment(flat)


def test_repeated_hostile_calls_do_not_grow_memory(seg, scene):
    inputs = [np.full((480, 640, 3), np.nan, np.float32),
              np.full((480, 640, 3), 1e30, np.float32), scene.points,
              np.zeros((0, 3), np.float32), np.asfortranarray(scene.points)]
    for p in inputs:  # warm-up: the segmenter's buffers reach their size
        seg.segment(p)
    before = proc_kib("VmRSS")
    for _ in range(10):
        for p in inputs:
            seg.segment(p)
        for bad in (np.zeros((10, 2), np.float32), np.zeros((10, 3), np.float64)):
            with pytest.raises((TypeError, ValueError), match="points"):
                seg.segment(bad)
    grown = proc_kib("VmRSS") - before
    assert grown < 64 * 1024, f"RSS grew by {grown} KiB over 50 frames and 20 refusals"
