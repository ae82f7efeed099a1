#!/bin/bash
# Interleaved default runs of two builds on lavapipe 25, each with its own cache folder; run 0 of
# each fills its caches (before's were filled by its run 0 earlier).
cd /tmp/perf27
run() { # tag i
  local s=$(date +%s%N)
  RTPROBE_CACHE_DIR=/tmp/perf27/cache-$1 ./rtprobe-$1 run -o /tmp/perf27/$1-$2.json > $1-$2.txt 2>&1
  echo "$1 $2 rc=$? ms=$(( ($(date +%s%N)-s)/1000000 )) load=$(cut -d' ' -f1 /proc/loadavg)" >> times.txt
}
for i in $RUNS; do
  for t in $TAGS; do run $t $i; done
done
