#!/usr/bin/env python3
"""Plots of bench occlusion's HLOD table along each walkthrough.

    treecut bench occlusion city.ply --path assets/paths/city_walk.campath --csv DIR
    (the same for plant and field)
    python3 tests/bench/occlusion_plot.py DIR docs/plots

Reads DIR/occlusion_SCENE.csv (per frame and method: frame_ms, drawn_blocks,
rarn, delayed, ...; demo/bench_hlod.cpp writes it) and writes
OUT/occlusion_SCENE.svg: two stacked charts over the frames of the walk, the
frame time and the drawn HLOD blocks (DN) of Bool, SW(B), Simp(B), Coh(B) and
the hoq stage strategy. Plain python3, no packages.
"""
import csv
import glob
import os
import sys

COLORS = ["#999999", "#1f77b4", "#ff7f0e", "#d62728", "#2ca02c", "#9467bd"]


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    methods = []
    data = {}
    for r in rows:
        m = r["method"]
        if m not in data:
            methods.append(m)
            data[m] = []
        data[m].append(r)
    return methods, data


def chart(methods, data, key, label, x0, y0, w, h):
    top = max(float(r[key]) for m in methods for r in data[m]) * 1.1 or 1.0
    n = max(len(data[m]) for m in methods)
    out = [f'<text x="{x0}" y="{y0 - 8}" font-size="13">{label}</text>',
           f'<rect x="{x0}" y="{y0}" width="{w}" height="{h}" fill="none" stroke="#ccc"/>']
    for i in range(5):
        v = top * i / 4
        y = y0 + h - h * i / 4
        out.append(f'<text x="{x0 - 6}" y="{y + 4:.1f}" font-size="10" text-anchor="end">'
                   f'{v:.0f}</text>')
    for c, m in enumerate(methods):
        pts = " ".join(f"{x0 + w * i / max(n - 1, 1):.1f},{y0 + h - h * float(r[key]) / top:.1f}"
                       for i, r in enumerate(data[m]))
        out.append(f'<polyline points="{pts}" fill="none" stroke="{COLORS[c % len(COLORS)]}" '
                   f'stroke-width="1.2"/>')
    out.append(f'<text x="{x0 + w / 2}" y="{y0 + h + 16}" font-size="10" text-anchor="middle">'
               f'frame of the walk (of {n})</text>')
    return out


def plot(path, dst):
    scene = os.path.basename(path)[len("occlusion_"):-len(".csv")]
    methods, data = load(path)
    w, h, left, top_margin, gap = 860, 240, 70, 50, 60
    height = top_margin + 2 * h + gap + 40 + 18 * len(methods)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{left + w + 30}" height="{height}" '
           f'font-family="sans-serif" font-size="12">',
           '<rect width="100%" height="100%" fill="white"/>',
           f'<text x="{left}" y="22" font-size="14">treecut bench occlusion, HLOD refinement: '
           f'{scene}</text>']
    out += chart(methods, data, "frame_ms", "frame time, ms (glFinish-ed wall time)", left,
                 top_margin, w, h)
    out += chart(methods, data, "drawn_blocks", "drawn HLOD blocks (DN)", left,
                 top_margin + h + gap, w, h)
    y = top_margin + 2 * h + gap + 34
    for c, m in enumerate(methods):
        out.append(f'<line x1="{left}" y1="{y - 4}" x2="{left + 24}" y2="{y - 4}" '
                   f'stroke="{COLORS[c % len(COLORS)]}" stroke-width="2"/>')
        out.append(f'<text x="{left + 30}" y="{y}">{m}</text>')
        y += 18
    out.append("</svg>")
    target = os.path.join(dst, f"occlusion_{scene}.svg")
    with open(target + ".tmp", "w") as f:
        f.write("\n".join(out) + "\n")
    os.replace(target + ".tmp", target)
    print(target)


def main():
    src, dst = sys.argv[1], sys.argv[2]
    files = sorted(glob.glob(os.path.join(src, "occlusion_*.csv")))
    if not files:
        sys.exit(f"{src}: no occlusion_*.csv")
    os.makedirs(dst, exist_ok=True)
    for path in files:
        plot(path, dst)


if __name__ == "__main__":
    main()
