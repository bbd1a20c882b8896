#!/usr/bin/env python3
"""Scores the object identities a daemon published against the ground truth of the recording
it replayed (docs/method.md, "Object identities across frames"; docs/results.md, "Object
identities").

Inputs: pairs of an LCM log the daemon wrote (`--lcm-url 'file:///abs/out.lcmlog?mode=w'`)
and the ground-truth directory `clutterseg-synth --oni X.oni --out GTDIR` wrote for the same
recording (frame_NNNNNN.pcd per recording frame, numbered like the replay's frame_seq, and
scenes.json; with `--gt-labels-only` frame_NNNNNN_label.png instead of the PCD, the centroids
coming from scenes.json); several pairs are scored together (objects of different recordings,
and of different scenes of one recording, are different objects).

In every frame each ground-truth object (a label with at least --min-points points of finite
xyz in the frame's PCD, or as many `valid_points` in scenes.json; the occluder named in
scenes.json left out) is matched to the published object whose centroid is nearest to its
centroid, when that is at most --match-distance away (several ground-truth objects may match
the same published object). Per object and overall:

- identity consistency: the share of its matched frames carrying its most frequent id (ties:
  the id matched first); overall, pooled over objects (sum of those frames / sum of matched);
- id switches: changes of the matched id between consecutive matched frames of an object;
- coverage: matched frames / visible frames;
- id reuse: over published ids, (distinct ground-truth objects matched - 1), summed;
- flicker: among consecutive frame pairs whose ground-truth object set is the same and has
  been for --settle-frames frames before, the share whose published id set differs;
- partition flicker (independent of the ids; needs the label images the daemon publishes on
  --labels-channel, lcm.publish_labels, on by default): among consecutive frame pairs of a
  static scene (the ground-truth object set the same and for --settle-frames frames before,
  no occluder pixel in either frame), the number and share whose partition differs. A frame's
  partition of the ground-truth objects: each object's dominant published segment (the one
  holding most of its pixels, or none when most are background), which objects share it
  (merged), and how many published segments each object dominates (split), plus the number
  of segments lying mostly on the background. Noise moving pixels along a boundary does not
  change it; a boundary that opens or closes, a piece that splits off, an object that drops
  out of the segmentation do.

Three kinds of id are scored, as tests/pipeline/tracker_report does:
  label  - object_t.id, each frame's label value (what a consumer had without the tracker)
  tracks - object_t.track_id of every published object
  shown  - object_t.track_id of TRACK_CONFIRMED objects only; for flicker the confirmed
           lost_tracks[] count as present (a consumer keeps showing a hidden object)

Usage:
  tools/track_consistency.py LOG GTDIR [LOG GTDIR ...] [--channel CLUTTERSEG_OBJECTS]
      [--labels-channel CLUTTERSEG_LABELS]
      [--match-distance 0.03] [--min-points 200] [--settle-frames 2]
      [--objects tracks|shown|label|none] [--min-consistency X] [--bindings DIR]

Exit codes: 0 scored (and, with --min-consistency, the tracks' overall consistency reached
it), 1 below --min-consistency, 2 bad input (no frames in common, unreadable files).

Standard library only, plus the generated clutterseg Python package (found on sys.path, in
--bindings DIR, or in build/*/lcmtypes/python of this repository). PCD files may be ascii,
binary or binary_compressed (LZF, decompressed here); clutterseg-synth writes binary. Label
PNGs are 16-bit greyscale as clutterseg-synth writes them (decoded here with zlib).
"""
import argparse
import array
import glob
import heapq
import json
import math
import os
import re
import struct
import sys
import zlib
from collections import Counter, OrderedDict
from itertools import accumulate

ID_KINDS = ("label", "tracks", "shown")


def fail(message):
    """Bad input: the message on stderr, exit code 2."""
    print("track_consistency: " + message, file=sys.stderr)
    sys.exit(2)


