//! The scene on the GPU: vertex/index/AABB buffers, one BLAS per mesh (one geometry per range of
//! `Mesh::geometries`) plus one for the procedural sphere, the scene TLAS (every instance, as
//! `Scene::instances` lists them) and the AS probe's TLAS variants (`probe::as_variant_has`
//! instances plus the floor, custom indices `probe::as_custom`). Built once per worker, only when
//! a cell needs it.
use super::{Geometry, Instance, Scene, SPHERE_AABB};
use crate::probe;
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
    /// Every scene instance (binding 1, the primary rays).
    pub scene_tlas: AccelStruct,
    /// The AS probe's TLAS variants (`probe::as_variants` of them).
    pub probe_tlas: Vec<AccelStruct>,
    inputs: Vec<Buffer>,
    /// Host-side wall time of [`SceneGpu::build`]: geometry upload, BLAS and TLAS builds and
    /// the fence wait (the run report's `timing.as_build_ms_*`).
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
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);

pub(crate) fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // SAFETY: plain-old-data slices of f32/u32 arrays and Vulkan POD structs.
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

pub(crate) struct Pending {
    pub(crate) geometries: Vec<vk::AccelerationStructureGeometryKHR<'static>>,
    pub(crate) ranges: Vec<vk::AccelerationStructureBuildRangeInfoKHR>,
    pub(crate) ty: vk::AccelerationStructureTypeKHR,
}

/// One BLAS build of one triangle geometry (f32 positions, u32 indices) with `flags`; the vertex
/// and index buffers go to `inputs` (they must live until the build has run).
pub(crate) fn triangles(
    gpu: &Gpu,
    positions: &[[f32; 3]],
    indices: &[[u32; 3]],
    flags: vk::GeometryFlagsKHR,
    inputs: &mut Vec<Buffer>,
) -> Result<Pending, VkError> {
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
    let range =
        vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(indices.len() as u32);
    inputs.extend([vb, ib]);
    Ok(Pending {
        geometries: vec![geometry],
        ranges: vec![range],
        ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
    })
}

/// Record the builds of each level in order, with a full barrier after each level.
pub(crate) fn record_builds(gpu: &Gpu, cmd: vk::CommandBuffer, levels: &[&[Build]]) {
    let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
    for level in levels {
        for (info, ranges) in level.iter() {
            // SAFETY: the build infos point at live geometry, AS objects and scratch.
            unsafe {
                accel.cmd_build_acceleration_structures(cmd, std::slice::from_ref(info), &[*ranges])
            };
        }
        full_barrier(gpu, cmd);
    }
}

pub(crate) type Build<'a> = (
    vk::AccelerationStructureBuildGeometryInfoKHR<'a>,
    &'a [vk::AccelerationStructureBuildRangeInfoKHR],
);

/// The BLAS builds: one per mesh (one geometry per range of its triangles), then the sphere's
/// AABB; their vertex, index and AABB buffers go to `inputs`.
fn pending_blas(
    gpu: &Gpu,
    scene: &Scene,
    inputs: &mut Vec<Buffer>,
) -> Result<Vec<Pending>, BuildError> {
    let mut blas_pending = Vec::new();
    for mesh in &scene.meshes {
        let vb = Buffer::with_data(gpu, bytes_of(&mesh.positions), INPUT_USAGE, "vertex buffer")?;
        let ib = Buffer::with_data(gpu, bytes_of(&mesh.indices), INPUT_USAGE, "index buffer")?;
        let tri = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
            .vertex_format(vk::Format::R32G32B32_SFLOAT)
            .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: vb.address })
            .vertex_stride(12)
            .max_vertex(mesh.positions.len() as u32 - 1)
            .index_type(vk::IndexType::UINT32)
            .index_data(vk::DeviceOrHostAddressConstKHR { device_address: ib.address });
        let geometry = vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { triangles: tri })
            .flags(vk::GeometryFlagsKHR::OPAQUE);
        // One geometry per range: same buffers, the range's first triangle as primitive offset.
        let ranges: Vec<_> = mesh
            .geometries
            .iter()
            .map(|r| {
                vk::AccelerationStructureBuildRangeInfoKHR::default()
                    .primitive_count(r.end - r.start)
                    .primitive_offset(r.start * 12)
            })
            .collect();
        blas_pending.push(Pending {
            geometries: vec![geometry; ranges.len()],
            ranges,
            ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
        });
        inputs.extend([vb, ib]);
    }
    let aabb = vk::AabbPositionsKHR {
        min_x: SPHERE_AABB[0],
        min_y: SPHERE_AABB[1],
        min_z: SPHERE_AABB[2],
        max_x: SPHERE_AABB[3],
        max_y: SPHERE_AABB[4],
        max_z: SPHERE_AABB[5],
    };
    let ab = Buffer::with_data(gpu, bytes_of(&[aabb]), INPUT_USAGE, "AABB buffer")?;
    let aabbs = vk::AccelerationStructureGeometryAabbsDataKHR::default()
        .data(vk::DeviceOrHostAddressConstKHR { device_address: ab.address })
        .stride(std::mem::size_of::<vk::AabbPositionsKHR>() as u64);
    blas_pending.push(Pending {
        geometries: vec![vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::AABBS)
            .geometry(vk::AccelerationStructureGeometryDataKHR { aabbs })
            .flags(vk::GeometryFlagsKHR::OPAQUE)],
        ranges: vec![vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(1)],
        ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
    });
    inputs.push(ab);
    Ok(blas_pending)
}

