#!/bin/bash
# Session 2026-12-04 (f), sixth call: main 13e5df2 (a worker's fatal signal with its native
# backtrace) on the NVIDIA driver: an injected real fault mid-cell, then two warm default runs.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && xz -d -k rtprobe.xz && chmod +x rtprobe; cd ../..
B=$PWD/.dev/h200/rtprobe; O=$OUT/s34f; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
F='stage=raygen|closest_hit,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing'
RTPROBE_WORKER_FAULT=trace:fault $B run -j 1 --no-confirm --patches none --filter "$F" -o fault.json > fault.txt 2>&1; echo "fault rc=$?" >> rc.txt
$B report fault.json > fault-issue.md 2>&1; echo "report rc=$?" >> rc.txt
for i in 0 1 2; do $B run -o warm$i.json > warm$i.txt 2>&1; echo "warm$i rc=$?" >> rc.txt; done
gzip -f *.json; cd $OUT && tar czf s34f.tgz s34f && rm -rf s34f
