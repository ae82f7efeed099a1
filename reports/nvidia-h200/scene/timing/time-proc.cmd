$ rtprobe run -j 1 --filter stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer -o time-proc.json
