#!/bin/bash
# One call (session 2026-12-03 b): default run cold/warm and --patches all (issue 26, the check's
# readback from cached memory), a traced warm run, the scene_layout cells, then issue 28's scene timing.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
R=$PWD; B=$PWD/.dev/h200/rtprobe; O=$OUT/s30; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 ))" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
rm -rf /tmp/nv/* /tmp/rc/*
t default-cold $B run -o default-cold.json
for i in 1 2 3; do t default-warm$i $B run -o default-warm$i.json; done
t patches-all-warm0 $B run --patches all -o patches-all-warm0.json
t patches-all-warm1 $B run --patches all -o patches-all-warm1.json
RUST_LOG=trace $B run -o default-warm-trace.json > default-warm-trace.txt 2> default-warm-trace.log; echo "trace rc=$?" >> times.txt
$B scene make sc > make.txt 2>&1
t layout-proc $B run --filter 'scene_layout=shared_buffers|per_mesh' -o layout-proc.json
t layout-scene $B run --scene sc/scene.gltf --filter 'scene_layout=shared_buffers|per_mesh' -o layout-scene.json
rm -rf sc; gzip -f *.json *.log; cd $OUT && tar czf s30.tgz s30 && rm -rf s30
cd $R && bash reports/nvidia-h200/scene/run-timing.sh
