#!/usr/bin/env python3
"""Plots and tables from selection_bench's per-frame CSVs (event_queue vs topdown).

    TREECUT_SELECTION_CSV=DIR selection_bench > DIR/bench.txt
    python3 tests/bench/selection_plot.py DIR [DIR2 ...] docs/plots

Writes OUT/selection_<path>.svg (one per camera path: a panel per model with
the selection time per frame of both strategies and the cut size, from the
first DIR) and prints docs/benchmarks.md's Markdown table: medians over the frames
after the first (which builds the first cut from the root for both), and for
the abrupt path the medians of its segments (fast turn, teleport frames,
frames after a teleport). With several DIRs (repeated runs) every cell is
the median over the runs of that run's median, and the ratio column the
median of the runs' ratios (each measured within one run).
"""
import csv
import os
import statistics
import sys

MODELS = [("dragon", "dragon"), ("lion", "lion"), ("terrain20m", "20 M terrain")]
PATHS = ["orbit", "flythrough", "abrupt"]
COLORS = {"topdown": "#d62728", "event_queue": "#1f77b4", "cut": "#999999"}


def load(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def med(rows, key):
    return statistics.median(float(r[key]) for r in rows) if rows else float("nan")


def fmt(x):
    return f"{x:,.0f}" if x >= 100 else f"{x:.3g}"


def panel(o, rows, y0, title, w=900.0, h=200.0, left=70.0, right=70.0):
    pw = w - left - right
    tmax = max(max(float(r["topdown_us"]), float(r["event_queue_us"])) for r in rows) / 1000.0
    cmax = max(float(r["cut"]) for r in rows)
    tmax = tmax if tmax > 0 else 1.0
    n = max(len(rows) - 1, 1)
    o.append(f'<rect x="{left}" y="{y0}" width="{pw}" height="{h}" fill="none" stroke="#888"/>')
    o.append(f'<text x="{left}" y="{y0 - 6}">{title}: selection time [ms] (max {tmax:.3g}), '
             f'cut size (grey, right axis, max {cmax:,.0f})</text>')
    for t in range(5):
        y = y0 + h - h * t / 4
        o.append(f'<text x="{left - 6}" y="{y + 4}" text-anchor="end">{tmax * t / 4:.3g}</text>')
        o.append(f'<text x="{left + pw + 6}" y="{y + 4}">{cmax * t / 4:,.0f}</text>')
    for key, scale, color in (("cut", cmax, COLORS["cut"]),
                              ("topdown_us", tmax * 1000.0, COLORS["topdown"]),
                              ("event_queue_us", tmax * 1000.0, COLORS["event_queue"])):
        pts = " ".join(f"{left + pw * i / n:.1f},{y0 + h - h * float(r[key]) / scale:.1f}"
                       for i, r in enumerate(rows))
        dash = ' stroke-dasharray="4 3"' if key == "cut" else ""
        o.append(f'<polyline fill="none" stroke="{color}" stroke-width="1.2"{dash} points="{pts}"/>')
    o.append(f'<text x="{left + pw / 2}" y="{y0 + h + 16}" text-anchor="middle">frame</text>')


def rows_of(rows, path):
    """One table row per segment of a run: the medians of its frames."""
    tail = rows[1:]
    # The abrupt path only by segment: its three parts have nothing in common.
    segments = [] if path == "abrupt" else [("all", tail)]
    if path == "abrupt":
        for seg in ("fast turn", "teleport", "after teleport"):
            segments.append((seg, [r for r in tail if r["segment"] == seg]))
    out = []
    for seg, rs in segments:
        if not rs:
            continue
        mt, me = med(rs, "topdown_us"), med(rs, "event_queue_us")
        ev = med(rs, "events")
        changed = med(rs, "changed") if "changed" in rs[0] else float("nan")
        descended = med(rs, "descended") if "descended" in rs[0] else float("nan")
        out.append((path if seg == "all" else f"{path}: {seg}",
                    [float(rows[0]["theta"]), med(rs, "cut"), mt, me, me / mt,
                     med(rs, "topdown_tests"), ev, med(rs, "frames_advanced"), changed,
                     descended, 1000.0 * me / ev if ev > 0 else float("nan")]))
    return out


def write_checked(name, text):
    # Beside the target, then renamed: a failed write leaves the old plot.
    tmp = name + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, name)


def main():
    srcs, out = sys.argv[1:-1], sys.argv[-1]
    table = []
    for path in PATHS:
        o = []
        y = 50.0
        for model, label in MODELS:
            runs = [load(os.path.join(src, f"{model}_{path}.csv")) for src in srcs
                    if os.path.exists(os.path.join(src, f"{model}_{path}.csv"))]
            if not runs:
                continue
            panel(o, runs[0], y, label)
            y += 250.0
            per_run = [rows_of(rows, path) for rows in runs]
            for i, (name, _) in enumerate(per_run[0]):
                cells = [statistics.median(r[i][1][k] for r in per_run)
                         for k in range(len(per_run[0][i][1]))]
                table.append((label, name, *cells))
        if not o:
            continue
        head = [f'<svg xmlns="http://www.w3.org/2000/svg" width="900" height="{y + 10}" '
                'font-family="sans-serif" font-size="12">',
                '<rect width="100%" height="100%" fill="white"/>',
                f'<text x="70" y="20" font-size="14">selection time per frame, path "{path}": '
                'event_queue vs topdown (tests/bench/selection_bench)</text>',
                f'<rect x="70" y="28" width="14" height="4" fill="{COLORS["topdown"]}"/>'
                '<text x="90" y="33">topdown</text>',
                f'<rect x="200" y="28" width="14" height="4" fill="{COLORS["event_queue"]}"/>'
                '<text x="220" y="33">event_queue</text>',
                f'<rect x="350" y="28" width="14" height="4" fill="{COLORS["cut"]}"/>'
                '<text x="370" y="33">cut size</text>']
        write_checked(os.path.join(out, f"selection_{path}.svg"),
                      "\n".join(head + o + ["</svg>"]) + "\n")
    print("| model | path | theta | cut (median) | topdown us | event_queue us | event / top |"
          " tests (top) | events | changed | children tested | ns / event | frames advanced |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, path, theta, cut, mt, me, ratio, tests, events, adv, changed, desc, ns in table:
        advanced = "rebuild" if adv < 0 else f"{adv:g}"
        # A rebuild's changes are the top-down pass's, not counted as events.
        ch = "-" if changed != changed or adv < 0 else f"{changed:,.0f}"
        de = "-" if desc != desc or adv < 0 else f"{desc:,.0f}"
        print(f"| {label} | {path} | {theta:.2f} | {cut:,.0f} | {fmt(mt)} | {fmt(me)} | "
              f"{ratio:.2f} | {tests:,.0f} | {events:,.0f} | {ch} | {de} | {ns:.0f} | {advanced} |")


if __name__ == "__main__":
    main()
