$ /work/main/.dev/h200/rtprobe-old run -o ab-old-warm4.json
