#!/usr/bin/env python3
"""Markdown tables for README.md from strategy_bench / exchange_bench output.

    strategy_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \\
        | python3 tests/bench/tables.py
    exchange_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \\
        | python3 tests/bench/tables.py

Reads Google Benchmark's console output (the `_median` aggregate rows) and
prints one table per benchmark family it finds.
"""
import re
import sys

ROW = re.compile(r"^(BM_\w+)/(\S*?)(?:/manual_time)?_median\s+.*?\s(\w+=\S+(?:\s+\w+=\S+)*)\s*$")
UNITS = {"k": 1e3, "M": 1e6, "G": 1e9}
MODELS = {0: "dragon", 1: "20 M cloud"}


def number(text):
    if text[-1] in UNITS:
        return float(text[:-1]) * UNITS[text[-1]]
    return float(text)


def parse(lines):
    rows = []
    for line in lines:
        m = ROW.match(line.strip())
        if not m:
            continue
        args = dict(a.split(":") for a in m.group(2).split("/") if ":" in a)
        counters = {k: number(v) for k, v in (c.split("=") for c in m.group(3).split())}
        rows.append((m.group(1), {k: int(v) for k, v in args.items()}, counters))
    return rows


def size(n):
    return f"{n / 1e6:g}M" if n >= 1e6 else f"{n / 1e3:g}k"


def strategies(rows):
    names = {"BM_Optimization": "optimization (k = 8192)", "BM_Bucket": "bucket",
             "BM_Recursive": "recursive (per visited node)"}
    print("| strategy | model | ns per node at cut size (median) | largest / smallest |")
    print("|---|---|---|---:|")
    for bench, label in names.items():
        for model, model_name in MODELS.items():
            points = sorted((a["cut"], c["ns_per_node"]) for b, a, c in rows
                            if b == bench and a.get("model") == model)
            if not points:
                continue
            cells = ", ".join(f"{size(n)}: {ns:.1f}" for n, ns in points)
            print(f"| {label} | {model_name} | {cells} | {points[-1][1] / points[0][1]:.2f} |")


def exchange(rows):
    names = {"BM_EmptyTimedRegion": "empty timed region (noise floor)",
             "BM_PollExchangeProtocol": "protocol, stage stepped between frames",
             "BM_PollExchange": "stage on its own thread"}
    print("| variant | cut | exchange median | p99.9 | max | frame median |")
    print("|---|---:|---:|---:|---:|---:|")
    for bench, label in names.items():
        for b, a, c in rows:
            if b != bench:
                continue
            what = f"work {a['work']}" if "work" in a else size(a["cut"])
            print(f"| {label} | {what} | {c['xchg_median_ns']:.0f} ns | "
                  f"{c['xchg_p999_ns']:.0f} ns | {c['xchg_max_ns'] / 1e3:.1f} us | "
                  f"{c['frame_median_ns']:.0f} ns |")


def main():
    rows = parse(sys.stdin)
    if not rows:
        sys.exit("no _median rows: run with --benchmark_repetitions=N "
                 "--benchmark_report_aggregates_only=true")
    families = {b for b, _, _ in rows}
    if families & {"BM_Optimization", "BM_Bucket", "BM_Recursive"}:
        strategies(rows)
    if families & {"BM_PollExchange", "BM_PollExchangeProtocol"}:
        exchange(rows)


if __name__ == "__main__":
    main()
