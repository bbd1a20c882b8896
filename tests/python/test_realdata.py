"""The Python module on real mOSD frames (ctest label realdata): organized, and shuffled into
unorganized clouds, give exactly the labels of clutterseg-segment; evaluate() gives the
scores of clutterseg-eval under the mOSD conventions.

Data: where tools/data_root.sh finds it ($CLUTTERSEG_DATA, <source>/data, <source>/../shared/data;
a data root without the frames below fails). Without any, every test is
skipped with a message naming tools/fetch_data.sh."""
import pathlib
import subprocess

import numpy as np
import pytest

import clutterseg
from conftest import SOURCE_DIR, last_json_line, run_tool, segment_with_tool, shuffled

# One frame of each category of the learn split: boxes, stacked boxes, occluded, cylinders.
FRAMES = [0, 20, 28, 40]


def data_root():
    """The real data root as every test finds it (tools/data_root.sh: $CLUTTERSEG_DATA when
    set, else <source>/data, else <source>/../shared/data), or None when none exists."""
    found = subprocess.run(["bash", str(SOURCE_DIR / "tools" / "data_root.sh")],
                           capture_output=True, text=True, check=False)
    return pathlib.Path(found.stdout.strip()) if found.returncode == 0 else None


@pytest.fixture(scope="module")
def mosd_learn():
    root = data_root()
    if root is None:
        pytest.skip("no real data found (CLUTTERSEG_DATA, <source>/data, <source>/../shared/data);"
                    " fetch it with tools/fetch_data.sh")
    return root / "mosd-learn"


def frame_path(mosd_learn, n):
    path = mosd_learn / f"learn{n}.pcd"
    if not path.is_file():
        pytest.fail(f"{path} missing from the data root {mosd_learn.parent}")
    return path


@pytest.mark.parametrize("n", FRAMES)
def test_organized_frame_matches_clutterseg_segment(mosd_learn, work_dir, n):
    path = frame_path(mosd_learn, n)
    cloud = clutterseg.read_pcd(str(path))
    assert cloud.organized and cloud.points.shape == (480, 640, 3)
    tool_labels, tool_json = segment_with_tool(work_dir, path, f"learn{n}")
    r = clutterseg.Segmenter().segment(cloud.points, cloud.colors)
    assert np.array_equal(r.labels, tool_labels)
    assert len(r.objects) == len(tool_json["objects"]) >= 1
    assert [o.num_points for o in r.objects] == [o["num_points"] for o in tool_json["objects"]]


@pytest.mark.parametrize("n", FRAMES)
def test_shuffled_unorganized_frame_matches_clutterseg_segment(mosd_learn, work_dir, n):
    cloud = clutterseg.read_pcd(str(frame_path(mosd_learn, n)))
    points, colors = shuffled(cloud.points, cloud.colors, seed=n)
    pcd = work_dir / f"learn{n}_shuffled.pcd"
    clutterseg.write_pcd(str(pcd), points, colors)
    tool_labels, _ = segment_with_tool(work_dir, pcd, f"learn{n}_shuffled")
    r = clutterseg.Segmenter().segment(points, colors)
    assert r.labels.shape == (640 * 480,)
    assert np.array_equal(r.labels, tool_labels)
    assert len(r.objects) >= 1


@pytest.mark.parametrize("convention", ["mosd-parts", "mosd-objects"])
def test_evaluate_equals_clutterseg_eval_on_a_real_frame(mosd_learn, work_dir, convention):
    path = frame_path(mosd_learn, FRAMES[0])
    cloud = clutterseg.read_pcd(str(path))
    r = clutterseg.Segmenter().segment(cloud.points, cloud.colors)
    pred = work_dir / "learn_pred.pcd"
    clutterseg.write_pcd(str(pred), cloud.points, cloud.colors, r.labels)
    tool = last_json_line(run_tool("clutterseg-eval", path, pred, "--gt-convention", convention,
                                   "--quiet"))
    m = clutterseg.evaluate(cloud.labels, r.labels, cloud.points, gt_convention=convention)
    for key in ("wov", "precision", "recall", "f1"):
        assert getattr(m, key) == pytest.approx(tool[key], rel=1e-9, abs=1e-12), key
    assert m.f1 > 0.5
