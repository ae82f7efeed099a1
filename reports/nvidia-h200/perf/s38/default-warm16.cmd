$ /work/main/.dev/h200/rtprobe run -o default-warm16.json
