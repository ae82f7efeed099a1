#!/usr/bin/env python3
"""rtprobe's own costs in a run, from its report (JSON or .json.gz) and, optionally, the
supervisor's trace log of the same run (`RUST_LOG=trace rtprobe run ... 2> trace.txt`).

Report: per attempt that ran to completion, `check_ms` (readback + reference + comparison),
`readback_ms` where the build records it, and the supervisor-observed overhead (the attempt's
`wall_ms` minus the worker's `total_ms`); the report's `timing` (wall, prebuild).
Trace: per cell of each worker, the time from its `Result` line to the next cell's `Trace`
phase (what runs between one cell's check and the next cell's submit, GPU wait excluded), the
`Check`→`Result` span, the prebuild's span, and the time cells ran while the prebuild was
still linking (`overlap`).

usage: costs.py REPORT [TRACE]
"""
import gzip, json, re, statistics, sys
from datetime import datetime


def load(path):
    op = gzip.open if path.endswith(".gz") else open
    with op(path, "rt") as f:
        return json.load(f)


def stats(name, xs, unit="ms"):
    if not xs:
        print(f"{name:<34} (none)")
        return
    xs = sorted(xs)
    p90 = xs[min(len(xs) - 1, int(0.9 * len(xs)))]
    print(f"{name:<34} n={len(xs):<5} sum={sum(xs):9.1f} {unit}  median={statistics.median(xs):7.3f}"
          f"  p90={p90:7.3f}  max={xs[-1]:8.3f}")


def report(path):
    r = load(path)
    t = r["timing"]
    check, readback, over, trace, stage = [], [], [], [], {}
    for c in r["cells"]:
        for a in c.get("attempts", []):
            res = a.get("result")
            if not res or res["outcome"] not in ("pass", "mismatch"):
                continue
            tm = res["timings"]
            check.append(tm["check_ms"])
            if "readback_ms" in tm:
                readback.append(tm["readback_ms"])
            trace.append(tm["trace_ms"])
            over.append(max(0.0, a["wall_ms"] - tm["total_ms"]))
            stage.setdefault(c["stage"], []).append(tm["check_ms"])
    print(f"report {path}: wall {t['wall_ms']:.0f} ms, prebuild {t.get('prebuild_ms', 0):.0f} ms "
          f"({t.get('prebuilt_pipelines', 0)} pipelines), cells timed {t['cells_timed']}, "
          f"outcomes {r['summary'].get('by_outcome', r['summary'])}")
    stats("check_ms per attempt", check)
    stats("  of which readback_ms", readback)
    stats("trace_ms per attempt", trace)
    stats("supervisor overhead per attempt", over)
    for s, xs in sorted(stage.items()):
        stats(f"  check_ms, stage {s}", xs)


STAMP = re.compile(r"(\d{4}-\d\d-\d\dT[\d:.]+)Z.*?worker (\d+): Msg\((\w+)(.*)")


def ts(s):
    return datetime.fromisoformat(s[:26]).timestamp() * 1e3


def timeline(path):
    text = re.sub(r"\x1b\[[0-9;]*m", "", open(path, errors="replace").read())
    last_result, prebuild, check_at = {}, {}, {}
    between, checks, overlap = [], [], 0.0
    building = {}
    for line in text.splitlines():
        m = STAMP.search(line)
        if not m:
            continue
        t, w, kind, rest = ts(m.group(1)), m.group(2), m.group(3), m.group(4)
        if kind == "Prebuild":
            prebuild.setdefault(w, []).append([t, None])
            building[w] = True
            last_result.pop(w, None)  # a prebuild between two cells is not per-cell overhead
        elif kind == "Prebuilt":
            if w in prebuild:
                prebuild[w][-1][1] = t
            building[w] = False
        elif kind == "Phase" and "phase: Trace" in rest and w in last_result:
            between.append(t - last_result.pop(w))
        elif kind == "Phase" and "phase: Check" in rest:
            check_at[w] = t
        elif kind == "Result":
            if w in check_at:
                checks.append(t - check_at.pop(w))
            if building.get(w) and w in last_result:
                overlap += t - last_result[w]
            last_result[w] = t
    print(f"trace {path}:")
    for w, spans in sorted(prebuild.items()):
        ms = [(b - a) if b else float("nan") for a, b in spans]
        print(f"  worker {w}: prebuilds " + ", ".join(f"{x:.1f}" for x in ms) + " ms")
    stats("  Result -> next Trace (between)", between)
    stats("  Check -> Result (check, seen)", checks)
    print(f"  cells' time while a prebuild was still running: {overlap:.1f} ms")


if __name__ == "__main__":
    report(sys.argv[1])
    if len(sys.argv) > 2:
        timeline(sys.argv[2])
