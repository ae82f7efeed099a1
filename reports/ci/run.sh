#!/usr/bin/env bash
# The CI log of reports/ci/transcript.txt, made the way a CI job runs rtprobe: CI=true, no
# terminal (stdout and stderr into one file), the matrix in two shards held to a baseline, then
# merged into one report whose verdict is the job's. The baseline expects the fault planted in
# closest-hit shaders' dynamic storage-buffer reads (made once from an unsharded run of the same
# plan: `rtprobe run … -o first.json; rtprobe baseline first.json -o reports/ci/baseline.json`).
#
#   bash reports/ci/run.sh > reports/ci/transcript.txt 2>&1
set -uo pipefail
cd "$(dirname "$0")/../.."
export PATH="$PWD/target/release:$PATH" CI=true RTPROBE_PROGRESS_SECS=5
out=reports/ci
filter='stage=closest_hit|raygen,resource=storage_buffer,descriptor_model=descriptor_indexing'
fault='stage=closest_hit,index=dynamic'
step() {
  printf '$'; printf " %q" "$@"; printf '\n'
  "$@"
  echo "(exit $?)"
  echo
}
echo "# $out/baseline.json: the expectations, made once from an unsharded run of the same plan"
if [ ! -f "$out/baseline.json" ]; then
  rtprobe run --filter "$filter" --inject-fault "$fault" -o "$out/first.json" >/dev/null 2>&1
  rtprobe baseline "$out/first.json" -o "$out/baseline.json"
  rm -f "$out/first.json"
fi
for i in 1 2; do
  step rtprobe run --filter "$filter" --inject-fault "$fault" --shard "$i/2" \
    --baseline "$out/baseline.json" -o "$out/shard-$i.json" --output-dir "$out/shard-$i"
done
step rtprobe merge "$out/shard-1.json" "$out/shard-2.json" -o "$out/merged.json"
