#!/usr/bin/env python3
"""Per-stage time chart (SVG) from clutterseg-bench JSON summaries.

One row of panels per JSON file (one data set each):

  * stages: one stacked bar per single-Segmenter configuration of the bench ("1 thread", "pool
    of N"), the stages in the order of the file's "stage_table" from the top of the bar down,
    on an axis scaled to our own totals; a stage's mean ms is written inside its segment where
    the segment is tall enough;
  * table: every stage of the stage table (however many) with its colour, name, mean ms per
    configuration, share of the total and description, so stages too thin to label in the
    bars still read;
  * comparison: total ms per frame of each configuration beside PCL supervoxels + LCCP (its
    two parts stacked) on a scale of its own, with the ratios written out; when the file has
    no "pcl" section (a bench built without PCL or run without --pcl) the panel says so.

Python 3 standard library only.

  plot_stages.py mosd.json synthetic.json -o stages.svg [--names mOSD synthetic]
"""

import argparse
import colorsys
import json
import math
import sys
from xml.sax.saxutils import escape

# Stage colours in stage-table order: neighbours in the stack contrast (Tableau 10, then its
# light variants); a longer table continues with golden-ratio hues.
PALETTE = ["#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#76b7b2", "#edc948", "#b07aa1",
           "#ff9da7", "#9c755f", "#bab0ac", "#a0cbe8", "#ffbe7d", "#8cd17d", "#ff9d9a",
           "#86bcb6", "#f1ce63", "#d4a6c8", "#d7b5a6"]
PCL_PARTS = [("supervoxels_ms", "PCL supervoxels", "#8c2d3c"),
             ("lccp_ms", "PCL LCCP", "#d98c96")]
OURS_TOTAL_COLOUR = "#44546a"
FONT = 12            # px, body text
CHAR_W = 0.55        # mean advance of a sans-serif character, in font sizes (layout estimate)
MIN_LABEL_H = 14     # px of segment height needed to write a value inside it
CALLOUT_PITCH = 13   # px between the baselines of two stage callouts


def stage_colour(i):
    if i < len(PALETTE):
        return PALETTE[i]
    r, g, b = colorsys.hsv_to_rgb((0.13 + 0.618034 * i) % 1.0, 0.55, 0.85)
    return f"#{int(r * 255):02x}{int(g * 255):02x}{int(b * 255):02x}"


def text_colour(fill):
    """Black or white, whichever reads better on `fill` (#rrggbb)."""
    r, g, b = (int(fill[k:k + 2], 16) / 255 for k in (1, 3, 5))
    luminance = 0.2126 * r + 0.7152 * g + 0.0722 * b
    return "#000" if luminance > 0.45 else "#fff"


def text_width(text, size=FONT):
    return len(text) * size * CHAR_W


def fmt_ms(v):
    if v is None:
        return "-"
    if v < 1:
        return f"{v:.2f}"
    if v < 100:
        return f"{v:.1f}"
    return f"{v:.0f}"


def nice_ceiling(value):
    """Rounds up to 1, 2 or 5 times a power of ten."""
    if value <= 0:
        return 1.0
    power = 10.0 ** math.floor(math.log10(value))
    for m in (1, 2, 5, 10):
        if m * power >= value * (1 - 1e-9):
            return m * power
    return 10 * power


def load(path):
    with open(path, encoding="utf-8") as f:
        lines = [line for line in f.read().splitlines() if line.strip()]
    if not lines:
        raise ValueError(f"{path}: empty file")
    return json.loads(lines[-1])


def stage_table(summary):
    """[(name, description, colour)] from the summary's stage table."""
    table = summary.get("stage_table")
    if not table:
        raise ValueError("the JSON has no stage_table (made by an older clutterseg-bench)")
    return [(t["name"], t.get("description", ""), stage_colour(i)) for i, t in enumerate(table)]


def config_label(cfg):
    threads = cfg.get("pool_threads", 1)
    return "1 thread" if threads == 1 else f"pool of {threads}"


def our_configs(summary):
    """The single-Segmenter configurations (1 lane), 1 thread first, as
    [(label, {stage: mean ms}, total ms, cpu ms or None)]."""
    configs = [c for c in summary.get("configs", []) if c.get("lanes", 1) == 1]
    if not configs:
        configs = list(summary.get("configs", []))
    configs.sort(key=lambda c: c.get("pool_threads", 1))
    out = []
    for cfg in configs:
        stages = cfg.get("stages_ms", {})
        means = {k: v["mean"] for k, v in stages.items() if isinstance(v, dict) and "mean" in v}
        total = means.pop("total", None)
        if total is None:
            total = sum(means.values())
        out.append((config_label(cfg), means, total, cfg.get("cpu_ms_per_frame")))
    if not out:
        raise ValueError("the JSON has no configs")
    return out


