$ /work/main/.dev/h200/rtprobe run --filter scene_layout=shared_buffers|per_mesh -o layout-proc.json
