#!/bin/bash
# Interleaved before/after default warm runs on lavapipe 25 (issue 26's own time).
cd /tmp/stage-perf/r2
B=/tmp/rtprobe-stage-before; A=/tmp/stage-perf/rtprobe-after3
for t in before after; do c=/tmp/stage-perf/r2/cache-$t; bin=$B; [ $t = after ] && bin=$A
  RTPROBE_CACHE_DIR=$c $bin run -o warmup-$t.json > warmup-$t.txt 2>&1; done
echo "warmup done $(date -u +%T)" >> times.txt
for i in 1 2 3; do for t in before after; do c=/tmp/stage-perf/r2/cache-$t; bin=$B; [ $t = after ] && bin=$A
  l0=$(cut -d, -f3- /proc/loadavg | awk '{print $1}'); l0=$(awk '{print $1}' /proc/loadavg)
  /usr/bin/time -f "%e %U %S" -o $t-$i.time env RTPROBE_CACHE_DIR=$c $bin run -o $t-$i.json > $t-$i.txt 2>&1
  echo "$t-$i load $l0 -> $(awk '{print $1}' /proc/loadavg) time $(cat $t-$i.time) $(date -u +%T)" >> times.txt
done; done
# one worker, two chunks (the reaper's case), traced
for t in before after; do c=/tmp/stage-perf/r2/cache-$t; bin=$B; [ $t = after ] && bin=$A
  l0=$(awk '{print $1}' /proc/loadavg)
  /usr/bin/time -f "%e %U %S" -o j1-$t.time env RTPROBE_CACHE_DIR=$c RUST_LOG=trace $bin run --no-confirm --patches none --threads 2 -j 1 -o j1-$t.json > j1-$t.txt 2> j1-$t.log
  echo "j1-$t load $l0 -> $(awk '{print $1}' /proc/loadavg) time $(cat j1-$t.time) $(date -u +%T)" >> times.txt
done
echo alldone >> times.txt
