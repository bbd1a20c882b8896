#!/usr/bin/env python3
"""The adoption protocol of docs/results.md ("Protocol: how a default is chosen") for a set of
candidate configurations, scored on every split in one run.

Splits: the six mOSD categories (boxes, stacked, occluded, cylindric from mosd-learn; mixed and
complex from mosd-clutter), scored with --gt-convention (mosd-parts, the primary score, or
mosd-objects, whole objects); synthetic piles of 10-20 objects (clutterseg-synth --count 15
--objects 10:20) of the tuning seeds 2101 and 2102 and the held-out seeds 2001 and 2002; the
synthetic rooms of seeds 7 and 101 (reported, not used for a choice).

For every held-out split the candidate with the best mean WOv over the other mOSD categories
and the tuning piles is chosen (ties, to four decimals: the first candidate, the reference)
and scored on the split; a candidate is adopted only when no split loses more than 0.002 WOv
against the reference and the mean gains.

Usage:
  tools/split_report.py [--build build/release] [--out out/splits]
      [--gt-convention mosd-parts] [--synthetic-parts] NAME='OPTIONS' [NAME='OPTIONS' ...]
With --synthetic-parts the synthetic sets carry mOSD's part labels (clutterseg-synth
--part-labels: a bowl's or cup's inside is a part of its own) and are scored with
--gt-convention like the mOSD categories; without it they have one label per object (plain).
The first NAME is the reference (usually 'defaults='); OPTIONS are clutterseg-segment options,
e.g. off= on="--set objects.container_max_axis_offset_rel=0.5". Needs the real sets
(tools/data_root.sh); synthetic sets are generated into OUT once. Per-frame CSVs stay in OUT.
"""
import argparse
import csv
import os
import shlex
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mosd_categories import category  # noqa: E402

CATEGORIES = ("boxes", "stacked", "occluded", "cylindric", "mixed", "complex")
TUNING_PILES = ("piles2101", "piles2102")
HELD_OUT_PILES = ("piles2001", "piles2002")
ROOMS = ("rooms7", "rooms101")
# Where the overlap is lost (clutterseg-eval's CSV columns; they add up to 1 - WOv).
LOSSES = ("loss_merged", "loss_split", "loss_boundary", "loss_background")


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def synthetic_sets(build, out, parts):
    """The synthetic sets, generated into OUT once; with `parts` labelled as mOSD's parts
    (clutterseg-synth --part-labels: a vessel's inside is a part of its own), in their own
    directories."""
    synth = os.path.join(build, "tools", "clutterseg-synth")
    extra = ["--part-labels"] if parts else []
    suffix = "_parts" if parts else ""
    sets = {}
    for name in TUNING_PILES + HELD_OUT_PILES:
        d = os.path.join(out, name + suffix)
        if not os.path.isdir(d):
            run([synth, "--out", d, "--count", "15", "--seed", name[5:], "--objects", "10:20"]
                + extra)
        sets[name] = d
    for name, count in (("rooms7", "30"), ("rooms101", "20")):
        d = os.path.join(out, name + suffix)
        if not os.path.isdir(d):
            run([synth, "--out", d, "--count", count, "--seed", name[5:]] + extra)
        sets[name] = d
    return sets


def mean(rows, key):
    return sum(float(r[key]) for r in rows) / len(rows)


