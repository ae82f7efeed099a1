$ rtprobe run -j 1 --scene big/scene.glb --filter stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer -o time-1m.json
