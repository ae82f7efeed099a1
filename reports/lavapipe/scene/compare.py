#!/usr/bin/env python3
"""Compare two rtprobe run reports cell by cell: PROC (procedural scene) and SCENE (`--scene`).

Prints, per outcome, how many cells agree; every cell whose outcome differs; the findings of
each side with their differing-pixel counts; and the cells SCENE's `scene.limits` names
undiscriminating, with their outcomes on both sides. Exit 1 when an outcome differs.

    compare.py run-default-proc.json run-default-scene.json      (.json or .json.gz)
"""
import collections
import gzip
import json
import sys


def load(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return json.load(f)


def cells(report):
    return {c["id"]: c for c in report["cells"]}


def detail(c):
    return (c.get("reason") or "")[:110]


def main(proc_path, scene_path):
    proc, scene = load(proc_path), load(scene_path)
    p, s = cells(proc), cells(scene)
    print(f"procedural: {proc_path}  scene: {scene_path} ({scene['scene']['params']['file']['path']})")
    only = sorted(set(p) ^ set(s))
    print(f"cells: {len(p)} procedural, {len(s)} scene, {len(only)} in one report only")
    for cid in only:
        print(f"  only in {'procedural' if cid in p else 'scene'}: {cid}")
    same = collections.Counter()
    differ = []
    for cid in sorted(set(p) & set(s)):
        a, b = p[cid]["outcome"], s[cid]["outcome"]
        if a == b:
            same[a] += 1
        else:
            differ.append((cid, a, b))
    print("same outcome: " + ", ".join(f"{k} {v}" for k, v in sorted(same.items())))
    print(f"different outcome: {len(differ)}")
    for cid, a, b in differ:
        print(f"  {cid}: procedural {a}, scene {b}")
    for name, rep in (("procedural", p), ("scene", s)):
        bad = [c for c in rep.values() if c["outcome"] not in ("pass", "unsupported", "not_implemented")]
        print(f"{name}: {len(bad)} cells neither pass nor unsupported")
        for c in sorted(bad, key=lambda c: c["id"]):
            print(f"  {c['outcome']:9} {c['id']}: {detail(c)}")
    limited = {}
    for lim in scene["scene"].get("limits") or []:
        for cid in lim["cells"]:
            limited.setdefault(cid, []).append(lim["why"].split(":")[0][:60].strip())
    by_outcome = collections.Counter((p[c]["outcome"], s[c]["outcome"]) for c in limited if c in p)
    print(f"undiscriminating on the scene (scene.limits): {len(limited)} cells; outcomes procedural/scene: "
          + ", ".join(f"{a}/{b} {n}" for (a, b), n in sorted(by_outcome.items())))
    for lim in scene["scene"].get("limits") or []:
        print(f"  {len(lim['cells'])} cells, {lim['share'] * 100:.0f}% of pixels: {lim['why']}")
    return 1 if differ or only else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: compare.py PROC.json[.gz] SCENE.json[.gz]")
    sys.exit(main(sys.argv[1], sys.argv[2]))
