$ /work/main/.dev/h200/rtprobe run --mutants --filter scene_layout=shared_buffers|per_mesh -o layout-mutants.json
