#!/usr/bin/env python3
"""Whether two run reports judged every cell the same: per cell id its verdict and, per attempt
that ran to completion, the outcome and the comparison's judgement (pixels compared, ambiguous,
mismatched, probe pixels checked, mismatches by field, the undefined reads' own/other/neither
split, lane contradictions). Timings and worker numbers are left out. Exit 1 on a difference.

usage: same_outcomes.py BEFORE.json[.gz] AFTER.json[.gz]
"""
import gzip, json, sys


def load(path):
    op = gzip.open if path.endswith(".gz") else open
    with op(path, "rt") as f:
        return json.load(f)


def judged(c):
    attempts = []
    for a in c.get("attempts", []):
        res = a.get("result") or {}
        cmp = res.get("comparison") or {}
        reads = cmp.get("element_reads") or {}
        attempts.append((
            a["outcome"],
            tuple(cmp.get(k) for k in ("pixels", "compared", "ambiguous", "mismatched_pixels",
                                       "probe_checked", "lane_contradictions", "lane_evidence")),
            tuple(sorted((cmp.get("by_field") or {}).items())),
            tuple(reads.get(k) for k in ("own", "other", "neither", "uniform", "by_subgroup")),
        ))
    # attempts of one cell may come back in another order (workers race): compare as a multiset
    return (c["outcome"], tuple(sorted(attempts, key=repr)))


def main(a, b):
    ra, rb = load(a), load(b)
    ca = {c["id"]: judged(c) for c in ra["cells"]}
    cb = {c["id"]: judged(c) for c in rb["cells"]}
    diff = sorted(k for k in ca.keys() | cb.keys() if ca.get(k) != cb.get(k))
    for k in diff[:20]:
        print(f"{k}:\n  before {ca.get(k)}\n  after  {cb.get(k)}")
    print(f"{len(ca)} / {len(cb)} cells; {len(diff)} judged differently")
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
