#!/usr/bin/env python3
"""Cross-checks clutterseg-eval against reference_metrics.py (ctest eval_python_cross_check).

Generates ground-truth / prediction PCD pairs (merges, splits, leakage, missed objects,
label noise, NaN points, ties, every ground-truth convention, every PCD encoding), scores
them with both implementations and requires agreement to 1e-6 on the ratios and exact
agreement on the counts. Also checks the tool's exit codes and error messages, and, when the
shared mOSD data is present, agreement on real frames.
"""

import argparse
import importlib.util
import json
import math
import os
import random
import shutil
import struct
import subprocess
import sys

RATIO_KEYS = ("wov", "precision", "recall", "f1", "tp", "fp", "fn", "loss_merged", "loss_split",
              "loss_boundary", "loss_background")
COUNT_KEYS = ("frames", "frames_scored", "missing", "gt_objects", "segments",
              "over_segmented", "under_segmented")
NAN = float("nan")

failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
        print("FAIL: " + message)


# ----------------------------------------------------------------------------- PCD writing

def lzf_literals(raw):
    """A valid LZF stream made of literal runs only (what the format allows for any input)."""
    out = bytearray()
    for start in range(0, len(raw), 32):
        chunk = raw[start:start + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def write_pcd(path, width, height, xyz, labels, encoding="binary", layout="xyzrgbal",
              with_label=True):
    n = width * height
    assert len(xyz) == n and len(labels) == n
    if layout == "xyzrgbal":
        fields = [("x", "F"), ("y", "F"), ("z", "F"), ("rgba", "U"), ("label", "U")]
    else:  # the mOSD files' order
        fields = [("label", "U"), ("x", "F"), ("y", "F"), ("z", "F"), ("rgba", "U")]
    if not with_label:
        fields = [f for f in fields if f[0] != "label"]

    def value(name, k):
        if name == "label":
            return labels[k]
        if name == "rgba":
            return 0xFF808080
        return xyz[k]["xyz".index(name)]

    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
              "FIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\nHEIGHT %d\n"
              "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n" % (
                  " ".join(f[0] for f in fields), " ".join("4" for _ in fields),
                  " ".join(f[1] for f in fields), " ".join("1" for _ in fields),
                  width, height, n, encoding))
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        if encoding == "ascii":
            lines = []
            for k in range(n):
                parts = []
                for name, typ in fields:
                    v = value(name, k)
                    parts.append(("nan" if math.isnan(v) else repr(v)) if typ == "F" else str(v))
                lines.append(" ".join(parts))
            f.write(("\n".join(lines) + "\n").encode("ascii"))
        elif encoding == "binary":
            fmt = "<" + "".join("f" if t == "F" else "I" for _, t in fields)
            f.write(b"".join(struct.pack(fmt, *[value(name, k) for name, _ in fields])
                             for k in range(n)))
        else:
            raw = b"".join(struct.pack("<%d%s" % (n, "f" if t == "F" else "I"),
                                       *[value(name, k) for k in range(n)]) for name, t in fields)
            comp = lzf_literals(raw)
            f.write(struct.pack("<II", len(comp), len(raw)) + comp)


# ----------------------------------------------------------------------------- scenes

def background_label(rng, convention):
    if convention in ("mosd-parts", "mosd-objects"):
        return rng.choice([0, 1, 1, 1, 2, 3])
    if convention == "ocid":
        return rng.choice([0, 1, 2])
    return 0


