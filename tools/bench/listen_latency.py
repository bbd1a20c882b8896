#!/usr/bin/env python3
"""Latency and delivery of one daemon run, from `clutterseg-listen` output of its log.

Reads the text `clutterseg-listen --lcm-url 'file://LOG?speed=0'` printed and reports, over
the frames after the first WARMUP: segment and capture-to-publish percentiles (nearest rank,
ms), frames published, frame_seq gaps (frames of the source that were never published), and
the last status line's dropped count (and overlay counts when asked).

Usage: listen_latency.py LISTEN_TXT [--warmup N] [--json]
Prints one line `published P gaps G dropped D seg_p50 A seg_p99 B c2p_p50 C c2p_p99 E
c2p_max F` (or a JSON object with --json). Standard library only.
"""
import argparse
import json
import re
import sys


def pct(values, q):
    """Nearest-rank percentile q (0..100) of values; nan when empty."""
    v = sorted(values)
    if not v:
        return float("nan")
    return v[max(0, min(len(v) - 1, int(-(-q * len(v) // 100)) - 1))]


def scan(path, warmup):
    seg, c2p, seqs = [], [], []
    result = {"dropped": None, "overlays_written": None, "overlays_dropped": None}
    obj = re.compile(r"^CLUTTERSEG_OBJECTS frame (\d+) .*segment ([\d.]+) ms, "
                     r"capture->publish ([\d.]+) ms")
    for line in open(path, errors="replace"):
        m = obj.search(line)
        if m:
            seqs.append(int(m.group(1)))
            seg.append(float(m.group(2)))
            c2p.append(float(m.group(3)))
            continue
        m = re.search(r"^CLUTTERSEG_STATUS .*dropped (\d+)", line)
        if m:
            result["dropped"] = int(m.group(1))
        m = re.search(r"^CLUTTERSEG_STATUS .*overlays (\d+) written / (\d+) dropped", line)
        if m:
            result["overlays_written"] = int(m.group(1))
            result["overlays_dropped"] = int(m.group(2))
    # A looped recording restarts frame_seq; a gap is a step of more than one inside a pass.
    gaps = sum(b - a - 1 for a, b in zip(seqs, seqs[1:]) if b > a + 1)
    seg, c2p = seg[warmup:], c2p[warmup:]
    result.update({
        "published": len(seqs), "gaps": gaps,
        "seg_p50": pct(seg, 50), "seg_p99": pct(seg, 99),
        "c2p_p50": pct(c2p, 50), "c2p_p99": pct(c2p, 99),
        "c2p_max": max(c2p) if c2p else float("nan"),
    })
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("listen_txt")
    ap.add_argument("--warmup", type=int, default=30)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    r = scan(a.listen_txt, a.warmup)
    if a.json:
        print(json.dumps(r))
    else:
        print(" ".join("%s %s" % (k, ("%.1f" % v) if isinstance(v, float) else v)
                       for k, v in r.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
