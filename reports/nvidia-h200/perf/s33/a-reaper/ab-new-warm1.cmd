$ /work/main/.dev/h200/rtprobe run -o ab-new-warm1.json
