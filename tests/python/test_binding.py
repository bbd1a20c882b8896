"""The Python module on clouds the project makes itself (clutterseg-synth, arrays built here):
equality with clutterseg-segment and clutterseg-eval, argument errors, threads and the GIL,
segment_depth, PCD round trips. Needs no real data."""
import math
import pydoc
import struct
import threading
import time
import zlib

import numpy as np
import pytest

import clutterseg
from conftest import (SOURCE_DIR, last_json_line, run_tool, segment_with_tool, shuffled)


@pytest.fixture(scope="module")
def scene(synth_dir):
    return clutterseg.read_pcd(str(synth_dir / "scene_0000.pcd"))


@pytest.fixture(scope="module")
def scene1(synth_dir):
    return clutterseg.read_pcd(str(synth_dir / "scene_0001.pcd"))


# ---- the same labels as clutterseg-segment ------------------------------------------------

def test_organized_scene_matches_clutterseg_segment(synth_dir, work_dir, scene):
    tool_labels, tool_json = segment_with_tool(work_dir, synth_dir / "scene_0000.pcd", "synth0")
    r = clutterseg.Segmenter().segment(scene.points, scene.colors)
    assert r.labels.dtype == np.uint32 and r.labels.shape == (480, 640)
    assert np.array_equal(r.labels, tool_labels)
    assert len(r.objects) == len(tool_json["objects"]) >= 2
    for ours, theirs in zip(r.objects, tool_json["objects"]):
        assert ours.id == theirs["id"]
        assert ours.num_points == theirs["num_points"] == np.count_nonzero(r.labels == ours.id)
        assert ours.centroid == pytest.approx(theirs["centroid"], rel=1e-6)
        assert ours.aabb_min == pytest.approx(theirs["aabb_min"], rel=1e-6)
        assert ours.obb_axes.shape == (3, 3)
        assert ours.support_plane_id == theirs["support_plane_id"]
        assert ours.has_gravity_box == (ours.support_plane_id >= 0)
        if ours.has_gravity_box:  # upright on its plane: the third axis is the plane's normal
            plane = next(p for p in r.planes if p.id == ours.support_plane_id)
            assert abs(float(np.dot(ours.gbox_axes[2], plane.normal))) > np.cos(np.radians(1.0))
            assert ours.gbox_extents[2] == pytest.approx(ours.height_m) and ours.height_m > 0
    assert [p.id for p in r.planes] == [p["id"] for p in tool_json["planes"]]
    assert any(p.is_support for p in r.planes)
    assert r.num_valid_points == tool_json["num_valid_points"]
    assert r.num_supervoxels == tool_json["num_supervoxels"]
    assert set(r.times) == set(tool_json["times_ms"]) | {"total"}
    assert r.times["total"] > 0


def test_unorganized_scene_matches_clutterseg_segment(work_dir, scene):
    points, colors = shuffled(scene.points, scene.colors, seed=7)
    pcd = work_dir / "synth0_shuffled.pcd"
    clutterseg.write_pcd(str(pcd), points, colors)
    tool_labels, _ = segment_with_tool(work_dir, pcd, "synth0_shuffled")
    r = clutterseg.Segmenter().segment(points, colors)
    assert r.labels.shape == (points.shape[0],)
    assert np.array_equal(r.labels, tool_labels)
    assert len(r.objects) >= 2


def test_thread_count_does_not_change_labels(scene1):
    one = clutterseg.Segmenter(threads=1).segment(scene1.points, scene1.colors)
    two = clutterseg.Segmenter(threads=2).segment(scene1.points, scene1.colors)
    assert np.array_equal(one.labels, two.labels)


def test_non_contiguous_arrays_give_the_same_labels(scene1):
    seg = clutterseg.Segmenter(threads=1)
    ref = seg.segment(scene1.points, scene1.colors).labels
    fortran = np.asfortranarray(scene1.points)
    assert not fortran.flags.c_contiguous
    assert np.array_equal(seg.segment(fortran, np.asfortranarray(scene1.colors)).labels, ref)
    # A strided view: every other row of a twice-as-tall array.
    tall = np.repeat(scene1.points, 2, axis=0)[::2]
    assert not tall.flags.c_contiguous
    assert np.array_equal(seg.segment(tall, scene1.colors).labels, ref)


