#!/bin/bash
# Session 2026-12-04 (f), fifth call: s34d's first warm run lost its worker to a SIGSEGV in the
# prebuild's staging (compiled 28/536, before any cell ran). Is it new? 15 warm default runs of
# main 0112824 (new) and of aaa913e (old, before the checker thread), interleaved, each build
# with its own rtprobe cache folder; every worker fault counted.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && for b in rtprobe rtprobe-old; do xz -d -k $b.xz && chmod +x $b; done; cd ../..
N=$PWD/.dev/h200/rtprobe; D=$PWD/.dev/h200/rtprobe-old; O=$OUT/s34e; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv; mkdir -p /tmp/nv /tmp/rc-new /tmp/rc-old
RTPROBE_CACHE_DIR=/tmp/rc-old $D run -o /tmp/x.json > first-old.txt 2>&1
RTPROBE_CACHE_DIR=/tmp/rc-new $N run -o /tmp/x.json > first-new.txt 2>&1
for i in $(seq 1 15); do
  RTPROBE_CACHE_DIR=/tmp/rc-old $D run -o old$i.json > old$i.txt 2>&1; echo "old$i rc=$?" >> rc.txt
  RTPROBE_CACHE_DIR=/tmp/rc-new $N run -o new$i.json > new$i.txt 2>&1; echo "new$i rc=$?" >> rc.txt
done
grep -H -E "worker .* (crash|timeout|device_lost)|^time:" *.txt > faults.txt
gzip -f *.json; cd $OUT && tar czf s34e.tgz s34e && rm -rf s34e
