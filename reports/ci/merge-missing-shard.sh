#!/usr/bin/env bash
# Issue 22's CI transcript (merge-missing-shard.txt next to this script): a sharded run held to a
# baseline, one shard missing, refused at the merge. Prints each command (as `$ …`), what it
# printed and its exit status. Run from anywhere: reports/ci/merge-missing-shard.sh > reports/ci/merge-missing-shard.txt
set -u
bin=${RTPROBE:-$(cd "$(dirname "$0")/../.." && pwd)/target/release/rtprobe}
dir=$(mktemp -d /tmp/rtprobe-ci-XXXX)
cd "$dir"
F='stage=raygen|miss,resource=storage_buffer|uniform_buffer,descriptor_model=descriptor_indexing'
K='stage=miss,index=literal@value'
run() {
  printf '$ rtprobe'; printf ' %q' "$@"; echo
  "$bin" "$@" 2>&1 | grep -E "^(plan|outcomes|baseline|  [A-Z]|shard|merged|rtprobe: error|report)" | sed "s#$dir/##g"
  echo "(exit ${PIPESTATUS[0]})"
  echo
}
echo "# lavapipe $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null), rtprobe $(git -C "$(dirname "$bin")/../.." rev-parse --short HEAD)"
echo "# the known fault: $K (2 cells); the matrix: $F (22 cells)"
echo
run run --patches none --filter "$F" --inject-fault "$K" -o first.json
run baseline first.json -o baseline.json
for i in 1 2 3; do
  run run --patches none --filter "$F" --inject-fault "$K" --shard "$i/3" --baseline baseline.json -o "shard-$i.json"
done
echo "# shard 3's job never reported (its artifact is missing): merge what came"
run merge shard-1.json shard-2.json -o rtprobe.json
echo "\$ ls rtprobe.json"
ls rtprobe.json 2>&1
echo
run run --patches none --filter "$F" --inject-fault "$K" --shard 2/2 --baseline baseline.json -o other-2-of-2.json
echo "# shards of another split: refused too"
run merge shard-1.json other-2-of-2.json shard-3.json -o rtprobe.json
echo "# every shard: merged"
run merge shard-1.json shard-2.json shard-3.json -o rtprobe.json
rm -rf "$dir"
