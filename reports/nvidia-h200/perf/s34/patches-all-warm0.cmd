$ /work/main/.dev/h200/rtprobe-new run --patches all -o patches-all-warm0.json
