$ /work/main/.dev/h200/rtprobe run --shader /work/main/tests/shaders/user/light_table.rchit --repeat 2 -o shader-light.json
