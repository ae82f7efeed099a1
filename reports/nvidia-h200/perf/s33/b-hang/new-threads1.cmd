$ /work/main/.dev/h200/rtprobe run --patches all --threads 1 -o new-threads1.json
