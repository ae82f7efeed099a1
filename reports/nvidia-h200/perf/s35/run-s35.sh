#!/bin/bash
# Session 2026-12-04 (g): main's release build on a fresh H200 host: a cold default run, then
# warm default runs, one after another, looking for the worker SIGSEGV in the prebuild's staging
# seen once in ~70 warm runs (s34 d-final); a worker's fatal signal now comes with its native
# backtrace (native_crash), which lands in the report's worker_exit and in the run's stderr.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && xz -d -k rtprobe.xz && chmod +x rtprobe; cd ../..
B=$PWD/.dev/h200/rtprobe; O=$OUT/s35; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 )) load=$(cut -d' ' -f1 /proc/loadavg)" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
t default-cold $B run -o default-cold.json
end=$(( $(date +%s) + ${SECS:-150} ))
i=0
while [ "$(date +%s)" -lt "$end" ]; do
  i=$((i + 1)); t default-warm$i $B run -o default-warm$i.json
done
grep -l 'fatal signal\|killed by signal' *.txt > faults.txt 2>/dev/null
grep -H -E '^time:|^prebuild:|^outcomes:' *.txt > summary-times.txt
gzip -f *.json; cd $OUT && tar czf s35.tgz s35 && rm -rf s35
