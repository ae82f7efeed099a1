#!/bin/bash
# One H200 call for issues 21 (mutants), 22 (stress), 26 (perf) and the canaries, last.
set -u
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
B=$PWD/.dev/h200/rtprobe
R=/tmp/r; mkdir -p $R/perf $R/mutants $R/stress $R/canaries
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc
mkdir -p /tmp/nv /tmp/rc
t() { # dir name timeout cmd...
  local d=$1 n=$2 to=$3; shift 3
  local s=$(date +%s%N)
  timeout $to "$@" > $R/$d/$n.txt 2>$R/$d/$n.err
  local c=$?
  echo "$d/$n rc=$c process_ms=$(( ($(date +%s%N)-s)/1000000 ))" | tee -a $R/times.txt
}
echo "start $(date -u +%FT%TZ)" > $R/times.txt
$B --version >> $R/times.txt 2>&1
t perf caps 60 $B caps -o $R/perf/caps.json
t perf h200-cold 90 $B run -o $R/perf/h200-cold.json
t perf h200-warm1 90 $B run -o $R/perf/h200-warm1.json
t perf h200-warm2 90 $B run -o $R/perf/h200-warm2.json
t perf h200-warm3 90 $B run -o $R/perf/h200-warm3.json
t perf h200-patches-all-first 90 $B run --patches all -o $R/perf/h200-patches-all-first.json
t perf h200-patches-all-warm 90 $B run --patches all -o $R/perf/h200-patches-all-warm.json
t stress stress 120 $B stress --json $R/stress/stress.json --svg $R/stress/stress-far.svg
t mutants run 240 $B run --mutants -o $R/mutants/run.json
t stress stress-full 120 $B stress --full --json $R/stress/stress-full.json
tar czf $OUT/h200.tgz -C /tmp r
cp $R/times.txt $OUT/
# Canaries last: an invalid-address read can leave this driver hung for later processes.
t canaries run 90 $B run --canaries --filter stage=raygen,resource=storage_buffer,index=literal -o $R/canaries/run.json
tar czf $OUT/h200.tgz -C /tmp r
cp $R/times.txt $OUT/
