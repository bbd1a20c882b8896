#!/usr/bin/env python3
"""Stacked per-stage bar chart (SVG) from clutterseg-bench JSON summaries.

For every JSON file (one data set each) the chart shows one bar per segmenter configuration
(per-stage mean wall times, stacked) and, when the file has a "pcl" section, one bar for PCL
supervoxels + LCCP (supervoxels and LCCP stacked). Python 3 standard library only.

  plot_stages.py mosd.json synthetic.json -o stages.svg [--names mOSD synthetic]
"""

import argparse
import json
import sys
from xml.sax.saxutils import escape

# Colours for the stages, in the order of the bench's "stage_table" (pipeline::StageTable()).
PALETTE = ["#9e9e9e", "#1f77b4", "#aec7e8", "#2ca02c", "#5ab55a", "#b5dfb5", "#98df8a",
           "#ff7f0e", "#9467bd", "#c5b0d5", "#8c564b", "#c49c94", "#e377c2", "#f7b6d2"]
PCL_STAGES = [
    ("supervoxels_ms", "PCL supervoxels", "#d62728"),
    ("lccp_ms", "PCL LCCP", "#ff9896"),
]
# Which configurations to draw, in order, and their short labels.
CONFIGS = [
    ("1 lane, no pool", "ours 1 thread"),
    ("1 lane, pool", "ours pool"),
]


def stage_table(summary):
    """[(name, description, colour)] from the summary's stage table."""
    table = summary.get("stage_table")
    if not table:
        raise ValueError("the JSON has no stage_table (made by an older clutterseg-bench)")
    return [(t["name"], t["description"], PALETTE[i % len(PALETTE)]) for i, t in enumerate(table)]


def load(path):
    with open(path, encoding="utf-8") as f:
        lines = [line for line in f.read().splitlines() if line.strip()]
    if not lines:
        raise ValueError(f"{path}: empty file")
    return json.loads(lines[-1])


def bars_for(summary):
    """Returns [(label, [(stage_key, value_ms, colour)], total_ms, cpu_ms or None)]."""
    bars = []
    for prefix, label in CONFIGS:
        for cfg in summary.get("configs", []):
            if cfg["name"].startswith(prefix) and cfg.get("lanes", 1) == 1:
                stages = cfg["stages_ms"]
                parts = [(key, stages[key]["mean"], colour)
                         for key, _, colour in stage_table(summary)]
                if prefix.endswith("pool"):
                    label = f"ours pool {cfg.get('pool_threads', '')}".strip()
                bars.append((label, parts, stages["total"]["mean"], cfg.get("cpu_ms_per_frame")))
                break
    pcl = summary.get("pcl")
    if pcl:
        parts = [(key, pcl[key]["mean"], colour) for key, _, colour in PCL_STAGES]
        bars.append(("PCL sv+LCCP", parts, pcl["total_ms"]["mean"], pcl.get("cpu_ms_per_frame")))
    return bars


def nice_ceiling(value):
    """Rounds up to 1, 2 or 5 times a power of ten."""
    if value <= 0:
        return 1.0
    power = 1.0
    while power * 10 < value:
        power *= 10
    while power > value:
        power /= 10
    for m in (1, 2, 5, 10):
        if m * power >= value:
            return m * power
    return 10 * power


