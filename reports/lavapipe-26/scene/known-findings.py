#!/usr/bin/env python3
"""Do the known findings stay findings? KNOWN is a report whose findings are known (here
`../run.json`, the default matrix of FINDINGS.md); each REPORT is checked for every planned cell
KNOWN has as a finding (mismatch, crash, timeout, device_lost, error) among the cells matching
FILTER (a substring of the id): still a finding, or not. Workaround variants (`.patch-` ids) are
retries, not planned cells, and are left out. Exit 1 when a known finding is not one.

    known-findings.py KNOWN.json descriptor_heap heap-scene.json heap-proc.json   (.json or .gz)
"""
import collections
import gzip
import json
import sys

BAD = ("mismatch", "crash", "timeout", "device_lost", "error")


def load(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return {c["id"]: c for c in json.load(f)["cells"]}


def main(known_path, needle, reports):
    known = load(known_path)
    kf = {k for k, c in known.items() if c["outcome"] in BAD and needle in k and ".patch-" not in k}
    by = collections.Counter(known[k]["outcome"] for k in kf)
    print(f"known findings in {known_path} ({needle}): {len(kf)} ({', '.join(f'{o} {n}' for o, n in sorted(by.items()))})")
    lost_any = False
    for path in reports:
        r = load(path)
        lost = sorted(k for k in kf if k not in r or r[k]["outcome"] not in BAD)
        found = {k for k, c in r.items() if c["outcome"] in BAD and ".patch-" not in k}
        changed = collections.Counter((known[k]["outcome"], r[k]["outcome"]) for k in kf - set(lost)
                                      if known[k]["outcome"] != r[k]["outcome"])
        print(f"{path}: {len(kf) - len(lost)} of {len(kf)} still findings; {len(found - kf)} new findings; "
              f"outcome changed among the kept: {dict(changed) or 'none'}")
        for k in lost:
            print(f"  no longer a finding: {k}: {r[k]['outcome'] if k in r else 'not in the report'}")
        for k in sorted(found - kf):
            print(f"  new finding: {k}: {r[k]['outcome']}")
        lost_any |= bool(lost)
    return 1 if lost_any else 0


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit("usage: known-findings.py KNOWN.json FILTER REPORT.json ...")
    sys.exit(main(sys.argv[1], sys.argv[2], sys.argv[3:]))
