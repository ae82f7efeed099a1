$ /work/main/.dev/h200/rtprobe run --patches all --pipelines whole -o new-whole.json
