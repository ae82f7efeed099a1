$ /work/main/.dev/h200/rtprobe run --mutants --filter scene_layout=shared_buffers,resource=sampled_image -o layout-mutants.json
