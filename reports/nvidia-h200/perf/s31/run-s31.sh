#!/bin/bash
# One call (issue 26, the cells overlapping the prebuild's pipeline creation, t-overlap): the
# default run cold, three warm, `--patches all` warm twice, and a fourth warm run traced
# (RUST_LOG=trace). Defaults as in s30 (the H200's 16 threads: `--threads` left to its default).
# Each summary's `time:` line now carries rtprobe's own time ("own", docs/performance.md).
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
R=$PWD; B=$PWD/.dev/h200/rtprobe; O=$OUT/s31; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 ))" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
rm -rf /tmp/nv/* /tmp/rc/*
t default-cold $B run -o default-cold.json
for i in 1 2 3; do t default-warm$i $B run -o default-warm$i.json; done
t patches-all-warm0 $B run --patches all -o patches-all-warm0.json
t patches-all-warm1 $B run --patches all -o patches-all-warm1.json
RUST_LOG=trace $B run -o default-warm-trace.json > default-warm-trace.txt 2> default-warm-trace.log; echo "trace rc=$?" >> times.txt
# The figures the issue asks for, from each summary: wall, own, the driver's parts, overlap.
grep -H -E '^time:|^prebuild:' *.txt > summary-times.txt
gzip -f *.json *.log; cd $OUT && tar czf s31.tgz s31 && rm -rf s31
