#!/bin/bash
# Session 2026-12-04 (f), second and third calls: where a warm default run's process wall goes outside the
# summary's clock (the CLI's start and end), from RUST_LOG=debug timestamps and `date` around it.
for f in .gl/*.deb; do dpkg -x $f / >/dev/null 2>&1; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
cd .dev/h200 && xz -d -k rtprobe-dbg.xz && chmod +x rtprobe-dbg; cd ../..
B=$PWD/.dev/h200/rtprobe-dbg; O=$OUT/s34${TAG:-b}; mkdir -p $O; cd $O
export __GL_SHADER_DISK_CACHE_PATH=/tmp/nv RTPROBE_CACHE_DIR=/tmp/rc; mkdir -p /tmp/nv /tmp/rc
$B run -o /tmp/w0.json > /dev/null 2>&1
for i in 1 2 3 4; do
  s=$(date +%s.%N); RUST_LOG=debug $B run -o w$i.json > w$i.txt 2> w$i.log; e=$(date +%s.%N)
  echo "w$i start=$s end=$e" >> times.txt
done
s=$(date +%s.%N); $B devices > devices.txt 2>&1; e=$(date +%s.%N); echo "devices start=$s end=$e" >> times.txt
s=$(date +%s.%N); $B --version > version.txt 2>&1; e=$(date +%s.%N); echo "version start=$s end=$e" >> times.txt
gzip -f *.json; cd $OUT && tar czf s34${TAG:-b}.tgz s34${TAG:-b} && rm -rf s34${TAG:-b}
