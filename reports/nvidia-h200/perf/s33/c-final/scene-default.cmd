$ /work/main/.dev/h200/rtprobe run --scene sc/scene.gltf -o scene-default.json
