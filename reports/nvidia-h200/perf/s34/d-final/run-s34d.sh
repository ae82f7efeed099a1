#!/bin/bash
# Session 2026-12-04 (f), fourth call: main 0112824 (the checker thread with runner::held, the
# CLI's instance destroyed in the background): issue 26's default runs as in s34, and two
# RUST_LOG=debug runs with `date` around them for the CLI's start and end.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && xz -d -k rtprobe.xz && chmod +x rtprobe; cd ../..
B=$PWD/.dev/h200/rtprobe; O=$OUT/s34d; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 )) load=$(cut -d' ' -f1 /proc/loadavg)" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
rm -rf /tmp/nv/* /tmp/rc/*
t default-cold $B run -o default-cold.json
for i in 1 2 3 4 5; do t default-warm$i $B run -o default-warm$i.json; done
t patches-all-warm0 $B run --patches all -o patches-all-warm0.json
t patches-all-warm1 $B run --patches all -o patches-all-warm1.json
for i in 1 2; do
  s=$(date +%s.%N); RUST_LOG=debug $B run -o w$i.json > w$i.txt 2> w$i.log; e=$(date +%s.%N)
  echo "w$i start=$s end=$e" >> stamps.txt
done
grep -H -E '^time:|^prebuild:|^outcomes:' *.txt > summary-times.txt
gzip -f *.json *.log; cd $OUT && tar czf s34d.tgz s34d && rm -rf s34d
