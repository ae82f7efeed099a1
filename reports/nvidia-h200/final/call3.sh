#!/bin/bash
# Third H200 call: the final integrated build (d5bdd3d): default run cold and warm, mutants, canaries last.
set -u
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
B=$PWD/.dev/h200/rtprobe
R=/tmp/r; mkdir -p $R/final
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc
mkdir -p /tmp/nv /tmp/rc
t() { local n=$1 to=$2; shift 2; local s=$(date +%s%N)
  timeout $to "$@" > $R/final/$n.txt 2>$R/final/$n.err; local c=$?
  echo "$n rc=$c process_ms=$(( ($(date +%s%N)-s)/1000000 ))" | tee -a $R/times.txt; }
t cold 60 $B run -o $R/final/cold.json
t warm1 60 $B run -o $R/final/warm1.json
t warm2 60 $B run -o $R/final/warm2.json
t mutants 240 $B run --mutants -o $R/final/mutants.json
tar czf $OUT/h200c.tgz -C /tmp r
t canaries 90 $B run --canaries --filter stage=raygen,resource=storage_buffer,index=literal -o $R/final/canaries.json
tar czf $OUT/h200c.tgz -C /tmp r
cp $R/times.txt $OUT/