class Svg:
    def __init__(self):
        self.items = []

    def add(self, s):
        self.items.append(s)

    def text(self, x, y, s, anchor="start", size=None, weight=None, fill=None, extra=""):
        attrs = f'x="{x:.1f}" y="{y:.1f}"'
        if anchor != "start":
            attrs += f' text-anchor="{anchor}"'
        if size:
            attrs += f' font-size="{size}"'
        if weight:
            attrs += f' font-weight="{weight}"'
        if fill:
            attrs += f' fill="{fill}"'
        self.add(f"<text {attrs}{extra}>{escape(s)}</text>")

    def rect(self, x, y, w, h, fill, title=None, stroke=None):
        s = f'<rect x="{x:.1f}" y="{y:.2f}" width="{w:.1f}" height="{h:.2f}" fill="{fill}"'
        if stroke:
            s += f' stroke="{stroke}" stroke-width="0.5"'
        if title:
            self.add(s + f"><title>{escape(title)}</title></rect>")
        else:
            self.add(s + "/>")

    def line(self, x1, y1, x2, y2, stroke="#000", width=1):
        self.add(f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" '
                 f'stroke="{stroke}" stroke-width="{width}"/>')


def axis(svg, x, top, h, width, vmax, label):
    """Horizontal grid lines and a value axis at x, from `top` down `h` px, 0..vmax."""
    ticks = 5
    for i in range(ticks + 1):
        v = vmax * i / ticks
        y = top + h - h * i / ticks
        svg.line(x, y, x + width, y, stroke="#e3e3e3")
        svg.text(x - 6, y + 4, f"{v:g}", anchor="end", size=11, fill="#333")
    svg.line(x, top, x, top + h, stroke="#000")
    cy = top + h / 2
    svg.text(x - 34, cy, label, anchor="middle", size=11, fill="#333",
             extra=f' transform="rotate(-90 {x - 34:.1f} {cy:.1f})"')


# Geometry of one data set's row, px.
LEFT = 70            # left of the stage panel's axis
BAR_W = 64
BAR_GAP = 28
PLOT_H_MIN = 380
TABLE_ROW_H = 21
PANEL_GAP = 56
CMP_BAR_W = 58
CMP_GAP = 18


def spread(wanted, pitch, lo, hi):
    """Positions near `wanted` (ascending) at least `pitch` apart, kept within [lo, hi] where
    they fit: pushed down past their neighbours, then back up from `hi`."""
    out = []
    for w in wanted:
        out.append(max(w, out[-1] + pitch) if out else max(w, lo))
    for i in range(len(out) - 1, -1, -1):
        limit = hi if i == len(out) - 1 else out[i + 1] - pitch
        out[i] = min(out[i], limit)
    return out


def ratio_lines(configs, pcl):
    lines = []
    walls = ", ".join(f"{pcl['total_ms']['mean'] / total:.1f}x vs {label}"
                      for label, _, total, _ in configs if total > 0)
    lines.append(f"PCL / ours, wall time: {walls}")
    pcl_cpu = pcl.get("cpu_ms_per_frame")
    ours_cpu = next((cpu for _, _, _, cpu in configs if cpu), None)
    if pcl_cpu and ours_cpu:
        lines.append(f"CPU per frame: PCL {fmt_ms(pcl_cpu)} / ours {fmt_ms(ours_cpu)} ms "
                     f"= {pcl_cpu / ours_cpu:.1f}x")
    return lines


def pcl_setting(pcl):
    space = ("single-camera transform" if pcl.get("single_camera_transform")
             else "metric voxel space")
    conv = ("extended convexity" if pcl.get("extended_convexity", True)
            else "no extended convexity")
    return f"PCL: {space}, {conv}; one thread"


