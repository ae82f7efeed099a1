#!/bin/bash
# Interleaved before/after warm runs on lavapipe 25 (a passing slice, no confirm round), each
# binary with its own cache folder; run 0 of each warms its caches.
set -u
cd /tmp/p26/ab
F="--filter stage=raygen --no-confirm --patches none"
run() { # tag bin i
  local s=$(date +%s%N)
  RTPROBE_CACHE_DIR=/tmp/p26/ab/cache-$1 $2 run $F -o /tmp/p26/ab/$1-$3.json > /tmp/p26/ab/$1-$3.txt 2>&1
  local c=$?
  local ms=$(( ($(date +%s%N)-s)/1000000 ))
  local x=$(python3 -c "import json;r=json.load(open('/tmp/p26/ab/$1-$3.json'));t=r['timing'];print('cells',t['cells_timed'],'compile_ms',round(t['compile_ms']),'report_wall_ms',round(t['wall_ms']))")
  echo "$1 run$3 rc=$c process_ms=$ms $x process-wall=$(python3 -c "import json;print(round($ms-json.load(open('/tmp/p26/ab/$1-$3.json'))['timing']['wall_ms']))") load=$(cut -d' ' -f1 /proc/loadavg)"
}
for i in $RUNS; do
  run before $BEFORE $i
  run after $AFTER $i
done