/// The custom index of instance `k` (`k = instances`: the floor) in probe TLAS variant `v`.
pub type VariantCustom = fn(u32, u32) -> u32;

/// The TLAS instance lists: the scene TLAS, then the probe variants (`blas`: the BLAS of each
/// mesh, then the sphere's), their custom indices from `custom`.
fn instance_lists(
    scene: &Scene,
    blas: &[AccelStruct],
    custom: VariantCustom,
) -> Vec<Vec<vk::AccelerationStructureInstanceKHR>> {
    let blas_index = |g: Geometry| match g {
        Geometry::Mesh(m) => m,
        Geometry::Sphere => scene.meshes.len(),
    };
    let flags = if scene.no_opaque {
        vk::GeometryInstanceFlagsKHR::FORCE_NO_OPAQUE.as_raw() as u8
    } else {
        0
    };
    let sbt = |i: &Instance| match i.geometry {
        Geometry::Mesh(_) => i.sbt_offset(),
        Geometry::Sphere => scene.procedural_sbt_offset,
    };
    let instance = |i: &Instance, custom: u32| vk::AccelerationStructureInstanceKHR {
        transform: vk::TransformMatrixKHR { matrix: bytemuck_transform(&i.transform) },
        instance_custom_index_and_mask: vk::Packed24_8::new(custom, 0xff),
        instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(sbt(i), flags),
        acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
            device_handle: blas[blas_index(i.geometry)].address,
        },
    };
    let n = scene.instances.len() as u32;
    let mut lists =
        vec![scene.instances.iter().map(|i| instance(i, i.custom_index)).collect::<Vec<_>>()];
    for v in 0..probe::as_variants(n) {
        let mut l: Vec<_> = (0..n)
            .filter(|k| probe::as_variant_has(v, *k))
            .map(|k| instance(&scene.instances[k as usize], custom(v, k)))
            .collect();
        l.push(instance(&scene.floor, custom(v, n)));
        lists.push(l);
    }
    lists
}

/// One TLAS build per instance list; the instance buffers go to `inputs`.
fn pending_tlas(
    gpu: &Gpu,
    lists: Vec<Vec<vk::AccelerationStructureInstanceKHR>>,
    inputs: &mut Vec<Buffer>,
) -> Result<Vec<Pending>, BuildError> {
    let mut tlas_pending = Vec::new();
    for instances in lists {
        let ib = Buffer::with_data(gpu, bytes_of(&instances), INPUT_USAGE, "instance buffer")?;
        let data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .array_of_pointers(false)
            .data(vk::DeviceOrHostAddressConstKHR { device_address: ib.address });
        tlas_pending.push(Pending {
            geometries: vec![vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::INSTANCES)
                .geometry(vk::AccelerationStructureGeometryDataKHR { instances: data })],
            ranges: vec![vk::AccelerationStructureBuildRangeInfoKHR::default()
                .primitive_count(instances.len() as u32)],
            ty: vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        });
        inputs.push(ib);
    }
    Ok(tlas_pending)
}

impl SceneGpu {
    pub fn build(
        gpu: &Gpu,
        scene: &Scene,
        submitter: &Submitter,
        timeout: Duration,
    ) -> Result<SceneGpu, BuildError> {
        Self::build_with(gpu, scene, submitter, timeout, probe::as_custom)
    }

