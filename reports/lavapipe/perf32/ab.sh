#!/bin/bash
cd /tmp/own
for i in 3 4 5; do for t in base new2; do RTPROBE_CACHE_DIR=/tmp/own/cache-perf RUST_LOG=trace ./rtprobe-$t run --no-confirm --patches none --threads 2 -j 1 -o t2-$t-$i.json > t2-$t-$i.txt 2> t2-$t-$i.log; done; done
echo "ab t2 done $(uptime)" >> times.txt
for i in 1 2; do for t in base new2; do c=/tmp/own/cache-base; [ $t = new2 ] && c=/tmp/own/cache-new; uptime > ab-$t-$i.load; s=$(date +%s%N); RTPROBE_CACHE_DIR=$c ./rtprobe-$t run -o ab-$t-$i.json > ab-$t-$i.txt 2>&1; echo "ab-$t-$i process_ms=$(( ($(date +%s%N)-s)/1000000 )) $(cat ab-$t-$i.load)" >> times.txt; done; done
echo abdone >> times.txt
