#!/usr/bin/env python3
"""Compare the kill matrices (`mutants.entries`) of two `rtprobe run --mutants` reports: PROC
(procedural scene) and SCENE (`--scene`).

Prints each report's counts by status, then every (cell, mutant) pair whose status differs,
each with whether SCENE's `scene.limits` names its cell undiscriminating and why. The claim
checked: every pair killed on PROC is killed on SCENE, unless the scene makes its cell
undiscriminating. Exit 1 when a pair killed on PROC is not killed on SCENE and its cell is not
in `scene.limits`.

    compare-mutants.py mutants-proc.json mutants-scene.json      (.json or .json.gz)
"""
import collections
import gzip
import json
import sys


def load(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return json.load(f)


def pairs(report):
    return {(e["cell"], e["mutant"]): e for e in report["mutants"]["entries"]}


def limits(report):
    out = {}
    for lim in report["scene"].get("limits") or []:
        short = lim["why"].split(":")[0][:60].strip()
        for cid in lim["cells"]:
            out.setdefault(cid, []).append(short)
    return out


def counts(name, p):
    c = collections.Counter(e["status"] for e in p.values())
    print(f"{name}: {len(p)} pairs: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))


def main(proc_path, scene_path):
    proc, scene = load(proc_path), load(scene_path)
    p, s, lim = pairs(proc), pairs(scene), limits(scene)
    counts("procedural", p)
    counts("scene", s)
    differ = [k for k in sorted(set(p) | set(s))
              if (p.get(k) or {}).get("status") != (s.get(k) or {}).get("status")]
    killed_p = [k for k in p if p[k]["status"] == "killed"]
    lost = [k for k in killed_p if (s.get(k) or {}).get("status") != "killed"]
    unexplained = [k for k in lost if k[0] not in lim]
    print(f"killed on procedural: {len(killed_p)}; of them killed on the scene: {len(killed_p) - len(lost)}; "
          f"not killed there: {len(lost)} ({len(lost) - len(unexplained)} in undiscriminating cells, "
          f"{len(unexplained)} unexplained)")
    by = collections.Counter()
    for k in differ:
        a, b = (p.get(k) or {}).get("status", "-"), (s.get(k) or {}).get("status", "-")
        by[(k[1], a, b, "; ".join(lim.get(k[0], [])) or "discriminating")] += 1
    print(f"pairs whose status differs: {len(differ)}")
    for (mutant, a, b, why), n in sorted(by.items()):
        print(f"  {n:4} × {mutant}: procedural {a}, scene {b} — cell on the scene: {why}")
    cells = sorted({k[0] for k in differ if k[0] in lim})
    print(f"their cells in scene.limits: {len(cells)}, by stage: "
          + ", ".join(f"{st} {n}" for st, n in sorted(collections.Counter(c.split('.')[0] for c in cells).items())))
    for k in differ:
        if k[0] in lim:
            continue
        a, b = p.get(k), s.get(k)
        print(f"    {k[0]} {k[1]}: procedural {a and a['status']} ({a and a['why'][:90]}); "
              f"scene {b and b['status']} ({b and b['why'][:90]})")
    return 1 if unexplained else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: compare-mutants.py PROC.json[.gz] SCENE.json[.gz]")
    sys.exit(main(sys.argv[1], sys.argv[2]))
