#!/bin/bash
# A/B on one machine: old (8a956ee) and new builds, each with its own caches, interleaved.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
D=$PWD/.dev/h200; O=$OUT/ab; mkdir -p $O; cd $O
for b in old new; do mkdir -p /tmp/$b-nv /tmp/$b-rc; done
bin() { [ $1 = old ] && echo $D/rtprobe-old || echo $D/rtprobe; }
one() { b=$1; tag=$2; s=$(date +%s%N)
  __GL_SHADER_DISK_CACHE_PATH=/tmp/$b-nv RTPROBE_CACHE_DIR=/tmp/$b-rc $(bin $b) run -o ab-$b-$tag.json > ab-$b-$tag.txt 2>/dev/null
  e=$(date +%s%N); echo "$b $tag process_ms=$(( (e-s)/1000000 )) $(grep '^time:' ab-$b-$tag.txt | cut -c1-60)" | tee -a ab.txt; gzip -f ab-$b-$tag.json; }
one old cold; one new cold
for i in 1 2 3 4 5; do one old warm$i; one new warm$i; done
cd $OUT && tar czf ab.tgz ab && rm -rf ab
