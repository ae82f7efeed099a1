#!/usr/bin/env python3
"""rtprobe's own time and the driver's split from run reports, and the first prebuild's staging
spans from a supervisor trace (`RUST_LOG=trace rtprobe run ... 2> TRACE`).

usage: split.py REPORT.json[.gz]... [--trace TRACE.log]...
"""
import gzip, json, re, sys
from datetime import datetime


def load(path):
    op = gzip.open if path.endswith(".gz") else open
    with op(path, "rt") as f:
        return json.load(f)


def report(path):
    t = load(path)["timing"]
    g = lambda k: t.get(k, 0.0) / 1e3
    own = t.get("own_ms")
    print(f"{path}: wall {g('wall_ms'):.2f} s, own {own / 1e3 if own is not None else float('nan'):.2f} s"
          f" | device creation {g('device_create_ms'):.2f}, setup waits {g('setup_wait_ms'):.3f},"
          f" pipeline waits {g('pipeline_wait_ms'):.2f}, fence waits {g('trace_ms'):.2f}"
          f" | check {g('check_ms'):.2f} s over {t['cells_timed']} cells, {t['workers_started']} workers")


STAMP = re.compile(r"^(\S+Z) ")


def trace(path):
    """First prebuild: its message, the first and last `compiled k/n` step, the first overlapped
    cell's step."""
    marks = {}
    op = gzip.open if path.endswith(".gz") else open
    with op(path, "rt", errors="replace") as f:
        for line in f:
            line = re.sub(r"\x1b\[[0-9;]*m", "", line)
            m = STAMP.match(line)
            if not m:
                continue
            at = datetime.fromisoformat(m.group(1).replace("Z", "+00:00"))
            if "prebuilds" in line and "start" not in marks:
                marks["start"] = at
            elif "start" in marks and "compiled 1/" in line and "first" not in marks:
                marks["first"] = at
            elif "start" in marks and re.search(r'compiled (\d+)/\1"', line) and "staged" not in marks:
                marks["staged"] = at
                break
    s = marks.get("start")
    span = lambda k: (marks[k] - s).total_seconds() if k in marks and s else float("nan")
    print(f"{path}: prebuild → first cell staged {span('first'):.3f} s, → all staged {span('staged'):.3f} s")


args = sys.argv[1:]
i = 0
while i < len(args):
    if args[i] == "--trace":
        trace(args[i + 1])
        i += 2
    else:
        report(args[i])
        i += 1
