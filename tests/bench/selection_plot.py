#!/usr/bin/env python3
"""Plots and tables from selection_bench's per-frame CSVs (event_queue vs topdown).

    TREECUT_SELECTION_CSV=DIR selection_bench > DIR/bench.txt
    python3 tests/bench/selection_plot.py DIR [DIR2 ...] docs/plots

Writes OUT/selection_<path>.svg (one per camera path: a panel per model with
the selection time per frame of both strategies and the cut size, from the
first DIR), OUT/selection_speed.svg (the ratio of the mean iteration times,
event_queue / topdown, against the camera's speed on the sweep, turn, zoom
and dolly paths) and prints docs/benchmarks.md's Markdown table: medians over
the frames after the first (which builds the first cut from the root for
both), the ratio of the means (issue 31's target) and the share of
iterations event_queue spent in plain top-down passes; the orbit and the
flythrough whole, the other paths by segment. With several DIRs (repeated
runs) every cell is the median over the runs of that run's value (each ratio
measured within one run).
"""
import math
import csv
import os
import statistics
import sys

MODELS = [("dragon", "dragon"), ("lion", "lion"), ("terrain20m", "20 M terrain")]
PATHS = ["orbit", "flythrough", "abrupt", "sweep", "turn", "zoom", "dolly"]
# Per-frame speed of a segment, from its name: diameters (sweep), radians
# (turn), or |d ln tan(fov / 2)| and |d ln distance| per frame (zoom over
# N frames from 50 to 35 degrees, a 0.88 dolly notch every N frames).
ZOOM = math.log(math.tan(math.radians(25.0)) / math.tan(math.radians(17.5)))
SPEED_AXES = {"sweep": "diameters a frame", "turn": "radians a frame",
              "zoom": "|d ln tan(fov/2)| a frame", "dolly": "|d ln distance| a frame"}
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


def speed_of(segment):
    kind, value = segment.split(" ", 1)
    if kind in ("sweep", "turn"):
        return float(value)
    frames = float(value.rstrip("f"))
    return ZOOM / frames if kind == "zoom" else math.log(1.0 / 0.88) / frames


def rows_of(rows, path):
    """One table row per segment of a run: the medians of its frames."""
    tail = rows[1:]
    # The orbit and the flythrough whole, the other paths by segment (in the
    # order they come).
    segments = []
    if path in ("orbit", "flythrough"):
        segments.append(("all", tail))
    else:
        names = []
        for r in tail:
            if r["segment"] not in names:
                names.append(r["segment"])
        for seg in names:
            segments.append((seg, [r for r in tail if r["segment"] == seg]))
    out = []
    for seg, rs in segments:
        if not rs:
            continue
        mt, me = med(rs, "topdown_us"), med(rs, "event_queue_us")
        ev = med(rs, "events")
        changed = med(rs, "changed") if "changed" in rs[0] else float("nan")
        descended = med(rs, "descended") if "descended" in rs[0] else float("nan")
        mean_ratio = (sum(float(r["event_queue_us"]) for r in rs) /
                      sum(float(r["topdown_us"]) for r in rs))
        passes = sum(1 for r in rs if float(r["frames_advanced"]) == -2) / len(rs)
        out.append((path if seg == "all" else f"{path}: {seg}",
                    [float(rows[0]["theta"]), med(rs, "cut"), mt, me, me / mt,
                     med(rs, "topdown_tests"), ev, med(rs, "frames_advanced"), changed,
                     descended, 1000.0 * me / ev if ev > 0 else float("nan"), mean_ratio,
                     passes]))
    return out


