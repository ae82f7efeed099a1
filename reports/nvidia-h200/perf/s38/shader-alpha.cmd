$ /work/main/.dev/h200/rtprobe run --shader /work/main/tests/shaders/user/object_table.rchit --shader /work/main/tests/shaders/user/alpha_table.rahit --repeat 2 -o shader-alpha.json
