//! The scene on the GPU: vertex/index/AABB buffers, one BLAS per mesh plus one for the procedural
//! sphere, and the two TLASes the probes use (TLAS 0: every instance; TLAS 1: the instances with
//! an even custom index). Built once per worker, only when a cell needs it.
use super::{Geometry, Scene, SPHERE_AABB};
use crate::vk::memory::{full_barrier, Buffer, Location};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{Gpu, VkError, VkResultExt};
use ash::vk;
use std::time::{Duration, Instant};

pub struct AccelStruct {
    pub raw: vk::AccelerationStructureKHR,
    pub buffer: Buffer,
    pub address: u64,
}

pub struct SceneGpu {
    pub blas: Vec<AccelStruct>,
    /// [whole scene, even custom indices]
    pub tlas: [AccelStruct; 2],
    inputs: Vec<Buffer>,
    pub build_ms: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error(transparent)]
    Vk(#[from] VkError),
    #[error("acceleration structure build did not finish within {0:?}")]
    TimedOut(Duration),
}

pub(crate) const INPUT_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR.as_raw() | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);

pub(crate) fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // SAFETY: plain-old-data slices of f32/u32 arrays and Vulkan POD structs.
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

pub(crate) struct Pending {
    pub(crate) geometry: vk::AccelerationStructureGeometryKHR<'static>,
    pub(crate) range: vk::AccelerationStructureBuildRangeInfoKHR,
    pub(crate) ty: vk::AccelerationStructureTypeKHR,
}

/// One BLAS build of one triangle geometry (f32 positions, u32 indices) with `flags`; the vertex
/// and index buffers go to `inputs` (they must live until the build has run).
pub(crate) fn triangles(gpu: &Gpu, positions: &[[f32; 3]], indices: &[[u32; 3]], flags: vk::GeometryFlagsKHR, inputs: &mut Vec<Buffer>) -> Result<Pending, VkError> {
    let vb = Buffer::with_data(gpu, bytes_of(positions), INPUT_USAGE, "vertex buffer")?;
    let ib = match Buffer::with_data(gpu, bytes_of(indices), INPUT_USAGE, "index buffer") {
        Ok(b) => b,
        Err(e) => {
            inputs.push(vb);
            return Err(e);
        }
    };
    let tri = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
        .vertex_format(vk::Format::R32G32B32_SFLOAT)
        .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: vb.address })
        .vertex_stride(12)
        .max_vertex(positions.len() as u32 - 1)
        .index_type(vk::IndexType::UINT32)
        .index_data(vk::DeviceOrHostAddressConstKHR { device_address: ib.address });
    let geometry = vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
        .geometry(vk::AccelerationStructureGeometryDataKHR { triangles: tri })
        .flags(flags);
    let range = vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(indices.len() as u32);
    inputs.extend([vb, ib]);
    Ok(Pending { geometry, range, ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL })
}

/// Record the builds of each level in order, with a full barrier after each level.
pub(crate) fn record_builds(gpu: &Gpu, cmd: vk::CommandBuffer, levels: &[&[(vk::AccelerationStructureBuildGeometryInfoKHR, vk::AccelerationStructureBuildRangeInfoKHR)]]) {
    let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
    for level in levels {
        for (info, range) in level.iter() {
            // SAFETY: the build infos point at live geometry, AS objects and scratch.
            unsafe { accel.cmd_build_acceleration_structures(cmd, std::slice::from_ref(info), &[std::slice::from_ref(range)]) };
        }
        full_barrier(gpu, cmd);
    }
}

impl SceneGpu {
    pub fn build(gpu: &Gpu, scene: &Scene, submitter: &Submitter, timeout: Duration) -> Result<SceneGpu, BuildError> {
        let start = Instant::now();
        let mut inputs = Vec::new();
        let mut blas_pending = Vec::new();
        for mesh in &scene.meshes {
            blas_pending.push(triangles(gpu, &mesh.positions, &mesh.indices, vk::GeometryFlagsKHR::OPAQUE, &mut inputs)?);
        }
        let aabb = vk::AabbPositionsKHR {
            min_x: SPHERE_AABB[0], min_y: SPHERE_AABB[1], min_z: SPHERE_AABB[2],
            max_x: SPHERE_AABB[3], max_y: SPHERE_AABB[4], max_z: SPHERE_AABB[5],
        };
        let ab = Buffer::with_data(gpu, bytes_of(&[aabb]), INPUT_USAGE, "AABB buffer")?;
        let aabbs = vk::AccelerationStructureGeometryAabbsDataKHR::default()
            .data(vk::DeviceOrHostAddressConstKHR { device_address: ab.address })
            .stride(std::mem::size_of::<vk::AabbPositionsKHR>() as u64);
        blas_pending.push(Pending {
            geometry: vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::AABBS)
                .geometry(vk::AccelerationStructureGeometryDataKHR { aabbs })
                .flags(vk::GeometryFlagsKHR::OPAQUE),
            range: vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(1),
            ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
        });
        inputs.push(ab);

        let mut all_scratch = Vec::new();
        let (blas, blas_builds) = Self::prepare_all(gpu, &blas_pending, &mut all_scratch)?;

