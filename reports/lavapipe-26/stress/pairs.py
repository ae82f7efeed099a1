#!/usr/bin/env python3
"""The two-triangle reproduction of each leak of a `stress` JSON (schema rtprobe.stress/3), from
the JSON alone: the ray, the triangle holding its crossing (role `expected`), and the neighbour
across that triangle's nearest edge (the listed triangle sharing that edge's two vertices, bit for
bit), with the crossing's exact signed distance to every edge of both (Python `fractions` on the
f32 bits; the rays are +z, so ray space is the xy plane). Usage: pairs.py FILE.json"""
import json, struct, sys
from fractions import Fraction as F

def f32(h):
    return F(struct.unpack(">f", bytes.fromhex(h))[0])

def xyz(bits):
    return [f32(h) for h in bits.split()[:3]]

def edge_dist(o, a, b):
    """Signed distance in the xy plane from o to the line a→b (positive: left of it)."""
    cross = (b[0] - a[0]) * (o[1] - a[1]) - (b[1] - a[1]) * (o[0] - a[0])
    return float(cross) / (float(b[0] - a[0]) ** 2 + float(b[1] - a[1]) ** 2) ** 0.5

def edges(o, tri):
    v = [xyz(b) for b in tri["vertex_bits"]]
    # Edge opposite vertex k: v[k+1] → v[k+2]; the sign tells the side, the winding the inside.
    d = [edge_dist(o, v[(k + 1) % 3], v[(k + 2) % 3]) for k in range(3)]
    area2 = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0])
    s = 1 if area2 > 0 else -1
    return [s * x for x in d], float(area2)

r = json.load(open(sys.argv[1]))
for case in r["cases"]:
    for e in case.get("examples", []):
        if e["kind"] != "leak":
            continue
        o = xyz(e["bits"][0])
        print(f"{case['name']} {e['part']} ray {e['ray']}: origin {e['bits'][0]}, direction {e['bits'][1]}")
        print(f"  driver: {'miss' if e.get('hit') is None else e['hit']}, {e['candidates']} any-hit candidates")
        exp = next(t for t in e["triangles"] if t["role"] == "expected")
        dexp, a_exp = edges(o, exp)
        k = min(range(3), key=lambda i: abs(dexp[i]))
        shared = {exp["vertex_bits"][(k + 1) % 3], exp["vertex_bits"][(k + 2) % 3]}
        near = [t for t in e["triangles"] if t is not exp and shared <= set(t["vertex_bits"])]
        for role, t in [("holds the crossing", exp)] + [("across its nearest edge", t) for t in near]:
            d, a = edges(o, t)
            print(f"  triangle {t['primitive']} ({role}): " + "  ".join(t["vertex_bits"]))
            print(f"    signed distance to the edges opposite v0, v1, v2 (inside > 0): " + ", ".join(f"{x:.3e}" for x in d) + f"; twice its area {abs(a):.3e}")
        if not near:
            print("  (the neighbour across the nearest edge is not in the JSON)")