def test_unaligned_points_are_copied_not_viewed(scene1):
    seg = clutterseg.Segmenter(threads=1)
    ref = seg.segment(scene1.points).labels
    raw = np.zeros(scene1.points.nbytes + 1, np.uint8)
    raw[1:] = np.frombuffer(scene1.points.tobytes(), np.uint8)
    unaligned = np.frombuffer(raw.data, np.float32, offset=1).reshape(scene1.points.shape)
    assert not unaligned.flags.aligned and unaligned.flags.c_contiguous
    assert np.array_equal(seg.segment(unaligned).labels, ref)


def test_result_is_a_snapshot(scene, scene1):
    seg = clutterseg.Segmenter(threads=1)
    first = seg.segment(scene.points, scene.colors)
    kept = first.labels.copy()
    seg.segment(scene1.points, scene1.colors)
    assert np.array_equal(first.labels, kept)


def test_segment_depth_matches_clutterseg_segment_on_a_depth_png(synth_dir, work_dir, scene):
    # Depth in millimetres from the scene's z, written as a 16-bit PNG for the tool.
    z = scene.points[:, :, 2]
    depth = np.where(np.isfinite(z), np.round(z * 1000.0), 0).astype(np.uint16)
    png = work_dir / "synth0_depth.png"
    write_png16(png, depth)
    tool_labels, _ = segment_with_tool(work_dir, png, "synth0_depth", "--intrinsics",
                                       synth_dir / "intrinsics.json")
    k = {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5}
    r = clutterseg.Segmenter().segment_depth(depth, k)
    assert r.labels.shape == (480, 640)
    assert np.array_equal(r.labels, tool_labels)
    assert len(r.objects) >= 2
    # Intrinsics as an object, and a depth image of another size refused.
    r2 = clutterseg.Segmenter(threads=1).segment_depth(depth, clutterseg.Intrinsics())
    assert np.array_equal(r2.labels, r.labels)
    with pytest.raises(ValueError, match="intrinsics are for 640x480"):
        clutterseg.Segmenter(threads=1).segment_depth(depth[:240], clutterseg.Intrinsics())


def write_png16(path, image):
    """A 16-bit greyscale PNG, standard library only."""
    h, w = image.shape
    raw = b"".join(b"\x00" + image[v].astype(">u2").tobytes() for v in range(h))

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    path.write_bytes(b"\x89PNG\r\n\x1a\n" +
                     chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)) +
                     chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


# ---- evaluate equals clutterseg-eval ------------------------------------------------------

@pytest.mark.parametrize("convention", clutterseg.GT_CONVENTIONS)
def test_evaluate_equals_clutterseg_eval(work_dir, scene, convention):
    r = clutterseg.Segmenter().segment(scene.points, scene.colors)
    pred = work_dir / "synth0_pred.pcd"
    clutterseg.write_pcd(str(pred), scene.points, scene.colors, r.labels)
    gt_pcd = work_dir / "synth0_gt.pcd"
    # Ground truth with a raw label that each convention maps differently.
    gt = scene.labels * np.uint32(10) + np.uint32(1) * (scene.labels > 0)
    clutterseg.write_pcd(str(gt_pcd), scene.points, scene.colors, gt)
    tool = last_json_line(run_tool("clutterseg-eval", gt_pcd, pred, "--gt-convention",
                                   convention, "--quiet"))
    m = clutterseg.evaluate(gt, r.labels, scene.points, gt_convention=convention)
    assert m.scored
    for key in ("wov", "precision", "recall", "f1", "tp", "fp", "fn", "loss_merged",
                "loss_split", "loss_boundary", "loss_background"):
        assert getattr(m, key) == pytest.approx(tool[key], rel=1e-9, abs=1e-12), key
    assert m.num_gt_objects == tool["gt_objects"]
    assert m.num_segments == tool["segments"]
    assert 0.0 < m.f1 <= 1.0


def test_evaluate_perfect_and_empty_predictions(scene):
    gt = scene.labels
    perfect = clutterseg.evaluate(gt, gt, scene.points)
    assert perfect.wov == 1.0 and perfect.f1 == 1.0
    assert len(perfect.objects) == perfect.num_gt_objects > 0
    empty = clutterseg.evaluate(gt, np.zeros_like(gt), scene.points)
    assert empty.f1 == 0.0 and empty.recall == 0.0
    # Without points every point counts; int64 labels are accepted.
    assert clutterseg.evaluate(gt.astype(np.int64), gt).wov == 1.0


