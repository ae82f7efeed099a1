#!/bin/bash
# Session 2026-12-04 (e), second call: which change hangs `run --patches all` on the H200 (s33:
# "worker 1 timeout in prebuild ... between_cells" in both warm runs). new = main 5ecc5f2;
# vA = 2eadece (reaper + lazy AS probe, no analysis threads); vB = b6bb2b5 (lazy AS probe only).
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && for b in rtprobe rtprobe-vA rtprobe-vB; do xz -d -k $b.xz && chmod +x $b; done; cd ../..
R=$PWD; D=$R/.dev/h200; O=$OUT/s33b; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2> $n.err; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 ))" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
t new-warmup $D/rtprobe run --patches all -o new-warmup.json
RUST_LOG=rtprobe=debug t new-debug $D/rtprobe run --patches all -o new-debug.json
t vA $D/rtprobe-vA run --patches all -o vA.json
t vB $D/rtprobe-vB run --patches all -o vB.json
t new-j1 $D/rtprobe run --patches all -j 1 -o new-j1.json
t new-whole $D/rtprobe run --patches all --pipelines whole -o new-whole.json
t new-threads1 $D/rtprobe run --patches all --threads 1 -o new-threads1.json
grep -H -E '^time:|^prebuild:|timeout in|worker faults' *.txt > summary.txt
gzip -f *.json *.err; cd $OUT && tar czf s33b.tgz s33b && rm -rf s33b
