#!/bin/bash
# Second H200 call: the cost of lane evidence on a warm run, then stress --full alone.
set -u
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
B=$PWD/.dev/h200/rtprobe
R=/tmp/r; mkdir -p $R/perf $R/stress
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc
mkdir -p /tmp/nv /tmp/rc
t() { local d=$1 n=$2 to=$3; shift 3; local s=$(date +%s%N)
  timeout $to "$@" > $R/$d/$n.txt 2>$R/$d/$n.err; local c=$?
  echo "$d/$n rc=$c process_ms=$(( ($(date +%s%N)-s)/1000000 ))" | tee -a $R/times.txt; }
t perf h200-b-cold 60 $B run -o $R/perf/h200-b-cold.json
t perf h200-b-warm1 60 $B run -o $R/perf/h200-b-warm1.json
t perf h200-b-warm2 60 $B run -o $R/perf/h200-b-warm2.json
t perf h200-noevidence-first 60 $B run --lane-evidence off -o $R/perf/h200-noevidence-first.json
t perf h200-noevidence-warm1 60 $B run --lane-evidence off -o $R/perf/h200-noevidence-warm1.json
t perf h200-noevidence-warm2 60 $B run --lane-evidence off -o $R/perf/h200-noevidence-warm2.json
tar czf $OUT/h200b.tgz -C /tmp r
t stress stress-full 480 $B stress --full --json $R/stress/stress-full.json
tar czf $OUT/h200b.tgz -C /tmp r
cp $R/times.txt $OUT/
