$ /work/main/.dev/h200/rtprobe-new run -o ab-new-warm4.json
