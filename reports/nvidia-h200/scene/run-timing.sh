#!/bin/bash
# Issue 28's cost table on the H200: load + fit, AS build, CPU reference, worker device setup and
# peak memory of `run --scene` for the test scene and the ≥ 1 M-triangle scene, one worker
# (`-j 1`) on the 28-cell CI filter, under `/usr/bin/time -v` where the machine has it.
# Run from the repository root through the device tool:
#   bash reports/nvidia-h200/scene/run-timing.sh
# Writes ONE file, $OUT/scene-timing.tgz (the reports gzipped, each command's output, `time -v`,
# the table from reports/lavapipe/scene/timing.py, `uptime` beside each run).
# Environment lines copied from reports/nvidia-h200/perf/s29/run-s29.sh.
set -u
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
B=$PWD/.dev/h200/rtprobe; T=$PWD/reports/lavapipe/scene/timing.py
O=$OUT/scene-timing; mkdir -p $O; cd $O
TV=""; [ -x /usr/bin/time ] && TV="/usr/bin/time -v"
F='stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer'
$B devices > devices.txt 2>&1
$B scene make sc > make.txt 2>&1
$B scene make big --triangles 1000000 --glb >> make.txt 2>&1
r() { # NAME ARGS...: one run, its output, `time -v` into NAME.time, the load beside it
  local n=$1; shift
  uptime > $n.uptime
  echo "\$ rtprobe $*" > $n.cmd
  if [ -n "$TV" ]; then $TV -o $n.time $B "$@" > $n.txt 2>&1; else $B "$@" > $n.txt 2>&1; fi
  echo "$n rc=$?" >> rc.txt
}
r time-proc run -j 1 --filter "$F" -o time-proc.json
r time-test run -j 1 --scene sc/scene.gltf --filter "$F" -o time-test.json
r time-1m run -j 1 --scene big/scene.glb --filter "$F" -o time-1m.json
python3 $T procedural=time-proc.json test=time-test.json 1m=time-1m.json > table.md 2>&1
rm -rf sc big; gzip -f *.json; cd $OUT && tar czf scene-timing.tgz scene-timing && rm -rf scene-timing
