$ /work/main/.dev/h200/rtprobe run --filter stage=miss,resource=storage_buffer|uniform_buffer,descriptor_model=descriptor_indexing --inject-fault stage=miss,index=dynamic@value:0.1 -o injected1.json