def speed_plot(table, out):
    """The ratio of the means against the speed, a panel per motion."""
    w, h, left, top = 420.0, 220.0, 60.0, 50.0
    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * w + 40}" '
         f'height="{2 * (h + 70) + 40}" font-family="sans-serif" font-size="12">',
         '<rect width="100%" height="100%" fill="white"/>',
         '<text x="20" y="22" font-size="14">event_queue / topdown, mean iteration time per '
         'segment, against the camera\'s speed (tests/bench/selection_bench)</text>']
    colors = {"dragon": "#1f77b4", "lion": "#2ca02c", "20 M terrain": "#d62728"}
    for k, kind in enumerate(("sweep", "turn", "zoom", "dolly")):
        x0 = 20.0 + left + (k % 2) * (w + 20.0)
        y0 = top + (k // 2) * (h + 70.0)
        pw = w - left - 10.0
        pts = {}
        for label, path, *cells in table:
            if not path.startswith(kind + ": "):
                continue
            pts.setdefault(label, []).append((speed_of(path.split(": ", 1)[1]), cells[11]))
        if not pts:
            continue
        xs = [x for v in pts.values() for x, _ in v]
        lo, hi = math.log(min(xs)) - 0.2, math.log(max(xs)) + 0.2
        ymax = max(1.2, max(y for v in pts.values() for _, y in v) * 1.1)
        sx = lambda x: x0 + pw * (math.log(x) - lo) / (hi - lo)
        sy = lambda y: y0 + h - h * y / ymax
        o.append(f'<rect x="{x0}" y="{y0}" width="{pw}" height="{h}" fill="none" stroke="#888"/>')
        o.append(f'<text x="{x0}" y="{y0 - 6}">{kind}: speed in {SPEED_AXES[kind]} (log)</text>')
        for t in range(5):
            y = ymax * t / 4
            o.append(f'<text x="{x0 - 6}" y="{sy(y) + 4}" text-anchor="end">{y:.2f}</text>')
        for guide, dash in ((1.05, "6 3"), (0.35, "2 3")):
            o.append(f'<line x1="{x0}" x2="{x0 + pw}" y1="{sy(guide)}" y2="{sy(guide)}" '
                     f'stroke="#999" stroke-dasharray="{dash}"/>')
            o.append(f'<text x="{x0 + pw - 4}" y="{sy(guide) - 3}" text-anchor="end" '
                     f'fill="#777">{guide}</text>')
        for x in sorted(set(xs)):
            o.append(f'<text x="{sx(x)}" y="{y0 + h + 14}" text-anchor="middle">{x:.3g}</text>')
        for i, (label, v) in enumerate(sorted(pts.items())):
            v.sort()
            line = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y in v)
            c = colors.get(label, "#555")
            o.append(f'<polyline fill="none" stroke="{c}" stroke-width="1.5" points="{line}"/>')
            for x, y in v:
                o.append(f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="3" fill="{c}"/>')
            o.append(f'<text x="{x0 + 8}" y="{y0 + 16 + 14 * i}" fill="{c}">{label}</text>')
    o.append("</svg>")
    write_checked(os.path.join(out, "selection_speed.svg"), "\n".join(o) + "\n")


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
    speed_plot(table, out)
    print("| model | path | theta | cut (median) | topdown us | event_queue us | event / top |"
          " mean event / mean top | passes | tests (top) | events | changed | children tested |"
          " ns / event | frames advanced |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (label, path, theta, cut, mt, me, ratio, tests, events, adv, changed, desc, ns,
         mean_ratio, passes) in table:
        advanced = "pass" if adv == -2 else "rebuild" if adv < 0 else f"{adv:g}"
        # A rebuild's changes are the top-down pass's, not counted as events.
        ch = "-" if changed != changed or adv < 0 else f"{changed:,.0f}"
        de = "-" if desc != desc or adv < 0 else f"{desc:,.0f}"
        print(f"| {label} | {path} | {theta:.2f} | {cut:,.0f} | {fmt(mt)} | {fmt(me)} | "
              f"{ratio:.2f} | {mean_ratio:.2f} | {100 * passes:.0f} % | {tests:,.0f} | "
              f"{events:,.0f} | {ch} | {de} | {ns:.0f} | {advanced} |")


if __name__ == "__main__":
    main()
