#!/bin/bash
# A/B: main's release binary vs t-overlap's, interleaved, warm, --threads 2, each with its own caches.
cd /tmp/ov/ab
cp /work/main/target/release/rtprobe ./rtprobe-main
run() { # name round
  local b=$1 k=$2
  RTPROBE_CACHE_DIR=/tmp/ov/ab/cache-$b \
    /usr/bin/time -f "$b $k process %e s" ./rtprobe-$b run --threads 2 -o /tmp/ov/ab/$b-$k.json > /tmp/ov/ab/$b-$k.txt 2>&1
  tail -1 /tmp/ov/ab/$b-$k.txt
  echo "$b $k load $(cut -d' ' -f1-3 /proc/loadavg)"
  grep -E "^time:|^prebuild:" /tmp/ov/ab/$b-$k.txt
}
# Both rtprobe caches warm already (main's from a first run, new's from two); Mesa's shader cache
# (~/.cache) shared and warm.
for k in 1 2 3; do run main $k; run new $k; done
