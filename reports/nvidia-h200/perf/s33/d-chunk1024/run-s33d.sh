#!/bin/bash
# Session 2026-12-04 (e), fourth call: as run-s33c.sh, with a worker's prebuild chunk 1024 cells
# instead of 512 (the default run is one chunk: no pipelines destroyed between chunks on the
# cell thread, the gap the reaper had removed before s33b's hang).
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && for b in rtprobe; do xz -d -k $b.xz && chmod +x $b; done; cd ../..
R=$PWD; B=$R/.dev/h200/rtprobe; O=$OUT/s33d; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 ))" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
rm -rf /tmp/nv/* /tmp/rc/*
t default-cold $B run -o default-cold.json
for i in 1 2 3; do t default-warm$i $B run -o default-warm$i.json; done
t patches-all-warm0 $B run --patches all -o patches-all-warm0.json
t patches-all-warm1 $B run --patches all -o patches-all-warm1.json
t default-warm4 $B run -o default-warm4.json
RUST_LOG=trace $B run -o default-warm-trace.json > default-warm-trace.txt 2> default-warm-trace.log; echo "trace rc=$?" >> times.txt
grep -H -E '^time:|^prebuild:' *.txt > summary-times.txt
gzip -f *.json *.log; cd $OUT && tar czf s33d.tgz s33d && rm -rf s33d