def render_dataset(svg, top, name, summary):
    """Draws one data set's row with its top at `top`; returns (row height, row width)."""
    stages = stage_table(summary)
    configs = our_configs(summary)
    pcl = summary.get("pcl")

    # Header.
    svg.text(LEFT - 50, top + 16, name, size=15, weight="bold")
    meta = (f"{summary.get('frames')} frames x {summary.get('repeat')} repetitions, "
            f"{summary.get('threads')} cores, load average {summary.get('load_avg_start')}; "
            f"{summary.get('source', '')}")
    svg.text(LEFT - 50 + text_width(name, 15) * 1.2 + 16, top + 16, meta, size=11, fill="#555")
    plot_top = top + 58
    plot_h = max(PLOT_H_MIN, TABLE_ROW_H * (len(stages) + 1) + 10)
    base = plot_top + plot_h

    # Stage panel: stacked bars on a scale of our own totals, every segment called out on the
    # bar's right with its stage name and ms (spread apart where segments are thin).
    def stacked(means):
        return sum(means.get(stage, 0.0) for stage, _, _ in stages)

    ymax = nice_ceiling(max(max(total, stacked(means)) for _, means, total, _ in configs))
    scale = plot_h / ymax
    callout_w = 40 + max(text_width(f"{s} 00.00", 11) for s, _, _ in stages)
    slot_w = BAR_W + callout_w + BAR_GAP // 2
    panel_w = BAR_GAP + len(configs) * slot_w
    svg.text(LEFT, plot_top - 26, "clutterseg, mean ms per frame by stage", size=12,
             weight="bold")
    axis(svg, LEFT, plot_top, plot_h, panel_w, ymax, "ms per frame")
    x = LEFT + BAR_GAP
    for label, means, total, cpu in configs:
        bar_top = base - stacked(means) * scale
        y = bar_top
        segments = []
        for stage, _, colour in stages:
            v = means.get(stage)
            if v is None:
                continue
            h = v * scale
            svg.rect(x, y, BAR_W, h, colour, title=f"{label}, {stage}: {v:.3f} ms")
            segments.append((stage, v, y + h / 2))
            y += h
        for (stage, v, centre), ly in zip(segments, spread([c for _, _, c in segments],
                                                           CALLOUT_PITCH, plot_top, base)):
            svg.add(f'<polyline points="{x + BAR_W:.1f},{centre:.1f} {x + BAR_W + 8:.1f},'
                    f'{centre:.1f} {x + BAR_W + 18:.1f},{ly:.1f} {x + BAR_W + 22:.1f},{ly:.1f}" '
                    f'fill="none" stroke="#888" stroke-width="0.8"/>')
            svg.text(x + BAR_W + 25, ly + 4, stage, size=11)
            svg.text(x + BAR_W + callout_w - 10, ly + 4, fmt_ms(v), anchor="end", size=11,
                     weight="bold")
        top_y = min(base - total * scale, bar_top)
        svg.text(x + BAR_W / 2, top_y - 20, f"{fmt_ms(total)} ms", anchor="middle",
                 weight="bold")
        if cpu is not None:
            svg.text(x + BAR_W / 2, top_y - 6, f"CPU {fmt_ms(cpu)} ms", anchor="middle", size=10,
                     fill="#555")
        svg.text(x + BAR_W / 2, base + 16, label, anchor="middle", size=11, weight="bold")
        x += slot_w

    # Table: every stage with its numbers.
    tx = LEFT + panel_w + 30
    ms_w = max(56, max(text_width(label, 11) for label, _, _, _ in configs) + 16)
    name_w = max(text_width(s, FONT) for s, _, _ in stages + [("stage", "", "")]) + 12
    desc_x = tx + 20 + name_w + len(configs) * ms_w + 56
    ty = plot_top + 4
    svg.text(tx + 20, ty + 10, "stage, ms", size=11, weight="bold")
    for k, (label, _, _, _) in enumerate(configs):
        svg.text(tx + 20 + name_w + (k + 1) * ms_w, ty + 10, label, anchor="end", size=11,
                 weight="bold")
    svg.text(desc_x - 10, ty + 10, "share", anchor="end", size=11, weight="bold")
    svg.text(desc_x, ty + 10, "what it does", size=11, weight="bold")
    svg.line(tx, ty + 15, desc_x + max(text_width(d, 11) for _, d, _ in stages), ty + 15,
             stroke="#bbb")
    ty += TABLE_ROW_H
    first_total = configs[0][2]
    for i, (stage, desc, colour) in enumerate(stages):
        if i % 2:
            svg.rect(tx - 4, ty - 4, desc_x - tx + max(text_width(d, 11) for _, d, _ in stages)
                     + 8, TABLE_ROW_H, "#f5f5f5")
        svg.rect(tx, ty, 14, 14, colour, stroke="#666")
        svg.text(tx + 20, ty + 11, stage)
        for k, (_, means, _, _) in enumerate(configs):
            svg.text(tx + 20 + name_w + (k + 1) * ms_w, ty + 11, fmt_ms(means.get(stage)),
                     anchor="end")
        v0 = configs[0][1].get(stage)
        share = f"{100 * v0 / first_total:.0f}%" if v0 is not None and first_total > 0 else "-"
        if share == "0%":
            share = "<1%"
        svg.text(desc_x - 10, ty + 11, share, anchor="end", fill="#555")
        svg.text(desc_x, ty + 11, desc, size=11, fill="#333")
        ty += TABLE_ROW_H
    svg.text(tx + 20, ty + 11, "total", weight="bold")
    for k, (_, _, total, _) in enumerate(configs):
        svg.text(tx + 20 + name_w + (k + 1) * ms_w, ty + 11, fmt_ms(total), anchor="end",
                 weight="bold")
    svg.text(desc_x, ty + 11, f"share: of the {configs[0][0]} total", size=11, fill="#555")
    table_right = desc_x + max(text_width(d, 11) for _, d, _ in stages)

    # Comparison panel: totals of ours and PCL on a scale of their own.
    cx = table_right + PANEL_GAP
    bars = [(label, [(label, total, OURS_TOTAL_COLOUR)], total) for label, _, total, _ in configs]
    if pcl:
        parts = [(title, pcl[key]["mean"], colour) for key, title, colour in PCL_PARTS
                 if key in pcl]
        bars.append(("PCL sv + LCCP", parts, pcl["total_ms"]["mean"]))
    cmax = nice_ceiling(max(b[2] for b in bars))
    cscale = plot_h / cmax
    cmp_w = CMP_GAP + len(bars) * (CMP_BAR_W + CMP_GAP)
    svg.text(cx, plot_top - 26, "total per frame, ms" + (" vs PCL" if pcl else ""), size=12,
             weight="bold")
    axis(svg, cx, plot_top, plot_h, cmp_w, cmax, "ms per frame")
    x = cx + CMP_GAP
    for label, parts, total in bars:
        y = base
        for part, v, colour in parts:
            h = v * cscale
            y -= h
            svg.rect(x, y, CMP_BAR_W, h, colour, title=f"{part}: {v:.2f} ms")
            if len(parts) > 1 and h >= MIN_LABEL_H:
                svg.text(x + CMP_BAR_W / 2, y + h / 2 + 4, fmt_ms(v), anchor="middle", size=11,
                         fill=text_colour(colour))
        svg.text(x + CMP_BAR_W / 2, base - total * cscale - 6, fmt_ms(total), anchor="middle",
                 weight="bold")
        svg.text(x + CMP_BAR_W / 2, base + 16, label, anchor="middle", size=10)
        x += CMP_BAR_W + CMP_GAP
    notes_y = base + 36
    if pcl:
        for k, (_, title, colour) in enumerate(PCL_PARTS):
            svg.rect(cx + k * 130, notes_y - 10, 12, 12, colour)
            svg.text(cx + k * 130 + 17, notes_y, title, size=11)
        lines = ratio_lines(configs, pcl) + [pcl_setting(pcl)]
    else:
        lines = ["no PCL section in this JSON: clutterseg-bench --pcl", "(built with the pcl preset) adds one"]
    for k, line in enumerate(lines):
        svg.text(cx, notes_y + 18 + 15 * k, line, size=11, fill="#333" if pcl else "#a33")
    right = max(cx + cmp_w, cx + max(text_width(s, 11) for s in lines)) + 20
    height = (notes_y + 18 + 15 * len(lines)) - top + 16
    return height, right


