$ /work/main/.dev/h200/rtprobe-new run -o default-warm2.json
