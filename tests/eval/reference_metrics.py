#!/usr/bin/env python3
"""Reference implementation of the clutterseg evaluation metrics (METHOD.md section 7).

Written independently of the C++ code, for cross-checking it: plain sets of point indices,
exact fractions for the choice of the best segment, Python standard library only.

    reference_metrics.py GT PRED [--gt-convention plain|mosd-parts|mosd-objects|ocid]
                         [--ocid-background 0,1,2] [--coverage-percent 10]

GT and PRED are PCD files with a label field (DATA ascii, binary or binary_compressed), or
two directories whose *.pcd files are matched by name. Prints one JSON object.

Definitions (the same readings as src/eval/metrics.h):
  * only points with finite x, y, z (in the ground-truth file) count, on both sides;
  * g_i: points whose mapped ground-truth label is i >= 1; s_j: points predicted j >= 1;
  * Ov_i = max_j |g_i & s_j| / |g_i | s_j|, WOv = sum |g_i| Ov_i / sum |g_i|;
  * s_i = the segment of maximum IoU with g_i; ties: larger intersection, then smaller label;
  * TP_i = |g_i & s_i| / |g_i|, FP_i = |s_i - g_i| / |s_i|, FN_i = |g_i - s_i| / |g_i|,
    and TP_i = 0, FP_i = 0, FN_i = 1 when no segment touches g_i;
  * precision = TP / (TP + FP), recall = TP / (TP + FN), F1 = 2PR / (P + R), 0/0 = 0;
  * a segment covers g_i when it holds >= coverage-percent of g_i; g_i is over-segmented
    when two or more segments cover it, under-segmented when a segment covering it also
    covers another ground-truth object;
  * where the overlap is lost: every point of g_i outside s_i and of s_i outside g_i weighs
    |g_i| / |g_i | s_i| (all of g_i weighs 1 when no segment touches it) and goes to one
    cause: merged (a point of g_i in a segment covering g_i and another object; a point of
    s_i on an object s_i covers), split (a point of g_i in a segment covering no other
    object, most of whose points are on objects), boundary (a point of g_i in a segment
    covering another object but not g_i; a point of s_i on an object it does not cover),
    background (a point of g_i predicted 0 or in a segment covering no other object, most of
    whose points are on no object; a point of s_i on no object); loss_<cause> is the
    weights' sum over sum |g_i|;
  * several frames: quality figures are means over frames that have ground-truth objects,
    counts are totals.
"""

import argparse
import json
import math
import os
import struct
import sys
from fractions import Fraction


# ----------------------------------------------------------------------------- PCD reading

def lzf_decompress(data, expected_size):
    out = bytearray()
    i = 0
    n = len(data)
    while i < n:
        ctrl = data[i]
        i += 1
        if ctrl < 32:
            run = ctrl + 1
            out += data[i:i + run]
            i += run
        else:
            length = ctrl >> 5
            if length == 7:
                length += data[i]
                i += 1
            back = ((ctrl & 0x1F) << 8) + data[i] + 1
            i += 1
            length += 2
            start = len(out) - back
            if start < 0:
                raise ValueError("corrupt LZF data")
            if back >= length:
                out += out[start:start + length]
            else:
                for k in range(length):
                    out.append(out[start + k])
    if len(out) != expected_size:
        raise ValueError("LZF size mismatch: %d != %d" % (len(out), expected_size))
    return bytes(out)


STRUCT_CODES = {("F", 4): "f", ("F", 8): "d", ("U", 1): "B", ("U", 2): "H", ("U", 4): "I",
                ("U", 8): "Q", ("I", 1): "b", ("I", 2): "h", ("I", 4): "i", ("I", 8): "q"}


