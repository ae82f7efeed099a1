$ /work/main/.dev/h200/rtprobe-vB run --patches all -o vB.json
