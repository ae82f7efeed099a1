$ /work/main/.dev/h200/rtprobe run --patches all -j 1 -o new-j1.json