    /// [`Self::build`] with the probe TLAS variants' custom indices from `custom` instead of
    /// `probe::as_custom` (the patch harness keeps them small enough to index arrays with).
    pub fn build_with(
        gpu: &Gpu,
        scene: &Scene,
        submitter: &Submitter,
        timeout: Duration,
        custom: VariantCustom,
    ) -> Result<SceneGpu, BuildError> {
        let start = Instant::now();
        let mut inputs = Vec::new();
        let blas_pending = pending_blas(gpu, scene, &mut inputs)?;
        let mut all_scratch = Vec::new();
        let (blas, blas_builds) = Self::prepare_all(gpu, &blas_pending, &mut all_scratch)?;
        let tlas_pending = pending_tlas(gpu, instance_lists(scene, &blas, custom), &mut inputs)?;
        let (mut tlas, tlas_builds) = Self::prepare_all(gpu, &tlas_pending, &mut all_scratch)?;

        let waited = submitter
            .run(gpu, timeout, |cmd| record_builds(gpu, cmd, &[&blas_builds, &tlas_builds]))?;
        if waited == Waited::TimedOut {
            // The builds may still be running: their scratch, inputs and structures are left
            // alive (leaked), never freed under them. "All submitted commands that refer to
            // buffer [...] must have completed execution" (VUID-vkDestroyBuffer-buffer-00922,
            // Vulkan 1.4.360): freeing the scratch here made lavapipe 26's build shader read
            // unmapped memory (SIGSEGV in setup; reports/lavapipe-26/FINDINGS.md).
            return Err(BuildError::TimedOut(timeout));
        }
        for s in &all_scratch {
            s.destroy(gpu);
        }
        drop(blas_pending);
        drop(tlas_pending);
        let probe_tlas = tlas.split_off(1);
        let scene_tlas = tlas.pop().expect("the scene TLAS");
        Ok(SceneGpu {
            blas,
            scene_tlas,
            probe_tlas,
            inputs,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// [`Self::prepare`] for each of `pending`; scratch buffers go to `scratch` (freed after the build).
    pub(crate) fn prepare_all<'a>(
        gpu: &Gpu,
        pending: &'a [Pending],
        scratch: &mut Vec<Buffer>,
    ) -> Result<(Vec<AccelStruct>, Vec<Build<'a>>), VkError> {
        let mut out = Vec::new();
        let mut builds = Vec::new();
        for p in pending {
            let (a, s, info) = Self::prepare(gpu, p)?;
            builds.push((info, p.ranges.as_slice()));
            scratch.push(s);
            out.push(a);
        }
        Ok((out, builds))
    }

    /// Sizes, buffer, AS object and scratch for one build; returns the build info pointing at `p`.
    fn prepare<'a>(
        gpu: &Gpu,
        p: &'a Pending,
    ) -> Result<(AccelStruct, Buffer, vk::AccelerationStructureBuildGeometryInfoKHR<'a>), VkError>
    {
        let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
        // A module reading `HitTriangleVertexPositionsKHR`: "The acceleration structure
        // corresponding to the current intersection must have been built with
        // VK_BUILD_ACCELERATION_STRUCTURE_ALLOW_DATA_ACCESS_BIT_KHR"
        // (VUID-HitTriangleVertexPositionsKHR-None-08751, Vulkan 1.4.360). Set on every BLAS of a
        // device given rayTracingPositionFetch, which only such modules ask for.
        let mut flags = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE;
        if gpu.enabled.shader.position_fetch
            && p.ty == vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL
        {
            flags |= vk::BuildAccelerationStructureFlagsKHR::ALLOW_DATA_ACCESS;
        }
        let mut info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(p.ty)
            .flags(flags)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(&p.geometries);
        let counts: Vec<u32> = p.ranges.iter().map(|r| r.primitive_count).collect();
        let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
        unsafe {
            accel.get_acceleration_structure_build_sizes(
                vk::AccelerationStructureBuildTypeKHR::DEVICE,
                &info,
                &counts,
                &mut sizes,
            )
        };
        let buffer = Buffer::new(
            gpu,
            sizes.acceleration_structure_size,
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Device,
            "acceleration structure",
        )?;
        let ci = vk::AccelerationStructureCreateInfoKHR::default()
            .buffer(buffer.raw)
            .size(sizes.acceleration_structure_size)
            .ty(p.ty);
        let raw = unsafe { accel.create_acceleration_structure(&ci, None) }
            .at("vkCreateAccelerationStructureKHR")?;
        let address = unsafe {
            accel.get_acceleration_structure_device_address(
                &vk::AccelerationStructureDeviceAddressInfoKHR::default()
                    .acceleration_structure(raw),
            )
        };
        let align = gpu
            .info
            .properties
            .accel
            .map(|a| a.min_acceleration_structure_scratch_offset_alignment as u64)
            .unwrap_or(256)
            .max(1);
        let scratch = Buffer::new(
            gpu,
            sizes.build_scratch_size + align,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            Location::Device,
            "scratch",
        )?;
        let aligned = scratch.address.div_ceil(align) * align;
        info = info
            .dst_acceleration_structure(raw)
            .scratch_data(vk::DeviceOrHostAddressKHR { device_address: aligned });
        Ok((AccelStruct { raw, buffer, address }, scratch, info))
    }

    pub fn destroy(&self, gpu: &Gpu) {
        let accel = gpu.accel.as_ref().expect("acceleration structures enabled");
        for a in
            self.blas.iter().chain(std::iter::once(&self.scene_tlas)).chain(self.probe_tlas.iter())
        {
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