def import_bindings(extra):
    """Imports the generated `clutterseg` package: from --bindings DIR when given, else from
    sys.path, else from the build trees of this repository (build/*/lcmtypes/python)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if extra:
        sys.path.insert(0, extra)
    else:
        try:
            import clutterseg.transport  # noqa: F401
        except ImportError:
            for c in sorted(glob.glob(os.path.join(root, "build", "*", "lcmtypes", "python"))):
                if os.path.isfile(os.path.join(c, "clutterseg", "transport.py")):
                    sys.path.insert(0, c)
                    break
    try:
        from clutterseg import objects_t
        from clutterseg.transport import read_log
    except ImportError as e:
        fail("cannot import the clutterseg Python bindings (%s); "
             "pass --bindings DIR (the directory holding clutterseg/)" % e)
    return objects_t, read_log


# ---- PCD ------------------------------------------------------------------------------------

_PCD_TYPES = {("F", 4): "f", ("F", 8): "d", ("U", 1): "B", ("U", 2): "H", ("U", 4): "I",
              ("U", 8): "Q", ("I", 1): "b", ("I", 2): "h", ("I", 4): "i", ("I", 8): "q"}


def lzf_decompress(src, out_len):
    """LZF (liblzf's format, as PCD binary_compressed uses) into `out_len` bytes."""
    out = bytearray(out_len)
    ip, op, n = 0, 0, len(src)
    while ip < n:
        ctrl = src[ip]
        ip += 1
        if ctrl < 32:  # a literal run of ctrl + 1 bytes
            length = ctrl + 1
            if ip + length > n or op + length > out_len:
                raise ValueError("LZF: literal run beyond the data")
            out[op:op + length] = src[ip:ip + length]
            ip += length
            op += length
            continue
        length = ctrl >> 5
        if length == 7:
            if ip >= n:
                raise ValueError("LZF: truncated length")
            length += src[ip]
            ip += 1
        if ip >= n:
            raise ValueError("LZF: truncated back reference")
        ref = op - ((ctrl & 0x1F) << 8) - src[ip] - 1
        ip += 1
        length += 2
        if ref < 0 or op + length > out_len:
            raise ValueError("LZF: back reference outside the output")
        dist = op - ref
        if dist >= length:
            out[op:op + length] = out[ref:ref + length]
        else:  # overlapping: the pattern of `dist` bytes repeats
            pattern = bytes(out[ref:op])
            reps = pattern * (length // dist + 1)
            out[op:op + length] = reps[:length]
        op += length
    if op != out_len:
        raise ValueError("LZF: %d bytes decoded, %d expected" % (op, out_len))
    return bytes(out)


def read_pcd_label_centroids(path, min_points):
    """({label: (x, y, z, count)} over the points of `path` with a label >= 1 and finite xyz,
    for labels with at least `min_points` such points; the labels of all points)."""
    labels, xs, ys, zs = read_pcd_columns(path)
    sums = {}
    isfinite = math.isfinite
    for i, lab in enumerate(labels):
        if lab <= 0:
            continue
        x, y, z = xs[i], ys[i], zs[i]
        if not (isfinite(x) and isfinite(y) and isfinite(z)):
            continue
        s = sums.get(lab)
        if s is None:
            sums[lab] = [x, y, z, 1]
        else:
            s[0] += x
            s[1] += y
            s[2] += z
            s[3] += 1
    return ({lab: (s[0] / s[3], s[1] / s[3], s[2] / s[3], s[3])
             for lab, s in sums.items() if s[3] >= min_points}, labels)


def read_pcd_columns(path):
    """(label, x, y, z) sequences of the points of the PCD file `path`."""
    with open(path, "rb") as f:
        blob = f.read()
    header, pos = {}, 0
    while True:
        end = blob.find(b"\n", pos)
        if end < 0:
            raise ValueError("%s: header ends without a DATA line" % path)
        line = blob[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, _, value = line.partition(" ")
        header[key.upper()] = value.split()
        if key.upper() == "DATA":
            break
    names = header.get("FIELDS") or header.get("COLUMNS")
    sizes = [int(s) for s in header["SIZE"]]
    types = [t.upper() for t in header["TYPE"]]
    counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
    points = int(header.get("POINTS", [0])[0]) or (
        int(header["WIDTH"][0]) * int(header.get("HEIGHT", ["1"])[0]))
    for need in ("x", "y", "z", "label"):
        if need not in names:
            raise ValueError("%s: no field '%s'" % (path, need))
    codes = []
    for t, s in zip(types, sizes):
        if (t, s) not in _PCD_TYPES:
            raise ValueError("%s: unsupported TYPE %s SIZE %d" % (path, t, s))
        codes.append(_PCD_TYPES[(t, s)])
    # Column of each field's first element in a point's flattened values.
    column, first = 0, {}
    for name, c in zip(names, counts):
        first[name] = column
        column += c
    xi, yi, zi, li = first["x"], first["y"], first["z"], first["label"]
    encoding = header["DATA"][0].lower()

    xs = ys = zs = labels = None
    if encoding == "ascii":
        rows = blob[pos:].split(b"\n")
        labels, xs, ys, zs = [], [], [], []
        for r in rows:
            tok = r.split()
            if len(tok) < column:
                continue
            labels.append(int(float(tok[li])))
            xs.append(float(tok[xi]))
            ys.append(float(tok[yi]))
            zs.append(float(tok[zi]))
    elif encoding == "binary":
        fmt = "<" + "".join(code * c for code, c in zip(codes, counts))
        stride = struct.calcsize(fmt)
        data = memoryview(blob)[pos:pos + points * stride]
        if len(data) < points * stride:
            raise ValueError("%s: %d data bytes, %d expected" % (path, len(data), points * stride))
        # Fast path: every value 4 bytes (x y z rgba label as clutterseg writes).
        if all(struct.calcsize(code) == 4 for code in codes) and sys.byteorder == "little":
            words = stride // 4
            fv = data.cast("f")
            lv = {"I": data.cast("I"), "i": data.cast("i"), "f": fv}[codes[names.index("label")]]
            labels = lv[li::words]
            xs, ys, zs = fv[xi::words], fv[yi::words], fv[zi::words]
        else:
            rows = list(struct.iter_unpack(fmt, data))
            labels = [int(r[li]) for r in rows]
            xs, ys, zs = [r[xi] for r in rows], [r[yi] for r in rows], [r[zi] for r in rows]
    elif encoding == "binary_compressed":
        comp, raw = struct.unpack_from("<II", blob, pos)
        data = lzf_decompress(blob[pos + 8:pos + 8 + comp], raw)
        # Planar: every value of field 0 for all points, then field 1, ...
        planes, off = {}, 0
        for name, code, c in zip(names, codes, counts):
            size = struct.calcsize(code) * c * points
            if c == 1:
                planes[name] = struct.unpack_from("<%d%s" % (points, code), data, off)
            off += size
        labels, xs, ys, zs = planes["label"], planes["x"], planes["y"], planes["z"]
    else:
        raise ValueError("%s: unknown DATA encoding %s" % (path, encoding))
    return labels, xs, ys, zs


def _paeth(a, b, c):
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    return a if pa <= pb and pa <= pc else (b if pb <= pc else c)


def read_png_label_runs(path):
    """runs_of the pixels of a 16-bit greyscale PNG (a clutterseg-synth label PNG). Fast path
    for what clutterseg-synth writes (every row Sub-filtered, every label below 256): only the
    non-zero filtered bytes, the label changes, are visited."""
    width, height, raw = _png_image(path)
    row_bytes = 2 * width
    stride = row_bytes + 1
    if raw[0::stride] == b"\x01" * height:
        body = b"".join(raw[v * stride + 1:(v + 1) * stride] for v in range(height))
        if body[0::2].count(0) == width * height:  # high bytes (PNG is big-endian) all 0
            lo = body[1::2]
            n = width * height
            runs, cur, start = [], 0, 0
            events = heapq.merge(range(0, n, width), (m.start() for m in _NONZERO.finditer(lo)))
            last = -1
            for k in events:
                if k == last:
                    continue
                last = k
                new = lo[k] if k % width == 0 else (cur + lo[k]) & 255
                if new != cur:
                    if k > start:
                        runs.append((cur, k - start))
                    cur, start = new, k
            runs.append((cur, n - start))
            return runs
    return runs_of(read_png_labels(path))


def _png_image(path):
    """(width, height, the filtered rows) of a 16-bit greyscale PNG without interlacing."""
    with open(path, "rb") as f:
        blob = f.read()
    if blob[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("%s: not a PNG file" % path)
    pos, idat, width = 8, [], None
    while pos + 8 <= len(blob):
        length, kind = struct.unpack_from(">I4s", blob, pos)
        body = blob[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 16 or colour != 0 or interlace != 0:
                raise ValueError("%s: not a 16-bit greyscale PNG without interlacing" % path)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    if width is None:
        raise ValueError("%s: no IHDR chunk" % path)
    raw = zlib.decompress(b"".join(idat))
    if len(raw) != (2 * width + 1) * height:
        raise ValueError("%s: %d image bytes, %d expected" % (path, len(raw),
                                                             (2 * width + 1) * height))
    return width, height, raw


def read_png_labels(path):
    """The pixels of a 16-bit greyscale PNG (a clutterseg-synth label PNG) as array('H'),
    row-major."""
    width, height, raw = _png_image(path)
    row_bytes = 2 * width
    out = bytearray(row_bytes * height)
    prev = bytearray(row_bytes)
    mask = (255).__and__
    for v in range(height):
        start = v * (row_bytes + 1)
        kind, row = raw[start], bytearray(raw[start + 1:start + 1 + row_bytes])
        if kind == 1:  # Sub, what clutterseg writes: a running sum per byte of the pixel
            row[0::2] = bytes(map(mask, accumulate(row[0::2])))
            row[1::2] = bytes(map(mask, accumulate(row[1::2])))
        elif kind == 2:  # Up
            row = bytearray(map(mask, map(int.__add__, row, prev)))
        elif kind in (3, 4):  # Average, Paeth
            for i in range(row_bytes):
                a = row[i - 2] if i >= 2 else 0
                b = prev[i]
                c = prev[i - 2] if i >= 2 else 0
                row[i] = (row[i] + ((a + b) >> 1 if kind == 3 else _paeth(a, b, c))) & 255
        elif kind != 0:
            raise ValueError("%s: unknown PNG filter %d" % (path, kind))
        out[v * row_bytes:(v + 1) * row_bytes] = row
        prev = row
    labels = array.array("H")
    labels.frombytes(bytes(out))
    if sys.byteorder == "little":
        labels.byteswap()  # PNG samples are big-endian
    return labels


_PAIR_RUNS = re.compile(b"(..)\\1*", re.S)
_NONZERO = re.compile(b"[^\\x00]")


def runs_of(labels):
    """[(label, run length)] of a label sequence, row-major."""
    if isinstance(labels, array.array) and labels.typecode == "H":
        raw = labels.tobytes()
        fmt = "<H" if sys.byteorder == "little" else ">H"
        return [(struct.unpack(fmt, m.group(1))[0], (m.end() - m.start()) >> 1)
                for m in _PAIR_RUNS.finditer(raw)]
    out = []
    for lab in labels:
        if out and out[-1][0] == lab:
            out[-1][1] += 1
        else:
            out.append([lab, 1])
    return [tuple(r) for r in out]


def published_runs(msg, decode_labels):
    """runs_of a label_image_t; run-length encoded messages give their runs directly."""
    if msg.compression == 1 and msg.size == len(msg.data) and len(msg.data) % 6 == 0:
        runs = [r for r in struct.iter_unpack("<HI", bytes(msg.data)) if r[1]]
        if sum(r[1] for r in runs) == msg.width * msg.height:
            return runs
    return runs_of(decode_labels(msg))


def upsampled_runs(runs, width, factor):
    """runs_of a label image of `width` columns scaled up `factor` times in each direction
    (each pixel becomes a factor x factor block): the published labels of a decimated camera
    (camera.decimation) over the full-resolution ground truth."""
    out, row, filled = [], [], 0
    for lab, n in runs:
        while n:
            k = min(n, width - filled)
            row.append((lab, k * factor))
            filled += k
            n -= k
            if filled == width:
                for _ in range(factor):
                    for r in row:
                        if out and out[-1][0] == r[0]:
                            out[-1] = (r[0], out[-1][1] + r[1])
                        else:
                            out.append(r)
                row, filled = [], 0
    return out


def contingency(runs_a, runs_b):
    """Counter of (a, b) pixel pairs of two label images given as runs over the same pixels."""
    counts = Counter()
    i = j = 0
    la = lb = 0
    a = b = 0
    while True:
        if la == 0:
            if i == len(runs_a):
                break
            a, la = runs_a[i]
            i += 1
            continue
        if lb == 0:
            if j == len(runs_b):
                break
            b, lb = runs_b[j]
            j += 1
            continue
        n = la if la < lb else lb
        counts[(a, b)] += n
        la -= n
        lb -= n
    if la or lb or i != len(runs_a) or j != len(runs_b):
        raise ValueError("label images of different sizes")
    return counts


def partition(gt_labels, pred_labels, gt_objects, occluder):
    """The partition of the ground-truth objects `gt_objects` (labels) by the published
    segmentation; both label images as runs (runs_of) over the same pixels: (per object: its merge group, or None when
    most of its pixels are not in a segment; per object: segments it dominates; segments
    dominated by the background). See the module docstring."""
    wanted = set(gt_objects)
    counts = Counter()
    for (g, p), n in contingency(gt_labels, pred_labels).items():
        counts[(g if g in wanted and g != occluder else 0, p)] += n
    seg_owner, seg_best = {}, {}  # segment -> dominant ground truth (0: background)
    obj_seg, obj_best = {}, {}    # object -> dominant segment (0: none)
    for (g, p), n in sorted(counts.items()):
        if p:
            if n > seg_best.get(p, 0):
                seg_best[p], seg_owner[p] = n, g
        if g:
            if n > obj_best.get(g, 0):
                obj_best[g], obj_seg[g] = n, p
    groups = {}
    for g in sorted(wanted):
        p = obj_seg.get(g, 0)
        if p:
            groups.setdefault(p, []).append(g)
    merged = tuple(sorted((g, tuple(groups[obj_seg[g]]) if obj_seg.get(g, 0) else None)
                          for g in wanted))
    pieces = Counter(seg_owner.values())
    split = tuple(sorted((g, pieces.get(g, 0)) for g in wanted))
    return merged, split, pieces.get(0, 0)


class GtFrame:
    """One ground-truth frame: its frame_seq, scene index, occluder label (0: none) and its
    visible pixels (None: unknown), the PCD and label PNG paths (None when absent), and the
    manifest's {label: (x, y, z, valid_points)} (None when the manifest has no centroids)."""

    __slots__ = ("seq", "scene", "occluder", "occluder_pixels", "pcd", "label_png", "centroids")

    def __init__(self, seq, scene, occluder, occluder_pixels, pcd, label_png, centroids):
        self.seq, self.scene, self.occluder = seq, scene, occluder
        self.occluder_pixels, self.pcd, self.label_png = occluder_pixels, pcd, label_png
        self.centroids = centroids


def ground_truth_frames(gt_dir):
    """[GtFrame] in frame order, from scenes.json (frames numbered by oni_frame) or, without
    it, from the frame_NNNNNN.pcd names."""
    manifest = os.path.join(gt_dir, "scenes.json")
    frames = []
    if os.path.isfile(manifest):
        with open(manifest) as f:
            doc = json.load(f)
        for k, rec in enumerate(doc.get("scenes", [])):
            files = rec.get("files", {})
            pcd = files.get("pcd")
            if pcd is None and "label_png" not in files:
                pcd = rec["name"] + ".pcd"
            png = files.get("label_png")
            objs = rec.get("objects", [])
            cents = None
            if objs and all("centroid" in o and "valid_points" in o for o in objs):
                cents = {o["label"]: tuple(o["centroid"]) + (o["valid_points"],) for o in objs}
            elif not objs and pcd is None:
                cents = {}
            frames.append(GtFrame(rec.get("oni_frame", k), rec.get("scene_index", 0),
                                  rec.get("occluder_label", 0),
                                  rec.get("occluder_visible_pixels"),
                                  os.path.join(gt_dir, pcd) if pcd else None,
                                  os.path.join(gt_dir, png) if png else None, cents))
    else:
        for p in sorted(glob.glob(os.path.join(gt_dir, "frame_*.pcd"))):
            stem = os.path.basename(p)[len("frame_"):-len(".pcd")]
            if stem.isdigit():
                frames.append(GtFrame(int(stem), 0, 0, None, p, None, None))
    frames.sort(key=lambda f: f.seq)
    for f in frames:
        if f.centroids is None and f.pcd is None:
            fail("%s: frame %d has neither a PCD nor centroids" % (gt_dir, f.seq))
    return frames


class PartitionFlicker:
    """Counts static frame pairs whose partition of the ground-truth objects differs."""

    def __init__(self, settle_frames):
        self.settle = settle_frames
        self.prev = None  # (ground-truth set, partition) of the previous frame
        self.same_run = 0
        self.pairs = 0
        self.changed = 0
        self.by_part = [0, 0, 0]  # changed pairs whose merges / splits / background differ
        self.frames = []  # (recording, frame_seq) of the changed frames

    def break_run(self):
        self.prev = None
        self.same_run = 0

    def add_frame(self, key, gt_set, part, static):
        """`part` None: the frame cannot be scored (no label image); `static`: no occluder."""
        if part is None or not static:
            self.break_run()
            return
        self.same_run = self.same_run + 1 if self.prev is not None and \
            self.prev[0] == gt_set else 1
        if self.same_run >= self.settle + 2:
            self.pairs += 1
            if part != self.prev[1]:
                self.changed += 1
                for i in range(3):
                    self.by_part[i] += part[i] != self.prev[1][i]
                self.frames.append(key)
        self.prev = (gt_set, part)


# ---- scoring (the definitions of eval::TrackingEvaluator) -----------------------------------


class Evaluator:
    def __init__(self, match_distance, settle_frames):
        self.max_d2 = match_distance * match_distance
        self.settle = settle_frames
        self.objects = OrderedDict()  # gt key -> {"visible", "ids", "switches"}
        self.id_objects = {}
        self.prev_gt = None
        self.prev_pred = None
        self.same_run = 0
        self.steady = 0
        self.flicker = 0

    def break_run(self):
        """The next frame does not follow the last one (a frame not published)."""
        self.prev_gt = None
        self.same_run = 0

    def add_frame(self, gt, pred, remembered=()):
        """gt: {key: (x, y, z)}; pred: [(id, (x, y, z))]; remembered: ids present without a
        position (flicker only)."""
        for key in sorted(gt):
            c = gt[key]
            acc = self.objects.setdefault(key, {"visible": 0, "ids": [], "switches": 0})
            acc["visible"] += 1
            best, best_d2 = None, float("inf")
            for pid, p in pred:
                d2 = (c[0] - p[0]) ** 2 + (c[1] - p[1]) ** 2 + (c[2] - p[2]) ** 2
                if d2 < best_d2:
                    best, best_d2 = pid, d2
            if best is None or best_d2 > self.max_d2:
                continue
            if acc["ids"] and acc["ids"][-1] != best:
                acc["switches"] += 1
            acc["ids"].append(best)
            self.id_objects.setdefault(best, set()).add(key)
        cur_gt = sorted(gt)
        cur_pred = sorted([pid for pid, _ in pred] + list(remembered))
        self.same_run = self.same_run + 1 if self.prev_gt is not None and cur_gt == self.prev_gt \
            else 1
        if self.same_run >= self.settle + 2:
            self.steady += 1
            if cur_pred != self.prev_pred:
                self.flicker += 1
        self.prev_gt, self.prev_pred = cur_gt, cur_pred

    def summary(self):
        per_object = []
        tot = {"visible": 0, "matched": 0, "main": 0, "switches": 0}
        min_cons = None
        for key, acc in sorted(self.objects.items()):
            counts = {}
            for i in acc["ids"]:
                counts[i] = counts.get(i, 0) + 1
            main_id, main_n = None, 0
            for i in acc["ids"]:  # ties: the id matched first
                if counts[i] > main_n:
                    main_id, main_n = i, counts[i]
            matched = len(acc["ids"])
            cons = main_n / matched if matched else 0.0
            if matched:
                min_cons = cons if min_cons is None else min(min_cons, cons)
            per_object.append({"key": key, "visible": acc["visible"], "matched": matched,
                               "main_id": main_id, "main_frames": main_n,
                               "consistency": cons, "switches": acc["switches"],
                               "distinct_ids": len(counts)})
            tot["visible"] += acc["visible"]
            tot["matched"] += matched
            tot["main"] += main_n
            tot["switches"] += acc["switches"]
        return {
            "objects": per_object,
            "num_objects": len(per_object),
            "visible": tot["visible"],
            "matched": tot["matched"],
            "coverage": tot["matched"] / tot["visible"] if tot["visible"] else 0.0,
            "consistency": tot["main"] / tot["matched"] if tot["matched"] else 0.0,
            "min_object_consistency": min_cons if min_cons is not None else 0.0,
            "switches": tot["switches"],
            "id_reuse": sum(len(s) - 1 for s in self.id_objects.values()),
            "steady_pairs": self.steady,
            "flicker_pairs": self.flicker,
            "flicker": self.flicker / self.steady if self.steady else 0.0,
        }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("inputs", nargs="+", metavar="LOG GTDIR",
                    help="an LCM log written by the daemon (file:// URL or lcm-logger) and the "
                         "ground-truth directory of clutterseg-synth --oni ... --out; repeatable")
    ap.add_argument("--channel", default="CLUTTERSEG_OBJECTS")
    ap.add_argument("--labels-channel", default="CLUTTERSEG_LABELS",
                    help="label_image_t channel, for the partition flicker")
    ap.add_argument("--match-distance", type=float, default=0.03, help="metres (default 0.03)")
    ap.add_argument("--min-points", type=int, default=200,
                    help="a ground-truth object is visible with at least this many points "
                         "of finite xyz (default 200, as tracker_report)")
    ap.add_argument("--settle-frames", type=int, default=2,
                    help="flicker counts pairs whose ground-truth set has not changed for "
                         "this many frames before them (default 2 = tracker.confirm_frames - 1)")
    ap.add_argument("--objects", default="tracks", choices=ID_KINDS + ("none",),
                    help="which ids the per-object table shows (default tracks)")
    ap.add_argument("--min-consistency", type=float, default=None,
                    help="exit 1 when the tracks' overall consistency is below this")
    ap.add_argument("--list-flicker", action="store_true",
                    help="list the (recording:frame_seq) whose partition changed")
    ap.add_argument("--bindings", default=None,
                    help="directory holding the generated clutterseg/ Python package")
    args = ap.parse_args()

    objects_t, read_log = import_bindings(args.bindings)
    from clutterseg import object_t, label_image_t
    from clutterseg.label_image_codec import decode as decode_labels
    if len(args.inputs) % 2:
        ap.error("expected pairs of LOG GTDIR")
    pairs = [(args.inputs[i], args.inputs[i + 1]) for i in range(0, len(args.inputs), 2)]

    evals = {k: Evaluator(args.match_distance, args.settle_frames) for k in ID_KINDS}
    parts = PartitionFlicker(args.settle_frames)
    no_label_images = 0
    tracker_off, total_objects = 0, 0
    for rec, (log, gt_dir) in enumerate(pairs):
        # Published frames by frame_seq (the first pass only, should the replay have looped).
        published, repeats, messages = {}, 0, 0
        label_images = {}  # frame_seq -> encoded label_image_t (decoded when scored)
        try:
            for ev in read_log(log, channels=[args.channel, args.labels_channel]):
                if ev.channel == args.labels_channel:
                    if ev.channel != args.channel:
                        seq = label_image_t.decode(ev.data).frame_seq
                        label_images.setdefault(seq, ev.data)
                        continue
                msg = objects_t.decode(ev.data)
                messages += 1
                if msg.frame_seq in published:
                    repeats += 1
                    continue
                objs = []
                for o in msg.objects:
                    total_objects += 1
                    if o.track_id < 0:
                        tracker_off += 1
                    objs.append((o.id, o.track_id, o.track_state, tuple(o.centroid)))
                lost = [t.track_id for t in msg.lost_tracks if t.was_confirmed]
                published[msg.frame_seq] = (objs, lost)
        except (OSError, ValueError) as e:
            fail("%s" % e)
        gt_frames = ground_truth_frames(gt_dir)
        if not gt_frames:
            fail("no ground-truth frames in %s" % gt_dir)

        for e in list(evals.values()) + [parts]:
            e.break_run()
        scored, missing, prev_seq = 0, 0, None
        for fr in gt_frames:
            seq, scene, occluder = fr.seq, fr.scene, fr.occluder
            if seq not in published:
                missing += 1
                prev_seq = None
                for e in list(evals.values()) + [parts]:
                    e.break_run()
                continue
            if prev_seq is not None and seq != prev_seq + 1:
                for e in list(evals.values()) + [parts]:
                    e.break_run()
            prev_seq = seq
            static = occluder == 0 or fr.occluder_pixels == 0
            gt_labels = None
            try:
                if fr.centroids is not None:
                    cents = {lab: c for lab, c in fr.centroids.items() if c[3] >= args.min_points}
                else:
                    cents, gt_labels = read_pcd_label_centroids(fr.pcd, args.min_points)
                if static and seq in label_images:
                    if fr.label_png is not None:
                        gt_runs = read_png_label_runs(fr.label_png)
                    else:
                        if gt_labels is None:
                            gt_labels = read_pcd_columns(fr.pcd)[0]
                        gt_runs = runs_of(gt_labels)
            except (OSError, ValueError, KeyError, zlib.error) as e:
                fail("%s: %s" % (fr.label_png or fr.pcd, e))
            gt = {(rec, scene, lab): c[:3] for lab, c in cents.items() if lab != occluder}
            part = None
            if seq not in label_images:
                no_label_images += 1
            elif static:
                try:
                    msg = label_image_t.decode(label_images[seq])
                    pred_runs = published_runs(msg, decode_labels)
                    gt_pixels = sum(n for _, n in gt_runs)
                    factor = round((gt_pixels / max(1, msg.width * msg.height)) ** 0.5)
                    if factor > 1 and gt_pixels == factor * factor * msg.width * msg.height:
                        pred_runs = upsampled_runs(pred_runs, msg.width, factor)
                    part = partition(gt_runs, pred_runs,
                                     [lab for lab in cents if lab != occluder], occluder)
                except ValueError as e:
                    fail("%s: frame %d: %s" % (log, seq, e))
            parts.add_frame((rec, seq), sorted(gt), part, static)
            objs, lost = published[seq]
            # Ids of different recordings are different ids.
            evals["label"].add_frame(gt, [((rec, o[0]), o[3]) for o in objs])
            evals["tracks"].add_frame(gt, [((rec, o[1]), o[3]) for o in objs])
            evals["shown"].add_frame(
                gt, [((rec, o[1]), o[3]) for o in objs if o[2] == object_t.TRACK_CONFIRMED],
                [(rec, t) for t in lost])
            scored += 1
        if scored == 0:
            fail("no frame of %s was published in %s" % (gt_dir, log))
        scenes = len({f.scene for f in gt_frames})
        print("recording %d: %s: %d objects_t messages; %s: %d ground-truth frames (%d scene%s), "
              "%d scored, %d not published%s" % (
                  rec, log, messages, gt_dir, len(gt_frames), scenes, "" if scenes == 1 else "s",
                  scored, missing,
                  ", %d repeated frame_seq left out" % repeats if repeats else ""))

    sums = {k: evals[k].summary() for k in ID_KINDS}
    kinds = ID_KINDS
    if tracker_off:
        print("warning: %d of %d published objects carry track_id -1 (tracker off)"
              % (tracker_off, total_objects))
        if tracker_off == total_objects:
            kinds = ("label",)
            if args.objects != "none":
                args.objects = "label"
    print("match within %.3f m, visible with >= %d points, flicker after %d settled frames\n"
          % (args.match_distance, args.min_points, args.settle_frames))

    if args.objects != "none":
        s = sums[args.objects]
        print("per object (%s ids):" % args.objects)
        print("| recording | scene | label | visible | matched | coverage | main id | "
              "consistency | switches | ids |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for o in s["objects"]:
            print("| %d | %d | %d | %d | %d | %.3f | %s | %.3f | %d | %d |" % (
                o["key"][0], o["key"][1], o["key"][2], o["visible"], o["matched"],
                o["matched"] / o["visible"] if o["visible"] else 0.0,
                "-" if o["main_id"] is None else o["main_id"][1], o["consistency"],
                o["switches"], o["distinct_ids"]))
        print()
    print("| ids | objects | consistency | min object | switches | reuse | coverage | flicker |")
    print("|---|---|---|---|---|---|---|---|")
    for k in kinds:
        s = sums[k]
        print("| %-6s | %d | %.3f | %.3f | %d | %d | %d/%d = %.3f | %d/%d = %.3f |" % (
            k, s["num_objects"], s["consistency"], s["min_object_consistency"], s["switches"],
            s["id_reuse"], s["matched"], s["visible"], s["coverage"], s["flicker_pairs"],
            s["steady_pairs"], s["flicker"]))
    if parts.pairs:
        print("\npartition flicker: %d of %d static frame pairs = %.3f (the partition of the "
              "ground-truth objects differs from the previous frame's)"
              % (parts.changed, parts.pairs, parts.changed / parts.pairs))
        print("  of those, merge groups differ in %d, split counts in %d, segments on the "
              "background in %d" % tuple(parts.by_part))
    else:
        print("\npartition flicker: no static frame pairs with label images%s"
              % (" (%d frames without a label image on %s)" % (no_label_images,
                                                               args.labels_channel)
                 if no_label_images else ""))
    if args.list_flicker and parts.frames:
        print("partition changed in: " + ", ".join("%d:%d" % k for k in parts.frames))
    if args.min_consistency is not None and (
            "tracks" not in kinds or sums["tracks"]["consistency"] < args.min_consistency):
        if "tracks" not in kinds:
            print("\nno track ids to score (tracker off): below %.3f" % args.min_consistency)
        else:
            print("\ntracks consistency %.3f below %.3f" % (sums["tracks"]["consistency"],
                                                           args.min_consistency))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
