$ /work/main/.dev/h200/rtprobe-new run -o default-warm4.json
