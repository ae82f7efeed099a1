$ /work/main/.dev/h200/rtprobe-new run -o default-warm1.json
