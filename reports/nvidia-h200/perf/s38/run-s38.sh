#!/bin/bash
# Session 2026-12-05 (s38): main's release build at 05024e6 on the H200: a cold default run,
# WARM warm default runs, two warm `--patches all`, two injected-mismatch runs (value fault on
# the miss shaders' dynamic reads: no device fault), then `run --shader`'s index check on a
# device with subgroup vote in its RT stages (the vote path, never run on hardware before).
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
R=$PWD; cd .dev/h200 && xz -d -k rtprobe.xz && chmod +x rtprobe; cd $R
B=$R/.dev/h200/rtprobe; U=$R/tests/shaders/user; O=$OUT/s38; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 )) load=$(cut -d' ' -f1 /proc/loadavg)" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1; nproc > nproc.txt; uptime > uptime.txt
t default-cold $B run -o default-cold.json
for i in $(seq 1 ${WARM:-8}); do t default-warm$i $B run -o default-warm$i.json; done
t patches-all-warm0 $B run --patches all -o patches-all-warm0.json
t patches-all-warm1 $B run --patches all -o patches-all-warm1.json
F="stage=miss,resource=storage_buffer|uniform_buffer,descriptor_model=descriptor_indexing"
t injected1 $B run --filter "$F" --inject-fault 'stage=miss,index=dynamic@value:0.1' -o injected1.json
t injected2 $B run --filter "$F" --inject-fault 'stage=miss,index=dynamic@value:0.1' -o injected2.json
t shader-sizeup $B run --shader $U/raygen.rgen --shader $U/miss.rmiss --shader $U/object_table.rchit --repeat 2 -o shader-sizeup.json
t shader-vote $B run --shader $U/object_table.rchit -D NO_NONUNIFORM --repeat 2 -o shader-vote.json
t shader-light $B run --shader $U/light_table.rchit --repeat 2 -o shader-light.json
t shader-alpha $B run --shader $U/object_table.rchit --shader $U/alpha_table.rahit --repeat 2 -o shader-alpha.json
ls -la /tmp | grep rtprobe > tmp-left.txt
grep -l 'fatal signal\|killed by signal' *.txt > faults.txt 2>/dev/null
grep -H -E '^time:|^prebuild:|^outcomes:|round ' *.txt > summary-times.txt
gzip -f *.json; cd $OUT && tar czf s38.tgz s38 && rm -rf s38
