$ /work/main/.dev/h200/rtprobe run --patches all -o new-warmup.json
