#!/usr/bin/env python3
"""Print the tables of a `run --mutants` report (mutants.json.gz or run.json) as the README's
Markdown: per-mutant counts, survivors grouped by mutant and reason, not-run pairs by reason."""
import collections, gzip, json, sys

def load(path):
    return json.load(gzip.open(path) if path.endswith(".gz") else open(path))

if len(sys.argv) > 2:
    # Several shards: the per-mutant counts summed, and each shard's wall time.
    cols = ["applicable", "killed", "survived", "allowed", "probe_defects", "faults", "equivalent", "no_target", "not_run"]
    per, order = collections.defaultdict(collections.Counter), []
    for path in sys.argv[1:]:
        r = load(path)
        t = r.get("timing", {})
        print(f"- `{path}`: started {r['started']}, finished {r['finished']}, complete {r['complete']}, cells {len(r['cells'])}, mutants round {r['mutants']['wall_ms'] / 1000:.1f} s")
        for name in r["mutants"]["mutants"]:
            if name not in order:
                order.append(name)
            for k in cols:
                per[name][k] += r["mutants"]["counts"][name][k]
    print("\n| mutant | applicable | killed | survived (allowed / probe defects) | faults | equivalent | no target | not run |")
    print("|---|---|---|---|---|---|---|---|")
    tot = collections.Counter()
    for name in order:
        c = per[name]
        tot.update(c)
        print(f"| `{name}` | {c['applicable']} | {c['killed']} | {c['survived']} ({c['allowed']} / {c['probe_defects']}) | {c['faults']} | {c['equivalent']} | {c['no_target']} | {c['not_run']} |")
    c = tot
    print(f"| **all** | {c['applicable']} | {c['killed']} | {c['survived']} ({c['allowed']} / {c['probe_defects']}) | {c['faults']} | {c['equivalent']} | {c['no_target']} | {c['not_run']} |")
    print(f"\nHad to be caught: {c['applicable'] - c['allowed']}, killed {c['killed']}, probe defects {c['probe_defects']}, faults {c['faults']}.")
    sys.exit(0)

path = sys.argv[1]
r = load(path)
m = r["mutants"]
cols = ["applicable", "killed", "survived", "faults", "equivalent", "no_target", "not_run"]
print("| mutant | applicable | killed | survived (allowed / probe defects) | faults | equivalent | no target | not run |")
print("|---|---|---|---|---|---|---|---|")
tot = collections.Counter()
for name in m["mutants"]:
    c = m["counts"][name]
    for k in cols + ["allowed", "probe_defects"]:
        tot[k] += c[k]
    print(f"| `{name}` | {c['applicable']} | {c['killed']} | {c['survived']} ({c['allowed']} / {c['probe_defects']}) | {c['faults']} | {c['equivalent']} | {c['no_target']} | {c['not_run']} |")
print(f"| **all** | {tot['applicable']} | {tot['killed']} | {tot['survived']} ({tot['allowed']} / {tot['probe_defects']}) | {tot['faults']} | {tot['equivalent']} | {tot['no_target']} | {tot['not_run']} |")
must = tot["applicable"] - tot["allowed"]
print(f"\nApplicable mutants that had to be caught (every applicable pair but the survivors the spec allows): {must}, killed {tot['killed']}, probe defects {tot['probe_defects']}, faults {tot['faults']}.")
print("\n## Survivors, with why\n")
groups = collections.OrderedDict()
for e in sorted((e for e in m["entries"] if e["status"] == "survived"), key=lambda e: (e["mutant"], e.get("probe_defect", False) is False)):
    key = (e["mutant"], "PROBE DEFECT" if e.get("probe_defect") else "allowed: " + (e.get("allowed_by") or "?"))
    groups.setdefault(key, []).append(e)
for (mut, why), es in groups.items():
    print(f"- `{mut}` × {len(es)} cells — {why}; e.g. `{es[0]['cell']}`")
first = next((e for e in m["entries"] if e["status"] == "survived"), None)
if first:
    print(f"\nEach entry's full reason is in the report (`why`), e.g.: \"{first['why']}\"")
print("\n## Not run\n")
nr = collections.Counter((e["mutant"], e["why"]) for e in m["entries"] if e["status"] == "not_run")
for (mut, why), n in sorted(nr.items()):
    print(f"- `{mut}` × {n}: {why}")
