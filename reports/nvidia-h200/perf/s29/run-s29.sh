#!/bin/bash
# One call: run --scene timings (test scene, 1M scene), run --shader on a scene, default run cold/warm.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
B=$PWD/.dev/h200/rtprobe; U=$PWD/tests/shaders/user; O=$OUT/s29; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
t() { local n=$1; shift; local s=$(date +%s%N); "$@" > $n.txt 2>&1; local rc=$?; local e=$(date +%s%N); echo "$n rc=$rc process_ms=$(( (e-s)/1000000 ))" | tee -a times.txt; echo "\$ $*" >> $n.cmd; }
$B devices > devices.txt 2>&1
t make-test $B scene make sc
t make-1m $B scene make big --triangles 1000000 --glb
F='stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer'
t run-proc $B run --filter "$F" -o run-proc.json
t run-test $B run --scene sc/scene.gltf --filter "$F" -o run-test.json
t run-1m $B run --scene big/scene.glb --filter "$F" -o run-1m.json
t run-default-scene $B run --scene sc/scene.gltf -o run-default-scene.json
t shader-tut $B run --shader $U/tutorial.rchit -I $U --scene sc/scene.gltf --fill push.16=scene.scene_desc --fill 1.2=scene.textures -D TEXTURED --repeat 2 -o shader-tut.json
t shader-tut-1m $B run --shader $U/tutorial.rchit -I $U --scene big/scene.glb --fill push.16=scene.scene_desc --repeat 1 -o shader-tut-1m.json
t shader-shadow $B run --shader $U/shadow_types.rchit --shader $U/miss.rmiss --shader $U/shadow.rmiss -I $U --repeat 2 -o shader-shadow.json
rm -rf /tmp/nv/* /tmp/rc/*
t default-cold $B run -o default-cold.json
for i in 1 2 3; do t default-warm$i $B run -o default-warm$i.json; done
t patches-all-warm0 $B run --patches all -o patches-all-warm0.json
t patches-all-warm1 $B run --patches all -o patches-all-warm1.json
rm -rf sc big; gzip -f *.json; cd $OUT && tar czf s29.tgz s29 && rm -rf s29