def score(build, out, data, sets, convention, synthetic_convention, tag, options):
    seg = os.path.join(build, "tools", "clutterseg-segment")
    ev = os.path.join(build, "tools", "clutterseg-eval")
    rows = {}
    inputs = [("learn", os.path.join(data, "mosd-learn"), convention),
              ("clutter", os.path.join(data, "mosd-clutter"), convention)]
    inputs += [(name, d, synthetic_convention) for name, d in sorted(sets.items())]
    for name, src, conv in inputs:
        csv_path = os.path.join(out, "%s.%s.%s.csv" % (tag, conv, name))
        if not os.path.isfile(csv_path):
            dst = os.path.join(out, "seg")
            shutil.rmtree(dst, ignore_errors=True)
            run([seg, src, dst, "-q", "--force"] + options)
            run([ev, src, dst, "--gt-convention", conv, "-q", "--csv", csv_path])
            shutil.rmtree(dst, ignore_errors=True)
        with open(csv_path) as f:
            frames = list(csv.DictReader(f))
        if name in ("learn", "clutter"):
            for c in CATEGORIES:
                picked = [r for r in frames if category(r["frame"]) == c]
                if picked:
                    rows[c] = picked
        else:
            rows[name] = frames
    return {k: (mean(v, "wov"), mean(v, "f1"), sum(int(r["under_segmented"]) for r in v),
                tuple(mean(v, key) for key in LOSSES) if LOSSES[0] in v[0] else None)
            for k, v in rows.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default="build/release")
    ap.add_argument("--out", default="out/splits")
    ap.add_argument("--gt-convention", default="mosd-parts",
                    choices=("mosd-parts", "mosd-objects"))
    ap.add_argument("--synthetic-parts", action="store_true",
                    help="label the synthetic sets as mOSD's parts (a vessel's inside apart) "
                         "and score them with --gt-convention, as the mOSD categories")
    ap.add_argument("candidates", nargs="+", help="NAME=OPTIONS; the first is the reference")
    args = ap.parse_args()
    data = subprocess.run([os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                        "data_root.sh")],
                          check=True, capture_output=True, text=True).stdout.strip()
    os.makedirs(args.out, exist_ok=True)
    sets = synthetic_sets(args.build, args.out, args.synthetic_parts)
    synthetic_convention = args.gt_convention if args.synthetic_parts else "plain"
    cands = []
    for c in args.candidates:
        name, _, opts = c.partition("=")
        tag = "".join(ch if ch.isalnum() else "_" for ch in name)
        cands.append((name, score(args.build, args.out, data, sets, args.gt_convention,
                                  synthetic_convention, tag, shlex.split(opts))))
    splits = CATEGORIES + TUNING_PILES + HELD_OUT_PILES + ROOMS
    print("Labels of the mOSD categories: %s; of the synthetic sets: %s\n"
          % (args.gt_convention, synthetic_convention))
    print("| configuration | " + " | ".join(splits) + " |")
    print("|---" * (len(splits) + 1) + "|")
    for name, s in cands:
        print("| %s | " % name + " | ".join("%.4f / %.4f (%d)" % s[k][:3] for k in splits) + " |")
    print("\nWhere the overlap is lost, 1 - WOv as merged / split / borders between objects / "
          "borders with the background:\n")
    print("| configuration | " + " | ".join(splits) + " |")
    print("|---" * (len(splits) + 1) + "|")
    for name, s in cands:
        print("| %s | " % name + " | ".join(
            "%.4f / %.4f / %.4f / %.4f" % s[k][3] if s[k][3] else "n/a" for k in splits) + " |")
    ref_name, ref = cands[0]
    print("\nLeave one out (choice on the other mOSD categories and the tuning piles; "
          "WOv / F1 held out):\n")
    print("| held out | chosen | held out | %s | change in WOv |" % ref_name)
    print("|---|---|---|---|---|")
    changes = []
    for held in CATEGORIES + HELD_OUT_PILES:
        train = [c for c in CATEGORIES if c != held] + list(TUNING_PILES)
        best = max(range(len(cands)), key=lambda i: (
            round(sum(cands[i][1][k][0] for k in train) / len(train), 4), -i))
        name, s = cands[best]
        change = s[held][0] - ref[held][0]
        changes.append(change)
        print("| %s | %s | %.4f / %.4f | %.4f / %.4f | %+.4f |" % (
            held, name, s[held][0], s[held][1], ref[held][0], ref[held][1], change))
    worst, avg = min(changes), sum(changes) / len(changes)
    verdict = "adopt" if worst >= -0.002 and avg > 0 else "keep %s" % ref_name
    print("\nmean change %+.4f, worst split %+.4f: %s" % (avg, worst, verdict))


if __name__ == "__main__":
    main()
