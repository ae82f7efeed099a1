$ /work/main/.dev/h200/rtprobe run --scene sc/scene.gltf --filter scene_layout=shared_buffers|per_mesh -o layout-scene.json
