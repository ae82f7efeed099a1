$ /work/main/.dev/h200/rtprobe run --patches all -o patches-all-warm1.json
