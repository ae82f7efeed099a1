$ /work/main/.dev/h200/rtprobe run -o default-warm19.json
