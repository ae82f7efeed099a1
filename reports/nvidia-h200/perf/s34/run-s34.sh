#!/bin/bash
# Session 2026-12-04 (f): issue 26 after the checker thread (an overlapped cell's check off the
# cell thread). A/B against the previous main (old: aaa913e, new: 69b35ee), interleaved, each
# with its own rtprobe cache folder warmed first; then the new build's cold, warm, --patches all
# and traced runs as in s33d.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && for b in rtprobe-new rtprobe-old; do xz -d -k $b.xz && chmod +x $b; done; cd ../..
R=$PWD; N=$R/.dev/h200/rtprobe-new; D=$R/.dev/h200/rtprobe-old; O=$OUT/s34; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv; mkdir -p /tmp/nv /tmp/rc-new /tmp/rc-old /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 )) load=$(cut -d' ' -f1 /proc/loadavg)" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$N devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
rm -rf /tmp/nv/*
export RTPROBE_CACHE_DIR=/tmp/rc
t default-cold $N run -o default-cold.json
for i in 1 2 3; do t default-warm$i $N run -o default-warm$i.json; done
t patches-all-warm0 $N run --patches all -o patches-all-warm0.json
t patches-all-warm1 $N run --patches all -o patches-all-warm1.json
t default-warm4 $N run -o default-warm4.json
RUST_LOG=trace $N run -o default-warm-trace.json > default-warm-trace.txt 2> default-warm-trace.log; echo "trace rc=$?" >> times.txt
RTPROBE_CACHE_DIR=/tmp/rc-old $D run -o /tmp/w-old.json > /dev/null 2>&1
RTPROBE_CACHE_DIR=/tmp/rc-new $N run -o /tmp/w-new.json > /dev/null 2>&1
for i in 1 2 3 4; do
  RTPROBE_CACHE_DIR=/tmp/rc-old t ab-old-warm$i $D run -o ab-old-warm$i.json
  RTPROBE_CACHE_DIR=/tmp/rc-new t ab-new-warm$i $N run -o ab-new-warm$i.json
done
grep -H -E '^time:|^prebuild:|^outcomes:' *.txt > summary-times.txt
gzip -f *.json *.log; cd $OUT && tar czf s34.tgz s34 && rm -rf s34
