$ /work/main/.dev/h200/rtprobe run -o default-cold.json
