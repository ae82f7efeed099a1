$ rtprobe run -j 1 --scene sc/scene.gltf --filter stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer -o time-test.json
