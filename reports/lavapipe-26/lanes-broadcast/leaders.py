#!/usr/bin/env python3
"""Count, in records.bin (80-byte probe::Record, little endian), the probe pixels with lane
evidence by whether lane 0 of their 8-lane subgroup was in the closest-hit call (bit 0 of the
ballot), and how many name lane 0's pixel (pixel - lane) as their subgroupBroadcastFirst leader."""
import struct, sys, os
f = os.path.join(os.path.dirname(__file__), "records.bin")
d = open(f, "rb").read()
recs = [struct.unpack("<IIIIIfffIIIIffffIIII", d[i * 80:(i + 1) * 80]) for i in range(len(d) // 80)]
lanes = [(p, r) for p, r in enumerate(recs) if r[0] & 4]  # FLAG_LANES
for name, keep in (("lane 0 inactive", lambda r: not r[18] & 1), ("lane 0 active", lambda r: r[18] & 1)):
    group = [(p, r) for p, r in lanes if keep(r)]
    lane0 = sum(r[17] == p - r[16] for p, r in group)
    lowest = sum(r[17] == p - r[16] + (r[18] & -r[18]).bit_length() - 1 for p, r in group)
    print(f"{name}: {len(group)} pixels; leader = lane 0's pixel {lane0}, = lowest active lane's {lowest}")