def read_pcd(path):
    """Returns (points, columns): columns maps x, y, z, label to per-point value lists."""
    with open(path, "rb") as f:
        blob = f.read()
    header = {}
    pos = 0
    while True:
        end = blob.index(b"\n", pos)
        line = blob[pos:end].decode("ascii").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, _, rest = line.partition(" ")
        header[key.upper()] = rest.split()
        if key.upper() == "DATA":
            break
    names = header["FIELDS"]
    sizes = [int(v) for v in header["SIZE"]]
    types = [v.upper() for v in header["TYPE"]]
    counts = [int(v) for v in header.get("COUNT", ["1"] * len(names))]
    points = int(header["POINTS"][0]) if "POINTS" in header else (
        int(header["WIDTH"][0]) * int(header["HEIGHT"][0]))
    mode = header["DATA"][0].lower()
    wanted = ("x", "y", "z", "label")
    columns = {}
    if mode == "ascii":
        rows = blob[pos:].decode("ascii").split("\n")
        rows = [r.split() for r in rows if r.strip()][:points]
        col = 0
        for name, typ, cnt in zip(names, types, counts):
            if name in wanted:
                conv = float if typ == "F" else int
                columns[name] = [conv(r[col]) for r in rows]
            col += cnt
    elif mode == "binary":
        fmt = "<" + "".join(STRUCT_CODES[(t, s)] * c for t, s, c in zip(types, sizes, counts))
        record = struct.calcsize(fmt)
        records = list(struct.iter_unpack(fmt, blob[pos:pos + record * points]))
        col = 0
        for name, cnt in zip(names, counts):
            if name in wanted:
                columns[name] = [r[col] for r in records]
            col += cnt
    elif mode == "binary_compressed":
        compressed, raw_size = struct.unpack_from("<II", blob, pos)
        raw = lzf_decompress(blob[pos + 8:pos + 8 + compressed], raw_size)
        offset = 0
        for name, typ, size, cnt in zip(names, types, sizes, counts):
            block = size * cnt * points
            if name in wanted:
                code = STRUCT_CODES[(typ, size)]
                values = struct.unpack("<%d%s" % (points * cnt, code), raw[offset:offset + block])
                columns[name] = list(values[::cnt])
            offset += block
    else:
        raise ValueError("%s: unsupported DATA %s" % (path, mode))
    return points, columns


# ----------------------------------------------------------------------------- metrics

def object_id(raw, convention, ocid_background):
    if convention == "plain":
        return raw
    if convention == "mosd-parts":
        return 0 if raw <= 9 else raw
    if convention == "mosd-objects":
        return 0 if raw <= 9 else raw // 10
    if convention == "ocid":
        return 0 if raw in ocid_background else raw
    raise ValueError("unknown convention " + convention)


def score_frame(xyz_ok, gt_raw, pred, convention, ocid_background, coverage_percent):
    valid = [k for k in range(len(gt_raw)) if xyz_ok[k]]
    objects = {}
    segments = {}
    for k in valid:
        g = object_id(gt_raw[k], convention, ocid_background)
        if g >= 1:
            objects.setdefault(g, set()).add(k)
        if pred[k] >= 1:
            segments.setdefault(pred[k], set()).add(k)

    def covers(seg, obj):
        return 100 * len(segments[seg] & objects[obj]) >= coverage_percent * len(objects[obj])

    gt_of = {}
    for g, points_g in objects.items():
        for k in points_g:
            gt_of[k] = g
    lost = {"merged": 0.0, "split": 0.0, "boundary": 0.0, "background": 0.0}
    result = {"gt_objects": len(objects), "segments": len(segments), "scored": bool(objects)}
    tps, fps, fns = [], [], []
    weighted = 0.0
    over = under = 0
    for g in sorted(objects):
        points_g = objects[g]
        touching = sorted({pred[k] for k in points_g if pred[k] >= 1})
        best = None
        if touching:
            best = max(touching, key=lambda j: (
                Fraction(len(points_g & segments[j]), len(points_g | segments[j])),
                len(points_g & segments[j]), -j))
        if best is None:
            tps.append(0.0)
            fps.append(0.0)
            fns.append(1.0)
        else:
            s = segments[best]
            tp_set = points_g & s
            weighted += len(points_g) * (len(tp_set) / len(points_g | s))
            tps.append(len(tp_set) / len(points_g))
            fps.append(len(s - tp_set) / len(s))
            fns.append(len(points_g - tp_set) / len(points_g))
        s = segments[best] if best is not None else set()
        weight = len(points_g) / len(points_g | s)

        def fn_cause(j):  # the cause of a point of g outside s, predicted j
            if j == 0:
                return "background"
            if any(o != g and covers(j, o) for o in objects):
                return "merged" if covers(j, g) else "boundary"
            on_objects = sum(1 for q in segments[j] if q in gt_of)
            return "split" if 2 * on_objects >= len(segments[j]) else "background"

        causes = {}
        for k in points_g - s:
            if pred[k] not in causes:
                causes[pred[k]] = fn_cause(pred[k])
            lost[causes[pred[k]]] += weight
        for k in s - points_g:
            o = gt_of.get(k, 0)
            cause = "background" if o == 0 else ("merged" if covers(best, o) else "boundary")
            lost[cause] += weight
        covering = [j for j in touching if covers(j, g)]
        if len(covering) >= 2:
            over += 1
        if any(covers(j, other) for j in covering for other in objects if other != g):
            under += 1
    result["over_segmented"] = over
    result["under_segmented"] = under
    if objects:
        n = len(objects)
        tp, fp, fn = sum(tps) / n, sum(fps) / n, sum(fns) / n
        precision = tp / (tp + fp) if tp + fp > 0 else 0.0
        recall = tp / (tp + fn) if tp + fn > 0 else 0.0
        f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
        total = sum(len(p) for p in objects.values())
        result.update(wov=weighted / total, tp=tp, fp=fp, fn=fn, precision=precision,
                      recall=recall, f1=f1)
        for cause, value in lost.items():
            result["loss_" + cause] = value / total
    return result


