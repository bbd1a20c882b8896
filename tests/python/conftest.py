"""Shared fixtures of the Python module's tests (tests/python, run by ctest as python.*).

Environment (ctest sets all of them; by hand only PYTHONPATH is needed when the build is
build/release):
  PYTHONPATH               the build's package directory (<build>/python)
  CLUTTERSEG_TOOLS_DIR     clutterseg-segment, -eval, -synth (default <source>/build/release/tools)
  CLUTTERSEG_TEST_WORK     where generated clouds and tool outputs go (default: pytest's tmp)
  CLUTTERSEG_DATA          real data root (test_realdata.py only)
"""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import clutterseg

SOURCE_DIR = pathlib.Path(__file__).resolve().parents[2]


def tools_dir():
    return pathlib.Path(os.environ.get("CLUTTERSEG_TOOLS_DIR",
                                       SOURCE_DIR / "build" / "release" / "tools"))


def run_tool(name, *args):
    """Runs a clutterseg program of the build; returns its stdout, fails the test on error."""
    exe = tools_dir() / name
    if not exe.exists():
        pytest.fail(f"{exe} not built (cmake --build --preset release --target {name})")
    proc = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True,
                          timeout=600)
    if proc.returncode != 0:
        pytest.fail(f"{name} {' '.join(map(str, args))} exited {proc.returncode}:\n"
                    f"{proc.stderr}")
    return proc.stdout


def last_json_line(text):
    return json.loads(text.strip().splitlines()[-1])


@pytest.fixture(scope="session")
def work_dir(tmp_path_factory):
    root = os.environ.get("CLUTTERSEG_TEST_WORK")
    if root:
        path = pathlib.Path(root)
        path.mkdir(parents=True, exist_ok=True)
        return path
    return tmp_path_factory.mktemp("clutterseg-python")


@pytest.fixture(scope="session")
def synth_dir(work_dir):
    """Two labelled synthetic tabletop scenes written by clutterseg-synth (PCD + PNGs)."""
    out = work_dir / "synth"
    run_tool("clutterseg-synth", "--out", out, "--count", 2, "--seed", 11, "--png")
    return out


def segment_with_tool(work_dir, pcd, tag, *extra):
    """clutterseg-segment on `pcd`: returns (labels read back, objects JSON)."""
    out = work_dir / f"{tag}.seg.pcd"
    js = work_dir / f"{tag}.seg.json"
    run_tool("clutterseg-segment", pcd, out, "--json", js, "--force", "--quiet", *extra)
    cloud = clutterseg.read_pcd(str(out))
    return cloud.labels, json.loads(js.read_text())


def shuffled(points, colors, seed):
    """The points (and colours) of a cloud in a seeded random order, as (N, 3) arrays."""
    order = np.random.default_rng(seed).permutation(points.shape[0] * points.shape[1])
    p = np.ascontiguousarray(points.reshape(-1, 3)[order])
    c = None if colors is None else np.ascontiguousarray(colors.reshape(-1, 3)[order])
    return p, c
