$ /work/main/.dev/h200/rtprobe run --shader /work/main/tests/shaders/user/object_table.rchit -D NO_NONUNIFORM --repeat 2 -o shader-vote.json
