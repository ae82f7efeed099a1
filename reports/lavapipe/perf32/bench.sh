#!/bin/bash
# usage: bench.sh TAG BIN  — one warming run, then 3 warm runs, plus a trace run
TAG=$1; BIN=$2; export RTPROBE_CACHE_DIR=/tmp/own/cache-$TAG; mkdir -p $RTPROBE_CACHE_DIR
cd /tmp/own
$BIN run -o $TAG-0.json > $TAG-0.txt 2>&1
for i in 1 2 3; do uptime > $TAG-$i.load; s=$(date +%s%N); $BIN run -o $TAG-$i.json > $TAG-$i.txt 2>&1; echo "$TAG-$i rc=$? process_ms=$(( ($(date +%s%N)-s)/1000000 )) $(cat $TAG-$i.load)" >> times.txt; done
RUST_LOG=trace $BIN run -o $TAG-trace.json > $TAG-trace.txt 2> $TAG-trace.log
echo done-$TAG >> times.txt
