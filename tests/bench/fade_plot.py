#!/usr/bin/env python3
"""Plot and table of render_bench's FadeStability (fades of an exchange).

    TREECUT_FADE_CSV=DIR render_bench --benchmark_filter=FadeStability
    python3 tests/bench/fade_plot.py DIR docs/plots

Reads DIR/fades_B_S.csv (budget = leaves / B, camera step S / 1000 degrees
per frame; per frame the changed-pixel fraction and frame time of the frozen
cut and of blend 0, 4 and 8), writes OUT/fades.svg (a panel per file: the
changed fraction per frame of each condition) and prints the Markdown table:
the largest changed fraction, its ratio to blend 0, the same above the motion
floor (frozen cut), and the median frame time.
"""
import csv
import glob
import os
import re
import statistics
import sys

COLORS = {"frozen": "#999999", "0": "#d62728", "4": "#1f77b4", "8": "#2ca02c"}
LABELS = {"frozen": "cut frozen (camera motion only)", "0": "no fade", "4": "--blend 4",
          "8": "--blend 8"}


def load(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def series(rows, key):
    return [100.0 * float(r[key]) for r in rows]


def panel(rows, title, x0, y0, w, h):
    keys = ["frozen", "0", "4", "8"]
    data = {k: series(rows, "changed_" + k) for k in keys}
    top = max(max(v) for v in data.values()) * 1.1 or 1.0
    n = len(rows)
    out = [f'<text x="{x0}" y="{y0 - 8}" font-size="13">{title}</text>',
           f'<rect x="{x0}" y="{y0}" width="{w}" height="{h}" fill="none" stroke="#ccc"/>']
    for i in range(5):
        v = top * i / 4
        y = y0 + h - h * i / 4
        out.append(f'<text x="{x0 - 6}" y="{y + 4:.1f}" font-size="10" text-anchor="end">'
                   f'{v:.2f}%</text>')
    for k in keys:
        pts = " ".join(f"{x0 + w * i / max(n - 1, 1):.1f},{y0 + h - h * v / top:.1f}"
                       for i, v in enumerate(data[k]))
        out.append(f'<polyline points="{pts}" fill="none" stroke="{COLORS[k]}" '
                   f'stroke-width="1.2"/>')
    out.append(f'<text x="{x0 + w / 2}" y="{y0 + h + 16}" font-size="10" text-anchor="middle">'
               f'frame (of {n})</text>')
    return out


def main():
    src, dst = sys.argv[1], sys.argv[2]
    files = sorted(glob.glob(os.path.join(src, "fades_*.csv")),
                   key=lambda p: [int(x) for x in re.findall(r"\d+", os.path.basename(p))])
    if not files:
        sys.exit(f"{src}: no fades_*.csv")
    w, h, gap = 520, 170, 60
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w + 120}" '
           f'height="{len(files) * (h + gap) + 60}" font-family="sans-serif">',
           '<rect width="100%" height="100%" fill="white"/>']
    print("| budget | camera | cut motion floor | no fade | --blend 4 | --blend 8 | "
          "above floor: 0 / 4 / 8 | frame ms: 0 / 4 / 8 |")
    print("|---|---|---|---|---|---|---|---|")
    for i, path in enumerate(files):
        b, s = re.findall(r"\d+", os.path.basename(path))[:2]
        rows = load(path)
        title = f"dragon, budget leaves/{b}, orbit {int(s) / 1000:g} deg/frame: changed pixels %"
        svg += panel(rows, title, 80, 40 + i * (h + gap), w, h)
        mx = {k: max(series(rows, "changed_" + k)) for k in ["frozen", "0", "4", "8"]}
        ms = {k: statistics.median(float(r["frame_ms_" + k]) for r in rows) for k in "048"}
        above = {k: max(mx[k] - mx["frozen"], 0.0) for k in "048"}
        print(f"| leaves/{b} | {int(s) / 1000:g} deg/frame | {mx['frozen']:.3f} % | "
              f"{mx['0']:.3f} % | {mx['4']:.3f} % ({mx['4'] / mx['0']:.2f}x) | "
              f"{mx['8']:.3f} % ({mx['8'] / mx['0']:.2f}x) | "
              f"{above['0']:.3f} / {above['4']:.3f} / {above['8']:.3f} % | "
              f"{ms['0']:.1f} / {ms['4']:.1f} / {ms['8']:.1f} |")
    y = len(files) * (h + gap) + 30
    for j, k in enumerate(["frozen", "0", "4", "8"]):
        x = 80 + j * 140
        svg.append(f'<line x1="{x}" y1="{y}" x2="{x + 20}" y2="{y}" stroke="{COLORS[k]}" '
                   f'stroke-width="2"/>')
        svg.append(f'<text x="{x + 25}" y="{y + 4}" font-size="10">{LABELS[k]}</text>')
    svg.append("</svg>")
    os.makedirs(dst, exist_ok=True)
    with open(os.path.join(dst, "fades.svg"), "w") as f:
        f.write("\n".join(svg) + "\n")


if __name__ == "__main__":
    main()
