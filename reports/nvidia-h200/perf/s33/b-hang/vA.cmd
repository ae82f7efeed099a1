$ /work/main/.dev/h200/rtprobe-vA run --patches all -o vA.json