def test_map_gt_labels_follows_the_conventions():
    raw = np.array([0, 1, 2, 5, 9, 10, 23, 27, 31], dtype=np.uint32)
    assert clutterseg.map_gt_labels(raw, "plain").tolist() == [0, 1, 2, 5, 9, 10, 23, 27, 31]
    assert clutterseg.map_gt_labels(raw, "mosd-parts").tolist() == [0, 0, 0, 0, 0, 10, 23, 27, 31]
    assert clutterseg.map_gt_labels(raw, "mosd-objects").tolist() == [0, 0, 0, 0, 0, 1, 2, 2, 3]
    assert clutterseg.map_gt_labels(raw, "ocid").tolist() == [0, 0, 0, 5, 9, 10, 23, 27, 31]
    assert clutterseg.map_gt_labels(raw, "ocid", ocid_background=[0, 5]).tolist()[:4] == [0, 1, 2, 0]


# ---- PCD ------------------------------------------------------------------------------------

@pytest.mark.parametrize("encoding", ["binary", "binary_compressed", "ascii"])
def test_pcd_round_trip(work_dir, scene, encoding):
    path = work_dir / f"round_trip_{encoding}.pcd"
    clutterseg.write_pcd(str(path), scene.points, scene.colors, scene.labels, encoding=encoding)
    back = clutterseg.read_pcd(str(path))
    assert back.organized and back.points.shape == (480, 640, 3)
    assert np.array_equal(back.points, scene.points, equal_nan=True)
    assert np.array_equal(back.colors, scene.colors)
    assert np.array_equal(back.labels, scene.labels)


def test_pcd_round_trip_unorganized_without_colour(work_dir):
    pts = np.random.default_rng(1).uniform(-1, 1, (1000, 3)).astype(np.float32)
    pts[::7] = np.nan
    path = work_dir / "unorganized.pcd"
    clutterseg.write_pcd(str(path), pts)
    back = clutterseg.read_pcd(str(path))
    assert not back.organized and back.points.shape == (1000, 3)
    assert np.array_equal(back.points, pts, equal_nan=True)
    # write_pcd writes rgba and label fields (PointXYZRGBL): white-less black, label 0.
    assert back.labels is not None and not back.labels.any()


# ---- threads and the GIL -------------------------------------------------------------------

def test_gil_is_released_while_segmenting(scene):
    seg = clutterseg.Segmenter(threads=1)
    seg.segment(scene.points, scene.colors)  # buffers grown

    def ticks_in_the_middle_of_a_call():
        window = {}
        ticks = []
        done = threading.Event()

        def work():
            t0 = time.perf_counter()
            seg.segment(scene.points, scene.colors)
            window["call"] = (t0, time.perf_counter())
            done.set()

        worker = threading.Thread(target=work)
        worker.start()
        while not done.is_set():
            ticks.append(time.perf_counter())
        worker.join()
        t0, t1 = window["call"]
        return [t for t in ticks if t0 + 0.25 * (t1 - t0) < t < t1 - 0.25 * (t1 - t0)]

    # With the GIL held for the whole call this thread could never run in its middle half; a
    # busy machine may leave it unscheduled there once, so a few calls are tried.
    assert any(ticks_in_the_middle_of_a_call() for _ in range(5)), \
        "no Python ran during the middle half of 5 segment calls: the GIL is held"


def test_one_segmenter_per_thread_and_one_shared(scene, scene1):
    frames = [scene, scene1]
    expected = [clutterseg.Segmenter(threads=1).segment(f.points, f.colors).labels for f in frames]
    results, errors = {}, []
    shared = clutterseg.Segmenter(threads=1)

    def work(i, seg):
        try:
            for rep in range(2):
                f = frames[(i + rep) % 2]
                results[(i, rep)] = ((i + rep) % 2, seg.segment(f.points, f.colors).labels)
        except Exception as e:  # reported below, on the main thread
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i, clutterseg.Segmenter(threads=1)))
               for i in range(2)]
    threads += [threading.Thread(target=work, args=(i, shared)) for i in range(2, 5)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=600)
    assert not errors
    assert len(results) == 10
    for which, labels in results.values():
        assert np.array_equal(labels, expected[which])


# ---- parameters -----------------------------------------------------------------------------

