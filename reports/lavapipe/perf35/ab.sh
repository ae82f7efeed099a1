#!/bin/bash
# Interleaved A/B of the warm default run on lavapipe 25: old = verify repeats compiled afresh,
# new = verify repeats with the driver's cache. Both share the warm caches (~/.cache).
set -u
for b in old new; do /tmp/ab/$b run -o /tmp/ab/out/warmup-$b.json > /dev/null 2>&1; done
for i in 1 2 3; do
  for b in old new; do
    l0=$(cut -d' ' -f1 /proc/loadavg)
    /usr/bin/time -f "%e %U %S" -o /tmp/ab/out/$b-$i.time /tmp/ab/$b run -o /tmp/ab/out/$b-$i.json > /tmp/ab/out/$b-$i.txt 2> /tmp/ab/out/$b-$i.err
    echo "$b-$i load $l0 -> $(cut -d' ' -f1 /proc/loadavg) time $(cat /tmp/ab/out/$b-$i.time)"
  done
done
