#!/usr/bin/env python3
"""One Markdown table row per `run --scene` report: load + fit, AS build, CPU reference, worker
device setup, the CLI's peak memory (`scene.cost.peak_mib`), and, when `NAME.time` (the output of
`/usr/bin/time -v`) lies beside `NAME.json`, the largest process's max RSS and the wall time.

    timing.py LABEL=run-test.json LABEL=run-1m.json ...      (.json or .json.gz)
"""
import gzip
import json
import os
import re
import sys


def load(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return json.load(f)


def time_v(path):
    base = re.sub(r"\.json(\.gz)?$", "", path)
    try:
        text = open(base + ".time").read()
    except OSError:
        return "—", "—"
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    wall = re.search(r"Elapsed \(wall clock\) time.*: (\S+)", text)
    return (f"{int(rss.group(1)) // 1024} MiB" if rss else "—", wall.group(1) if wall else "—")


def row(label, path):
    r = load(path)
    c, t, sc = r["scene"].get("cost") or {}, r["timing"], r["scene"]
    rss, wall = time_v(path)
    build = (f"{t['as_build_ms_mean']:.1f} ms (max {t['as_build_ms_max']:.1f}, {t['as_builds']} workers)"
             if t.get("as_builds") else "—")
    return (f"| {label} | {sc.get('triangles', '—')} | {c.get('load_ms', 0):.1f} ms | {build} | "
            f"{c.get('reference_ms', 0):.0f} ms | {t['device_ms_mean']:.0f} ms | "
            f"{c.get('peak_mib', '—')} MiB | {rss} | {wall} |")


def main(args):
    print("| scene | triangles | load + fit | AS build | CPU reference | worker device setup (incl. AS build) "
          "| peak memory (CLI) | max RSS (`time -v`) | wall (`time -v`) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for a in args:
        label, _, path = a.partition("=")
        print(row(label, path if path else label))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: timing.py LABEL=REPORT.json ...")
    main(sys.argv[1:])