def test_overrides_dotted_nested_and_config_file(scene1):
    dotted = clutterseg.Segmenter(**{"supervoxel.seed_resolution_m": 0.02,
                                     "segmenter.objects.min_object_points": 50})
    nested = clutterseg.Segmenter(supervoxel={"seed_resolution_m": 0.02},
                                  objects={"min_object_points": np.int64(50)})
    assert dotted.params == nested.params
    assert dotted.params["supervoxel.seed_resolution_m"] == "0.02"
    assert "supervoxel.seed_resolution_m" in clutterseg.Segmenter.keys()
    from_file = clutterseg.Segmenter(str(SOURCE_DIR / "config" / "clutterseg.yaml"))
    assert from_file.params == clutterseg.Segmenter().params
    # An override changes the segmentation: no object may have that many points.
    none = clutterseg.Segmenter(objects={"min_object_points": 10_000_000, "max_objects": 5})
    assert none.segment(scene1.points, scene1.colors).objects == []


def test_config_file_errors_name_the_file_and_key(work_dir):
    with pytest.raises(FileNotFoundError, match="config"):
        clutterseg.Segmenter(str(work_dir / "missing.yaml"))
    bad = work_dir / "bad.yaml"
    bad.write_text("segmenter:\n  supervoxel:\n    seed_resolution_mm: 0.02\n")
    with pytest.raises(ValueError, match="seed_resolution_mm"):
        clutterseg.Segmenter(str(bad))


@pytest.mark.parametrize("overrides, error, words", [
    ({"supervoxel.seed_resolution": 0.02}, KeyError, "seed_resolution_m"),
    ({"nosuchsection": {"x": 1}}, KeyError, "nosuchsection"),
    ({"supervoxel.seed_resolution_m": 5.0}, ValueError, "seed_resolution_m = 5"),
    ({"supervoxel.seed_resolution_m": "far"}, ValueError, "seed_resolution_m"),
    ({"objects.min_object_points": 2.5}, ValueError, "min_object_points"),
    ({"objects.min_object_points": [1]}, TypeError, "min_object_points"),
    ({"points.min_depth_m": -1.0}, ValueError, "min_depth_m"),
])
def test_bad_parameters_raise_naming_the_key(overrides, error, words):
    with pytest.raises(error, match=words):
        clutterseg.Segmenter(**overrides)


def test_bad_threads():
    with pytest.raises(ValueError, match="threads"):
        clutterseg.Segmenter(threads=-1)


# ---- bad inputs -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def seg():
    return clutterseg.Segmenter(threads=1)


@pytest.mark.parametrize("points, error, words", [
    (np.zeros((480, 640, 3), np.float64), TypeError, "points must have dtype float32"),
    (np.zeros((480, 640, 3), np.int32), TypeError, "points must have dtype float32"),
    ([[0.0, 0.0, 1.0]], TypeError, "points must be a numpy array"),
    (np.zeros((480, 640), np.float32), ValueError, r"points must have shape .*\(480, 640\)"),
    (np.zeros((10, 4), np.float32), ValueError, "points must have shape"),
    (np.zeros((2, 2, 2, 3), np.float32), ValueError, "points must have shape"),
    (np.zeros((5000, 5000, 3), np.float32)[:, :, :], ValueError, "points: .*exceeds"),
])
def test_bad_points(seg, points, error, words):
    with pytest.raises(error, match=words):
        seg.segment(points)