        // Instances: TLAS 0 all, TLAS 1 the even custom indices.
        let blas_index = |g: Geometry| match g {
            Geometry::Mesh(m) => m,
            Geometry::Sphere => scene.meshes.len(),
        };
        let mut tlas_pending = Vec::new();
        for filter in [None, Some(0u32)] {
            let instances: Vec<vk::AccelerationStructureInstanceKHR> = scene
                .instances
                .iter()
                .filter(|i| filter.is_none_or(|r| i.custom_index % 2 == r))
                .map(|i| vk::AccelerationStructureInstanceKHR {
                    transform: vk::TransformMatrixKHR { matrix: bytemuck_transform(&i.transform) },
                    instance_custom_index_and_mask: vk::Packed24_8::new(i.custom_index, 0xff),
                    instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(i.sbt_offset(), 0),
                    acceleration_structure_reference: vk::AccelerationStructureReferenceKHR { device_handle: blas[blas_index(i.geometry)].address },
                })
                .collect();
            let ib = Buffer::with_data(gpu, bytes_of(&instances), INPUT_USAGE, "instance buffer")?;
            let data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
                .array_of_pointers(false)
                .data(vk::DeviceOrHostAddressConstKHR { device_address: ib.address });
            tlas_pending.push(Pending {
                geometry: vk::AccelerationStructureGeometryKHR::default()
                    .geometry_type(vk::GeometryTypeKHR::INSTANCES)
                    .geometry(vk::AccelerationStructureGeometryDataKHR { instances: data }),
                range: vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(instances.len() as u32),
                ty: vk::AccelerationStructureTypeKHR::TOP_LEVEL,
            });
            inputs.push(ib);
        }
        let (mut tlas, tlas_builds) = Self::prepare_all(gpu, &tlas_pending, &mut all_scratch)?;

        let waited = submitter.run(gpu, timeout, |cmd| record_builds(gpu, cmd, &[&blas_builds, &tlas_builds]))?;
        for s in &all_scratch {
            s.destroy(gpu);
        }
        drop(blas_pending);
        drop(tlas_pending);
        if waited == Waited::TimedOut {
            return Err(BuildError::TimedOut(timeout));
        }
        let t1 = tlas.pop().expect("two TLAS");
        let t0 = tlas.pop().expect("two TLAS");
        Ok(SceneGpu { blas, tlas: [t0, t1], inputs, build_ms: start.elapsed().as_secs_f64() * 1e3 })
    }

    /// [`Self::prepare`] for each of `pending`; scratch buffers go to `scratch` (freed after the build).
    #[allow(clippy::type_complexity)]
    pub(crate) fn prepare_all<'a>(
        gpu: &Gpu,
        pending: &'a [Pending],
        scratch: &mut Vec<Buffer>,
    ) -> Result<(Vec<AccelStruct>, Vec<(vk::AccelerationStructureBuildGeometryInfoKHR<'a>, vk::AccelerationStructureBuildRangeInfoKHR)>), VkError> {
        let mut out = Vec::new();
        let mut builds = Vec::new();
        for p in pending {
            let (a, s, info) = Self::prepare(gpu, p)?;
            builds.push((info, p.range));
            scratch.push(s);
            out.push(a);
        }
        Ok((out, builds))
    }

    /// Sizes, buffer, AS object and scratch for one build; returns the build info pointing at `p`.
    fn prepare<'a>(gpu: &Gpu, p: &'a Pending) -> Result<(AccelStruct, Buffer, vk::AccelerationStructureBuildGeometryInfoKHR<'a>), VkError> {
        let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
        let mut info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(p.ty)
            .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(std::slice::from_ref(&p.geometry));
        let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
        unsafe {
            accel.get_acceleration_structure_build_sizes(vk::AccelerationStructureBuildTypeKHR::DEVICE, &info, &[p.range.primitive_count], &mut sizes)
        };
        let buffer = Buffer::new(
            gpu,
            sizes.acceleration_structure_size,
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Device,
            "acceleration structure",
        )?;
        let ci = vk::AccelerationStructureCreateInfoKHR::default().buffer(buffer.raw).size(sizes.acceleration_structure_size).ty(p.ty);
        let raw = unsafe { accel.create_acceleration_structure(&ci, None) }.at("vkCreateAccelerationStructureKHR")?;
        let address = unsafe {
            accel.get_acceleration_structure_device_address(&vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(raw))
        };
        let align = gpu.info.properties.accel.map(|a| a.min_acceleration_structure_scratch_offset_alignment as u64).unwrap_or(256).max(1);
        let scratch = Buffer::new(
            gpu,
            sizes.build_scratch_size + align,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Device,
            "scratch",
        )?;
        let aligned = scratch.address.div_ceil(align) * align;
        info = info.dst_acceleration_structure(raw).scratch_data(vk::DeviceOrHostAddressKHR { device_address: aligned });
        Ok((AccelStruct { raw, buffer, address }, scratch, info))
    }

    pub fn destroy(&self, gpu: &Gpu) {
        let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
        for a in self.blas.iter().chain(self.tlas.iter()) {
            unsafe { accel.destroy_acceleration_structure(a.raw, None) };
            a.buffer.destroy(gpu);
        }
        for b in &self.inputs {
            b.destroy(gpu);
        }
    }
}

pub(crate) fn bytemuck_transform(t: &[[f32; 4]; 3]) -> [f32; 12] {
    let mut m = [0.0; 12];
    for (r, row) in t.iter().enumerate() {
        m[r * 4..r * 4 + 4].copy_from_slice(row);
    }
    m
}