def make_scene(rng, convention, width, height):
    """Returns (xyz, gt_raw, object_of_point) with object_of_point the mapped object id."""
    n = width * height
    gt = [background_label(rng, convention) for _ in range(n)]
    num_objects = rng.randint(0 if rng.random() < 0.1 else 1, 6)
    base = rng.choice([1, 1000, 70000])  # plain labels need not be small
    for obj in range(num_objects):
        w = rng.randint(2, max(2, width // 2))
        h = rng.randint(2, max(2, height // 2))
        u0 = rng.randint(0, width - w)
        v0 = rng.randint(0, height - h)
        split = rng.random() < 0.4
        for v in range(v0, v0 + h):
            for u in range(u0, u0 + w):
                part = 1 if split and u >= u0 + w // 2 else 0
                if convention in ("mosd-parts", "mosd-objects"):
                    label = 10 * (obj + 2) + part
                elif convention == "ocid":
                    label = 3 + 2 * obj + part
                else:
                    label = base + 2 * obj + part
                gt[v * width + u] = label
    xyz = []
    nan_block = rng.random() < 0.5
    bu, bv = rng.randint(0, width - 1), rng.randint(0, height - 1)
    for k in range(n):
        u, v = k % width, k // width
        invalid = rng.random() < 0.05 or (nan_block and abs(u - bu) < 4 and abs(v - bv) < 3)
        if invalid:
            which = rng.randint(0, 2)
            p = [0.1 * u, 0.1 * v, 1.0]
            p[which] = NAN if rng.random() < 0.8 else float("inf")
            if rng.random() < 0.5:
                p = [NAN, NAN, NAN]
            xyz.append(tuple(p))
            if rng.random() < 0.5:
                gt[k] = rng.choice([0, 1, 25, 31, 3])  # garbage on invalid points
        else:
            xyz.append((0.01 * u, 0.01 * v, 1.0 + 0.001 * rng.random()))
    return xyz, gt


def make_prediction(rng, gt, width, height):
    """Perturbs a copy of the raw ground truth into a plain prediction."""
    n = len(gt)
    ids = sorted(set(gt))
    remap = {}
    for i in ids:
        r = rng.random()
        if r < 0.15:
            remap[i] = 0                            # missed (or background kept as 0)
        elif r < 0.3 and remap:
            remap[i] = rng.choice(list(remap.values()))  # merged with another
        else:
            remap[i] = rng.randint(1, 40)
    pred = [remap[g] for g in gt]
    cut = rng.randint(0, width - 1)
    split_label = rng.randint(41, 60)
    # Split: points right of a column in one segment move to a new label.
    victim = rng.choice(list(remap.values()))
    for k in range(n):
        if pred[k] == victim and victim != 0 and k % width > cut:
            pred[k] = split_label
    # Leakage: shift some rows sideways by a few pixels.
    shift = rng.randint(-3, 3)
    for v in range(height):
        if rng.random() < 0.5:
            row = pred[v * width:(v + 1) * width]
            pred[v * width:(v + 1) * width] = row[-shift:] + row[:-shift] if shift else row
    # Label noise.
    for k in range(n):
        if rng.random() < 0.03:
            pred[k] = rng.choice([0, 1, 2, 77, split_label])
    return pred


# ----------------------------------------------------------------------------- runners

def run_tool(tool, args):
    return subprocess.run([tool] + args, capture_output=True, text=True)


def tool_json(tool, args):
    proc = run_tool(tool, args)
    check(proc.returncode == 0, "clutterseg-eval %s: exit %d, stderr %s"
          % (" ".join(args), proc.returncode, proc.stderr))
    if proc.returncode != 0:
        return None
    return json.loads(proc.stdout.strip().split("\n")[-1])


def compare(label, got, want):
    if got is None:
        return
    for key in RATIO_KEYS:
        a, b = got.get(key), want.get(key)
        if a is None or b is None:
            check(a is None and b is None, "%s: %s tool %r reference %r" % (label, key, a, b))
        else:
            check(abs(a - b) <= 1e-6, "%s: %s tool %r reference %r" % (label, key, a, b))
    for key in COUNT_KEYS:
        check(got.get(key) == want.get(key),
              "%s: %s tool %r reference %r" % (label, key, got.get(key), want.get(key)))
    check(got.get("convention") == want.get("convention"), label + ": convention differs")
    for name, result in (("tool", got), ("reference", want)):
        if result.get("wov") is not None:
            total = result["wov"] + sum(result[key] for key in RATIO_KEYS if key.startswith("loss_"))
            check(abs(total - 1.0) <= 1e-6, "%s: %s wov + losses = %r, not 1" % (label, name, total))


class RefArgs:
    def __init__(self, convention, ocid_background=(0, 1, 2), coverage_percent=10):
        self.gt_convention = convention
        self.ocid_background = list(ocid_background)
        self.coverage_percent = coverage_percent


def find_data_root(source_dir):
    """The real data sets' root as every test finds it (tools/data_root.sh: CLUTTERSEG_DATA,
    then the checkout's data/, then ../shared/data beside it), or None when none exists."""
    found = subprocess.run(["bash", os.path.join(source_dir, "tools", "data_root.sh")],
                           capture_output=True, text=True, check=False)
    return found.stdout.strip() if found.returncode == 0 else None


def real_frames(opt, ref):
    """Real mOSD frames (binary_compressed, read by clutterseg's own PCD reader): predict
    whole objects shifted by a few pixels and compare both conventions. Exit 77 (skipped)
    without any data, 1 when a data root lacks the frames."""
    data_dir = find_data_root(opt.source_dir)
    if data_dir is None:
        print("SKIP: real data not found (CLUTTERSEG_DATA, data/, ../shared/data): run "
              "tools/fetch_data.sh to fetch it")
        return 77
    os.makedirs(opt.workdir)
    mosd = os.path.join(data_dir, "mosd-learn")
    compared = 0
    for name in ("learn5.pcd", "learn27.pcd", "learn36.pcd"):
        gt_path = os.path.join(mosd, name)
        if not os.path.isfile(gt_path):
            print("FAIL: real data '%s' missing under %s: run tools/fetch_data.sh again"
                  % (os.path.join("mosd-learn", name), data_dir))
            return 1
        n, cols = ref.read_pcd(gt_path)
        width = 640
        pred = [0] * n
        for k, raw in enumerate(cols["label"]):
            if raw >= 10:
                target = k + 4 if (k % width) + 4 < width else k
                pred[target] = raw // 10
        pred_path = os.path.join(opt.workdir, "pred_" + name)
        xyz = list(zip(cols["x"], cols["y"], cols["z"]))
        write_pcd(pred_path, width, n // width, xyz, pred)
        for conv in ("mosd-parts", "mosd-objects"):
            got = tool_json(opt.tool, [gt_path, pred_path, "--gt-convention", conv, "-q"])
            want = ref.summarize([ref.score_files(gt_path, pred_path, RefArgs(conv))],
                                 RefArgs(conv), 0)
            compare("%s/%s" % (name, conv), got, want)
            compared += 1
            print("%s %s: wov %.4f f1 %.4f" % (name, conv, want["wov"], want["f1"]))
    print("%d comparisons, %d failures" % (compared, len(failures)))
    return 1 if failures else 0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--tool", required=True)
    parser.add_argument("--reference", required=True)
    parser.add_argument("--workdir", required=True)
    parser.add_argument("--source-dir", default="",
                        help="checkout whose data/ and ../shared/data are searched")
    parser.add_argument("--real-data", action="store_true",
                        help="compare on real mOSD frames only (ctest label realdata)")
    parser.add_argument("--scenes", type=int, default=24)
    opt = parser.parse_args()

    sys.dont_write_bytecode = True  # keep the source tree free of __pycache__
    spec = importlib.util.spec_from_file_location("reference_metrics", opt.reference)
    ref = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ref)

    shutil.rmtree(opt.workdir, ignore_errors=True)
    if opt.real_data:
        return real_frames(opt, ref)
    gt_dir = os.path.join(opt.workdir, "gt")
    pred_dir = os.path.join(opt.workdir, "pred")
    os.makedirs(gt_dir)
    os.makedirs(pred_dir)
    rng = random.Random(20261122)
    conventions = ["plain", "mosd-parts", "mosd-objects", "ocid"]
    encodings = ["binary", "ascii", "binary_compressed"]
    compared = 0

    # 1. Random scenes, one file pair each, every convention.
    for i in range(opt.scenes):
        convention = conventions[i % 4]
        width, height = rng.choice([(16, 12), (40, 30), (64, 48)])
        xyz, gt = make_scene(rng, convention, width, height)
        pred = make_prediction(rng, gt, width, height)
        gt_path = os.path.join(opt.workdir, "scene%02d_gt.pcd" % i)
        pred_path = os.path.join(opt.workdir, "scene%02d_pred.pcd" % i)
        write_pcd(gt_path, width, height, xyz, gt, rng.choice(encodings),
                  rng.choice(["xyzrgbal", "mosd"]))
        # The prediction's coordinates are ignored: write them all valid.
        write_pcd(pred_path, width, height, [(0.0, 0.0, 1.0)] * len(gt), pred,
                  rng.choice(encodings))
        for conv in conventions:
            extra = []
            ocid_bg = (0, 1, 2)
            if conv == "ocid" and i % 3 == 0:
                ocid_bg = (0, 3)
                extra = ["--ocid-background", "0,3"]
            coverage = 10 if i % 5 else 25
            label = "scene%02d/%s" % (i, conv)
            got = tool_json(opt.tool, [gt_path, pred_path, "--gt-convention", conv, "--quiet",
                                       "--coverage-percent", str(coverage)] + extra)
            want = ref.summarize([ref.score_files(gt_path, pred_path,
                                                  RefArgs(conv, ocid_bg, coverage))],
                                 RefArgs(conv, ocid_bg, coverage), 0)
            compare(label, got, want)
            compared += 1
        if convention == "mosd-parts":
            shutil.copy(gt_path, os.path.join(gt_dir, "frame%02d.pcd" % i))
            shutil.copy(pred_path, os.path.join(pred_dir, "frame%02d.pcd" % i))

    # 2. Exact ties: both implementations must pick the same segment.
    ties = [([1] * 6 + [0] * 3, [1, 1, 2, 2, 2, 0, 2, 2, 2]),
            ([1] * 6 + [0] * 3, [2, 2, 1, 1, 1, 0, 1, 1, 1]),
            ([1] * 4, [7, 7, 3, 3]),
            ([1] * 10 + [0] * 14, [1] * 6 + [2] * 4 + [1] * 14)]
    for t, (gt, pred) in enumerate(ties):
        n = len(gt)
        gt_path = os.path.join(opt.workdir, "tie%d_gt.pcd" % t)
        pred_path = os.path.join(opt.workdir, "tie%d_pred.pcd" % t)
        write_pcd(gt_path, n, 1, [(0.0, 0.0, 1.0)] * n, gt)
        write_pcd(pred_path, n, 1, [(0.0, 0.0, 1.0)] * n, pred)
        got = tool_json(opt.tool, [gt_path, pred_path, "-q"])
        want = ref.summarize([ref.score_files(gt_path, pred_path, RefArgs("plain"))],
                             RefArgs("plain"), 0)
        compare("tie%d" % t, got, want)
        compared += 1

    # 3. Directory mode, table output, CSV, and the reference's own command line.
    csv_path = os.path.join(opt.workdir, "frames.csv")
    proc = run_tool(opt.tool, [gt_dir, pred_dir, "--gt-convention", "mosd-parts", "--csv",
                               csv_path])
    check(proc.returncode == 0, "directory mode failed: " + proc.stderr)
    check(proc.stderr == "", "stderr must stay empty when it is not a terminal: %r" % proc.stderr)
    lines = proc.stdout.strip().split("\n")
    check(len(lines) > 3 and lines[0].startswith("frame"), "table header missing")
    got = json.loads(lines[-1])
    ref_cli = subprocess.run([sys.executable, opt.reference, gt_dir, pred_dir,
                              "--gt-convention", "mosd-parts"], capture_output=True, text=True)
    check(ref_cli.returncode == 0, "reference CLI failed: " + ref_cli.stderr)
    compare("directory", got, json.loads(ref_cli.stdout))
    num_frames = len(os.listdir(gt_dir))
    check(got["frames"] == num_frames, "directory frame count")
    with open(csv_path) as f:
        csv_lines = f.read().strip().split("\n")
    check(len(csv_lines) == num_frames + 1, "CSV must have a header and one row per frame")
    compared += 1

    # 4. Missing prediction: an error naming the file, or scored empty with --allow-missing.
    first = sorted(os.listdir(pred_dir))[0]
    os.rename(os.path.join(pred_dir, first), os.path.join(opt.workdir, "held_out.pcd"))
    proc = run_tool(opt.tool, [gt_dir, pred_dir, "-q"])
    check(proc.returncode == 1 and first in proc.stderr,
          "missing prediction must fail with exit 1 naming %s: %d %r"
          % (first, proc.returncode, proc.stderr))
    proc = run_tool(opt.tool, [gt_dir, pred_dir, "-q", "--allow-missing",
                               "--gt-convention", "mosd-parts"])
    check(proc.returncode == 0 and first in proc.stderr, "--allow-missing must report " + first)
    if proc.returncode == 0:
        ref_cli = subprocess.run([sys.executable, opt.reference, gt_dir, pred_dir,
                                  "--gt-convention", "mosd-parts", "--allow-missing"],
                                 capture_output=True, text=True)
        got = json.loads(proc.stdout.strip().split("\n")[-1])
        check(got["missing"] == 1, "missing count")
        check(proc.stdout.count("\n") == 1, "--quiet prints only the JSON line")
        compare("allow-missing", got, json.loads(ref_cli.stdout))
        compared += 1
    os.rename(os.path.join(opt.workdir, "held_out.pcd"), os.path.join(pred_dir, first))

    # 5. Errors and exit codes.
    a = os.path.join(opt.workdir, "scene00_gt.pcd")
    small = os.path.join(opt.workdir, "small.pcd")
    write_pcd(small, 3, 1, [(0.0, 0.0, 1.0)] * 3, [0, 1, 1])
    proc = run_tool(opt.tool, [a, small])
    check(proc.returncode == 1 and a in proc.stderr and small in proc.stderr,
          "point count mismatch must exit 1 naming both files: %r" % proc.stderr)
    nolabel = os.path.join(opt.workdir, "nolabel.pcd")
    write_pcd(nolabel, 3, 1, [(0.0, 0.0, 1.0)] * 3, [0, 0, 0], with_label=False)
    proc = run_tool(opt.tool, [small, nolabel])
    check(proc.returncode == 1 and nolabel in proc.stderr,
          "prediction without label must exit 1 naming it: %r" % proc.stderr)
    proc = run_tool(opt.tool, [nolabel, small])
    check(proc.returncode == 1 and nolabel in proc.stderr,
          "ground truth without label must exit 1 naming it: %r" % proc.stderr)
    missing_file = os.path.join(opt.workdir, "does_not_exist.pcd")
    proc = run_tool(opt.tool, [missing_file, small])
    check(proc.returncode == 3 and missing_file in proc.stderr,
          "absent input must exit 3 (input cannot be opened) naming it: %r" % proc.stderr)
    for bad in ([a, small, "--gt-convention", "mosd"], [a], [a, gt_dir],
                [a, small, "--coverage-percent", "0"], [a, small, "--ocid-background", "x"],
                [a, small, "--no-such-flag"]):
        proc = run_tool(opt.tool, bad)
        check(proc.returncode == 2, "bad command line %r must exit 2, got %d"
              % (bad, proc.returncode))
    proc = run_tool(opt.tool, ["--help"])
    check(proc.returncode == 0 and "--gt-convention" in proc.stdout, "--help")

    print("%d comparisons, %d failures" % (compared, len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