def score_files(gt_path, pred_path, args):
    n_gt, gt = read_pcd(gt_path)
    if pred_path is None:
        pred = [0] * n_gt
    else:
        n_pred, pred_cols = read_pcd(pred_path)
        if n_pred != n_gt:
            raise ValueError("point counts differ: %s has %d, %s has %d"
                             % (gt_path, n_gt, pred_path, n_pred))
        pred = pred_cols["label"]
    ok = [math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
          for x, y, z in zip(gt["x"], gt["y"], gt["z"])]
    return score_frame(ok, gt["label"], pred, args.gt_convention, set(args.ocid_background),
                       args.coverage_percent)


def summarize(frames, args, missing):
    scored = [f for f in frames if f["scored"]]
    out = {"convention": args.gt_convention, "frames": len(frames),
           "frames_scored": len(scored), "missing": missing}
    for key in ("wov", "precision", "recall", "f1", "tp", "fp", "fn", "loss_merged",
                "loss_split", "loss_boundary", "loss_background"):
        out[key] = sum(f[key] for f in scored) / len(scored) if scored else None
    for key in ("gt_objects", "segments", "over_segmented", "under_segmented"):
        out[key] = sum(f[key] for f in frames)
        out["mean_" + key] = out[key] / len(frames) if frames else 0.0
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("gt")
    parser.add_argument("pred")
    parser.add_argument("--gt-convention", default="plain",
                        choices=["plain", "mosd-parts", "mosd-objects", "ocid"])
    parser.add_argument("--ocid-background", default="0,1,2",
                        type=lambda s: [int(v) for v in s.split(",") if v])
    parser.add_argument("--coverage-percent", type=int, default=10)
    parser.add_argument("--allow-missing", action="store_true")
    args = parser.parse_args()
    frames = []
    missing = 0
    if os.path.isdir(args.gt):
        for name in sorted(n for n in os.listdir(args.gt) if n.endswith(".pcd")):
            pred_path = os.path.join(args.pred, name)
            if not os.path.exists(pred_path):
                if not args.allow_missing:
                    sys.exit("no prediction for " + os.path.join(args.gt, name))
                pred_path = None
                missing += 1
            frames.append(score_files(os.path.join(args.gt, name), pred_path, args))
    else:
        frames.append(score_files(args.gt, args.pred, args))
    print(json.dumps(summarize(frames, args, missing)))


if __name__ == "__main__":
    main()
