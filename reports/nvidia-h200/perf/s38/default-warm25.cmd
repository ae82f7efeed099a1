$ /work/main/.dev/h200/rtprobe run -o default-warm25.json
