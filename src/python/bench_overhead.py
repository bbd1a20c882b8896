#!/usr/bin/env python3
"""Overhead of the Python module over the C++ call, per frame (not a test).

For each frame: the wall time of Segmenter.segment() as Python sees it, minus the wall time of
the C++ Segmenter::Process inside it (SegmentationResult.times['total']). The difference is
what the binding adds: argument checks, packing the colours into the pipeline's rgba (the
points are read in place), handing the labels over to numpy and building the result objects.

Usage: bench_overhead.py [--frames N] [--threads T] [CLOUD.pcd]
Without a cloud, a 640x480 synthetic scene is made with clutterseg-synth (from
$CLUTTERSEG_TOOLS_DIR, or build/release/tools of this checkout). Run with the build's package
on PYTHONPATH, e.g. `cmake --build --preset release --target clutterseg_python_bench`.
"""
import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

import clutterseg


def synth_cloud(tmp):
    tools = pathlib.Path(os.environ.get(
        "CLUTTERSEG_TOOLS_DIR",
        pathlib.Path(__file__).resolve().parents[1] / "build" / "release" / "tools"))
    subprocess.run([str(tools / "clutterseg-synth"), "--out", tmp, "--count", "1", "--seed", "3"],
                   check=True, capture_output=True)
    return pathlib.Path(tmp) / "scene_0000.pcd"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cloud", nargs="?", help="a PCD (default: a synthetic 640x480 scene)")
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = args.cloud or synth_cloud(tmp)
        cloud = clutterseg.read_pcd(str(path))
    seg = clutterseg.Segmenter(threads=args.threads)
    print(f"{path}: {cloud.points.shape}, threads={args.threads}, {args.frames} frames")
    for name, colors in (("points + colours", cloud.colors), ("points only", None)):
        for _ in range(5):  # buffers grown
            seg.segment(cloud.points, colors)
        over, total = [], []
        for _ in range(args.frames):
            t0 = time.perf_counter()
            r = seg.segment(cloud.points, colors)
            wall_ms = 1000.0 * (time.perf_counter() - t0)
            over.append(wall_ms - r.times["total"])
            total.append(r.times["total"])
        o = np.array(over)
        print(f"  {name:17s} overhead per frame: median {np.median(o):.3f} ms, "
              f"p90 {np.percentile(o, 90):.3f} ms, min {o.min():.3f} ms "
              f"(C++ call: median {np.median(total):.1f} ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
