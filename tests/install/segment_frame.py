#!/usr/bin/env python3
"""Segments a PCD with the installed Python module and compares the labels with those of the
installed clutterseg-segment (check_install.sh).

Usage: segment_frame.py ROOT CLOUD.pcd TOOL_OUTPUT.pcd
ROOT: the staging root; the module must be imported from under it, never from a build tree.
"""
import sys

import numpy as np

import clutterseg


def main():
    root, cloud_path, tool_path = sys.argv[1:4]
    core_file = clutterseg._core.__file__
    if not core_file.startswith(root):
        sys.exit(f"clutterseg._core imported from {core_file}, not from the staged {root}")
    cloud = clutterseg.read_pcd(cloud_path)
    result = clutterseg.Segmenter().segment(cloud.points, cloud.colors)
    tool = clutterseg.read_pcd(tool_path)
    if not np.array_equal(result.labels, tool.labels):
        sys.exit(f"labels differ from clutterseg-segment's on "
                 f"{np.count_nonzero(result.labels != tool.labels)} points")
    if not result.objects:
        sys.exit("no object segmented")
    print(f"python: {len(result.objects)} objects, labels equal to clutterseg-segment's")


if __name__ == "__main__":
    main()
