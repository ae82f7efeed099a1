$ /work/main/.dev/h200/rtprobe-new run -o ab-new-warm2.json