def test_bad_colors_and_intrinsics(seg, scene):
    p = scene.points
    with pytest.raises(TypeError, match="colors must have dtype uint8"):
        seg.segment(p, scene.colors.astype(np.float32))
    with pytest.raises(ValueError, match=r"colors must have shape \(480, 640\)"):
        seg.segment(p, scene.colors[:100])
    with pytest.raises(ValueError, match="colors must have shape"):
        seg.segment(p, np.zeros((480, 640, 4), np.uint8))
    with pytest.raises(ValueError, match="intrinsics.fx"):
        seg.segment(p, intrinsics={"fx": 0.0, "fy": 525, "cx": 319.5, "cy": 239.5})
    with pytest.raises(KeyError, match="missing 'cy'"):
        seg.segment(p, intrinsics={"fx": 525, "fy": 525, "cx": 319.5})
    with pytest.raises(KeyError, match="unknown key 'f'"):
        seg.segment(p, intrinsics={"f": 525, "fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5})
    with pytest.raises(TypeError, match="intrinsics must be"):
        seg.segment(p, intrinsics=(525, 525, 319.5, 239.5))
    with pytest.raises(ValueError, match="intrinsics.fx"):
        clutterseg.Intrinsics(fx=1e6)
    # Intrinsics of another resolution are scaled, as clutterseg-segment does.
    half = clutterseg.Intrinsics().scaled(320, 240)
    assert np.array_equal(seg.segment(p, scene.colors, half).labels,
                          seg.segment(p, scene.colors).labels)


def test_bad_depth_and_eval_and_pcd_arguments(seg, work_dir, scene):
    k = clutterseg.Intrinsics()
    with pytest.raises(TypeError, match="depth_mm must have dtype uint16"):
        seg.segment_depth(np.zeros((480, 640), np.float32), k)
    with pytest.raises(ValueError, match=r"depth_mm must have shape \(H, W\)"):
        seg.segment_depth(np.zeros((480, 640, 1), np.uint16), k)
    with pytest.raises(ValueError, match="intrinsics are required"):
        seg.segment_depth(np.zeros((480, 640), np.uint16), None)
    with pytest.raises(ValueError, match="colors must have shape"):
        seg.segment_depth(np.zeros((480, 640), np.uint16), k, np.zeros((480, 640), np.uint8))
    labels = np.zeros((480, 640), np.uint32)
    with pytest.raises(ValueError, match="same shape"):
        clutterseg.evaluate(labels, labels[:10])
    with pytest.raises(ValueError, match="gt_labels holds negative"):
        clutterseg.evaluate(np.full((4,), -1, np.int32), np.zeros(4, np.uint32))
    with pytest.raises(TypeError, match="labels must have an integer dtype"):
        clutterseg.evaluate(labels, labels.astype(np.float32))
    with pytest.raises(ValueError, match="mosd"):
        clutterseg.evaluate(labels, labels, gt_convention="mosd")
    with pytest.raises(ValueError, match="coverage_percent"):
        clutterseg.evaluate(labels, labels, coverage_percent=0)
    with pytest.raises(ValueError, match="one point per label"):
        clutterseg.evaluate(labels, labels, scene.points[:10])
    with pytest.raises(FileNotFoundError, match="missing.pcd"):
        clutterseg.read_pcd(str(work_dir / "missing.pcd"))
    junk = work_dir / "junk.pcd"
    junk.write_bytes(b"not a point cloud\n" * 10)
    with pytest.raises(RuntimeError, match="junk.pcd"):
        clutterseg.read_pcd(str(junk))
    with pytest.raises(RuntimeError, match="no/such/dir"):
        clutterseg.write_pcd(str(work_dir / "no/such/dir/x.pcd"), scene.points)
    with pytest.raises(ValueError, match="encoding"):
        clutterseg.write_pcd(str(work_dir / "x.pcd"), scene.points, encoding="zip")
    with pytest.raises(ValueError, match="labels must have shape"):
        clutterseg.write_pcd(str(work_dir / "x.pcd"), scene.points, labels=labels[:5])


def test_degenerate_frames_give_empty_results(seg):
    for points in (np.full((480, 640, 3), np.nan, np.float32), np.zeros((0, 3), np.float32),
                   np.zeros((1, 3), np.float32), np.ones((100, 3), np.float32)):
        r = seg.segment(points)
        assert r.objects == [] and r.labels.shape == points.shape[:-1]
        assert not r.labels.any()


# ---- documentation --------------------------------------------------------------------------

def test_help_documents_every_argument_with_units():
    text = pydoc.render_doc(clutterseg.Segmenter, renderer=pydoc.plaintext)
    for word in ("config", "threads", "overrides", "points", "colors", "intrinsics",
                 "depth_mm", "metres", "millimetres", "pixels", "Thread-safety", "GIL",
                 "float32", "uint8", "uint16", "(H, W, 3)", "(N, 3)"):
        assert word in text, word
    for fn in (clutterseg.read_pcd, clutterseg.write_pcd, clutterseg.evaluate):
        assert "metres" in fn.__doc__ or "PCD" in fn.__doc__
    assert "gt_convention" in clutterseg.evaluate.__doc__
    assert clutterseg.__version__.count(".") == 2
    assert math.isfinite(0.0)