def render(datasets, title):
    bar_w, gap, group_gap = 56, 18, 70
    left, top, plot_h, bottom = 80, 100, 360, 90
    groups = [(name, bars_for(summary), summary) for name, summary in datasets]
    top += 14 * max(0, len(groups) - 2)
    n_bars = sum(len(b) for _, b, _ in groups)
    width = left + n_bars * (bar_w + gap) + (len(groups) - 1) * group_gap + 300
    height = top + plot_h + bottom
    ymax = nice_ceiling(max((b[2] for _, bars, _ in groups for b in bars), default=1.0) * 1.08)
    scale = plot_h / ymax

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'font-family="sans-serif" font-size="12">',
        f'<rect width="{width}" height="{height}" fill="white"/>',
        f'<text x="{left}" y="24" font-size="16" font-weight="bold">{escape(title)}</text>',
    ]
    out.append(f'<text x="{left}" y="42" fill="#555">Mean wall time per frame, ms, stacked by '
               f'stage; above the bars: wall / CPU ms per frame</text>')
    for i, (name, _, s) in enumerate(groups):
        out.append(f'<text x="{left}" y="{58 + 14 * i}" fill="#555" font-size="11">'
                   f'{escape(name)}: {s.get("frames")} frames x {s.get("repeat")} repetitions, '
                   f'{s.get("threads")} cores, load average {escape(str(s.get("load_avg_start")))}'
                   f'</text>')

    # Axis and grid.
    ticks = 5
    for i in range(ticks + 1):
        v = ymax * i / ticks
        y = top + plot_h - v * scale
        out.append(f'<line x1="{left}" y1="{y:.1f}" x2="{width - 290}" y2="{y:.1f}" '
                   f'stroke="#ddd"/>')
        out.append(f'<text x="{left - 8}" y="{y + 4:.1f}" text-anchor="end">{v:g}</text>')
    out.append(f'<line x1="{left}" y1="{top}" x2="{left}" y2="{top + plot_h}" stroke="black"/>')
    out.append(f'<text x="20" y="{top + plot_h / 2}" transform="rotate(-90 20 {top + plot_h / 2})" '
               f'text-anchor="middle">ms per frame</text>')

    x = left + gap
    for name, bars, _ in groups:
        group_start = x
        for label, parts, total, cpu in bars:
            y = top + plot_h
            for key, value, colour in parts:
                h = value * scale
                y -= h
                out.append(f'<rect x="{x}" y="{y:.2f}" width="{bar_w}" height="{h:.2f}" '
                           f'fill="{colour}"><title>{escape(label)} {escape(key)}: '
                           f'{value:.2f} ms</title></rect>')
            text = f"{total:.0f}" if cpu is None else f"{total:.0f} / {cpu:.0f}"
            out.append(f'<text x="{x + bar_w / 2}" y="{y - 6:.1f}" text-anchor="middle">'
                       f'{text}</text>')
            out.append(f'<text x="{x + bar_w / 2}" y="{top + plot_h + 16}" text-anchor="middle" '
                       f'font-size="11">{escape(label)}</text>')
            x += bar_w + gap
        centre = (group_start + x - gap) / 2
        out.append(f'<text x="{centre}" y="{top + plot_h + 40}" text-anchor="middle" '
                   f'font-weight="bold">{escape(name)}</text>')
        pcl = [b for b in bars if b[0].startswith("PCL")]
        ours = [b for b in bars if not b[0].startswith("PCL")]
        if pcl and ours:
            best = min(b[2] for b in ours)
            line = f"PCL / ours: {pcl[0][2] / best:.1f}x wall"
            if pcl[0][3] and ours[0][3]:
                line += f", {pcl[0][3] / ours[0][3]:.1f}x CPU"
            out.append(f'<text x="{centre}" y="{top + plot_h + 58}" text-anchor="middle" '
                       f'fill="#555">{escape(line)}</text>')
        x += group_gap

    # Legend.
    lx = width - 280
    ly = top
    for _, label, colour in stage_table(datasets[0][1]) + PCL_STAGES:
        out.append(f'<rect x="{lx}" y="{ly}" width="14" height="14" fill="{colour}"/>')
        out.append(f'<text x="{lx + 20}" y="{ly + 11}">{escape(label)}</text>')
        ly += 20
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("json", nargs="+", help="clutterseg-bench --json outputs")
    parser.add_argument("-o", "--output", required=True, help="SVG file to write")
    parser.add_argument("--names", nargs="*", help="data set names (default: file names)")
    parser.add_argument("--title", default="clutterseg per-stage time vs PCL supervoxels + LCCP")
    args = parser.parse_args(argv)
    names = args.names or [p.rsplit("/", 1)[-1].rsplit(".", 1)[0] for p in args.json]
    if len(names) != len(args.json):
        parser.error("--names needs one name per JSON file")
    datasets = [(name, load(path)) for name, path in zip(names, args.json)]
    svg = render(datasets, args.title)
    with open(args.output, "w", encoding="utf-8") as f:
        f.write(svg)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