def render(datasets, title):
    svg = Svg()
    y = 70
    width = 0
    for name, summary in datasets:
        h, w = render_dataset(svg, y, name, summary)
        y += h + 24
        width = max(width, w)
    height = y
    head = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
        f'font-family="sans-serif" font-size="{FONT}">',
        f'<rect width="{width:.0f}" height="{height:.0f}" fill="white"/>',
        f'<text x="20" y="28" font-size="17" font-weight="bold">{escape(title)}</text>',
        f'<text x="20" y="48" fill="#555">Mean wall time per frame of one Segmenter (bench '
        f'configurations with one lane); stages from the top of each bar down in pipeline '
        f'order. The right panel has a scale of its own.</text>',
    ]
    return "\n".join(head + svg.items + ["</svg>"]) + "\n"


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("json", nargs="+", help="clutterseg-bench --json outputs")
    parser.add_argument("-o", "--output", required=True, help="SVG file to write")
    parser.add_argument("--names", nargs="*", help="data set names (default: file names)")
    parser.add_argument("--title", help="chart title (default: says whether PCL is in it)")
    args = parser.parse_args(argv)
    names = args.names or [p.rsplit("/", 1)[-1].rsplit(".", 1)[0] for p in args.json]
    if len(names) != len(args.json):
        parser.error("--names needs one name per JSON file")
    datasets = [(name, load(path)) for name, path in zip(names, args.json)]
    title = args.title
    if title is None:
        title = "clutterseg per-stage time"
        if any(summary.get("pcl") for _, summary in datasets):
            title += ", and total vs PCL supervoxels + LCCP"
    svg = render(datasets, title)
    with open(args.output, "w", encoding="utf-8") as f:
        f.write(svg)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
