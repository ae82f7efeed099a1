$ /work/main/.dev/h200/rtprobe run -o default-warm1.json
