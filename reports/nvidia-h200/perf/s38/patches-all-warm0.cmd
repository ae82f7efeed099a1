$ /work/main/.dev/h200/rtprobe run --patches all -o patches-all-warm0.json
