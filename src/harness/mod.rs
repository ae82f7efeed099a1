//! The patch harness: a ray tracing pipeline built from given SPIR-V modules (raygen, misses,
//! closest-hit, any-hit, intersection, callables; a procedural hit group without an intersection
//! shader of its own gets one that reports nothing), its resources made from the modules'
//! reflected interface ([`reflect`]) with distinct data in every descriptor ([`resources`],
//! [`textures`]; runtime arrays and the sink sized by [`sizes`]), the
//! harness scene ([`scene`]: every index it produces within the runtime arrays) traced 64×64
//! from its raygen, and every storage image and every writable storage buffer read back. Running
//! the unpatched pipeline and the patched one — fed as the host contract says: each address in
//! push constants, tables of addresses — and comparing their images texel for texel and their
//! writable buffers byte for byte is `rtprobe patch --verify` ([`verify`], judged by [`judge`]).
//! Uses exec's pieces: the device, memory, the scene's acceleration structures and
//! `exec::pipeline`'s RT pipeline and SBT, with a fence deadline per submission. `rtprobe patch`
//! runs it in a child process (`rtprobe __verify JOB`, [`child`]), so a driver crash is the
//! verification's outcome, not the end of rtprobe.
//! `rtprobe run --shader` runs a user's pipeline in it the same way, one variant per child
//! (`rtprobe __shader JOB`, [`run`]), `--entry` reducing a module to one entry point ([`entry`]).
mod bindings;
mod buffers;
mod capabilities;
pub mod child;
mod compare;
pub mod entry;
mod error;
pub mod fill;
mod groups;
pub mod heap;
pub mod hit_table;
pub mod inject;
pub mod ints;
mod module;
pub mod per_primitive;
pub mod profile;
pub mod ray_types;
mod record;
pub mod reflect;
mod resources;
pub mod run;
pub mod scene;
pub mod scene_data;
mod scene_item;
pub mod scene_textures;
pub mod sizes;
pub mod spec;
mod supply;
mod textures;
pub mod traces;
pub mod variable;

pub use bindings::check as check_bindings;
pub use compare::{compare, compare_within, judge, Compared, Part, PartKind, Tolerance, Verdict};
pub use error::HarnessError;
pub use module::{enable_needs, google, google_of, UserModule};
pub use sizes::Sizes;
pub use supply::{free_binding, supply, MISS_MARKER};

use crate::exec::pipeline::{self, Pipeline, RtPipeline, SbtCounts};
use crate::model::contract::HostContract;
use crate::model::DescriptorModel;
use crate::scene::gpu::SceneGpu;
use crate::vk::memory::{color_range, full_barrier, transition, Buffer, Location, Transition};
use crate::vk::submit::{Submitter, Waited};
use crate::vk::{Gpu, Requirements, VkResultExt};
use ash::vk;
use groups::{groups, Groups};
use reflect::BindingKind;
use resources::{Element, Resources};
use std::ffi::CString;
use std::time::Duration;

/// Width and height of the traced image.
pub const SIZE: u32 = scene::TRACE_SIZE;
/// The fence deadline of one submission by default.
pub const TIMEOUT: Duration = Duration::from_secs(30);

/// What the device must enable for `modules` (`scalar`: their blocks need scalar layout).
/// Every module needs the RT pipeline; the patched ones device addresses and 64-bit integers;
/// descriptor indexing covers runtime arrays and non-uniform indexing.
pub fn requirements(scalar: bool) -> Requirements {
    requirements_for(scalar, DescriptorModel::DescriptorIndexing)
}

/// [`requirements`] under descriptor model `model`: the heap model needs descriptor heaps and
/// the untyped pointers `layout(descriptor_heap)` arrays are compiled to.
pub fn requirements_for(scalar: bool, model: DescriptorModel) -> Requirements {
    let (heap, buffer) = match model {
        DescriptorModel::DescriptorHeap => (true, false),
        DescriptorModel::DescriptorBuffer => (false, true),
        DescriptorModel::DescriptorIndexing => (false, false),
    };
    Requirements {
        rt_pipeline: true,
        buffer_device_address: true,
        int64: true,
        descriptor_indexing: true,
        scalar_block_layout: scalar,
        descriptor_heap: heap,
        untyped_pointers: heap,
        descriptor_buffer: buffer,
        ..Requirements::default()
    }
}

/// How a harness binds its descriptors, and what each model needs at its run.
pub struct Setup {
    pub model: DescriptorModel,
    /// `--spec`'s values, given to every stage that declares them.
    pub spec: Vec<spec::SpecValue>,
    /// The heap model's arrays as `--heap-layout` gives them (else read from the modules).
    pub heap_layout: Option<Vec<heap::Array>>,
    /// `--profile`'s robustness (the device's, already enabled) and binding flags.
    pub profile: profile::ProfileSetup,
    /// The sink buffer's bytes (`--sink-size`).
    pub sink: u64,
    /// `--fill`'s bytes over the harness's data.
    pub fills: fill::Fills,
    /// `--scene`: the loaded scene traced instead of the harness's, and its `scene.NAME` fills.
    pub scene: Option<SceneSetup>,
    /// The fence deadline of the setup's submissions (acceleration-structure builds, uploads):
    /// `--setup-timeout`, not a trace's; `None`: the trace's.
    pub setup_timeout: Option<Duration>,
}

/// `run --shader --scene`'s scene and the fills that read it.
pub struct SceneSetup {
    pub loaded: crate::scene::gltf::Loaded,
    pub fills: Vec<scene_data::SceneFill>,
}

impl Default for Setup {
    fn default() -> Setup {
        Setup {
            profile: Default::default(),
            model: DescriptorModel::DescriptorIndexing,
            spec: Vec::new(),
            heap_layout: None,
            sink: sizes::SINK_SIZE,
            fills: fill::Fills::default(),
            scene: None,
            setup_timeout: None,
        }
    }
}

/// The bound descriptors: descriptor sets, descriptor buffers, or the heap model's heaps.
enum Bound {
    Sets,
    Buffers(buffers::DescriptorBuffers),
    Heap(heap::HeapModel),
}

/// A device with the scene, the resources of a set of modules and a pipeline layout for them.
pub struct Harness {
    gpu: Gpu,
    submitter: Submitter,
    scene: SceneGpu,
    res: Resources,
    layout: vk::PipelineLayout,
    push_size: u32,
    /// The integer words of the push range (every module's block).
    push_ints: ints::IntWords,
    /// The fence deadline of one submission.
    timeout: Duration,
    bound: Bound,
    spec: Vec<spec::SpecValue>,
    /// `--fill`'s bytes (push constants; the buffers' are in `res`).
    fills: fill::Fills,
    /// The shader record data after every SBT handle ([`record`]).
    record: Vec<u8>,
    /// `--scene`'s buffers that fills name.
    scene_buffers: Option<scene_data::SceneBuffers>,
    /// The most geometries a triangle BLAS of the scene has, and the sphere instances' SBT
    /// offset the hit table was laid out with ([`hit_table`]).
    geometries: u32,
    procedural: u32,
    /// `--scene`'s images, when `scene.textures` fills a texture array.
    scene_textures: Option<scene_textures::SceneTextures>,
}

/// Each stage's SPIR-V, stage flag and entry name, and the intersection shader's index.
type Sources = (Vec<Vec<u32>>, Vec<vk::ShaderStageFlags>, Vec<CString>, usize);

/// An intersection shader that reports nothing, for the procedural hit group of a pipeline
/// without one (the scene's spheres then stay invisible).
const NO_INTERSECTION: &str =
    "#version 460\n#extension GL_EXT_ray_tracing : require\nvoid main() {}\n";

/// The pipeline's shader groups: the raygen, each miss, one hit group per record of `table`
/// (its ray type's triangle or procedural group, the latter with that type's intersection
/// shader or `intersection`; an empty triangle group where no ray reaches), each callable.
fn shader_groups(
    g: &Groups,
    table: &hit_table::HitTable,
    intersection: usize,
) -> Vec<vk::RayTracingShaderGroupCreateInfoKHR<'static>> {
    use hit_table::Geometry;
    let idx = |i: Option<usize>| i.map_or(vk::SHADER_UNUSED_KHR, |i| i as u32);
    let general = |i: usize| {
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
            .general_shader(i as u32)
            .closest_hit_shader(vk::SHADER_UNUSED_KHR)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR)
    };
    let hit = |ty, chit: Option<usize>, any: Option<usize>, isect: Option<usize>| {
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(ty)
            .general_shader(vk::SHADER_UNUSED_KHR)
            .closest_hit_shader(idx(chit))
            .any_hit_shader(idx(any))
            .intersection_shader(idx(isect))
    };
    let mut groups = vec![general(g.raygen)];
    groups.extend(g.misses.iter().map(|i| general(*i)));
    for r in &table.records {
        let t = r.map(|(kind, k)| (kind, g.types[k as usize]));
        groups.push(match t {
            Some((Geometry::Procedural, t)) => hit(
                vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP,
                t.hit[1],
                t.any_hit,
                Some(t.intersection.unwrap_or(intersection)),
            ),
            Some((Geometry::Triangles, t)) => hit(
                vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP,
                t.hit[0],
                t.any_hit,
                None,
            ),
            None => hit(vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP, None, None, None),
        });
    }
    groups.extend(g.callables.iter().map(|i| general(*i)));
    groups
}

/// The integer and address words of the push block, from every module's reflection.
fn push_ints(modules: &[&UserModule]) -> ints::IntWords {
    let mut out = ints::IntWords::default();
    for m in modules {
        out.fixed.low.extend(&m.iface.push_ints.fixed.low);
        out.fixed.addr.extend(&m.iface.push_ints.fixed.addr);
    }
    out
}

/// `--profile`'s binding flags: only on descriptor sets the shaders bind through.
fn binding_flags(setup: &Setup) -> crate::model::profile::BindingFlags {
    match setup.model {
        DescriptorModel::DescriptorIndexing => setup.profile.flags,
        DescriptorModel::DescriptorBuffer | DescriptorModel::DescriptorHeap => Default::default(),
    }
}

/// The scene the harness traces — `--scene`'s, fitted, else the harness's — with the buffers
/// its fills name and every fill placed.
fn traced_scene(
    gpu: &Gpu,
    setup: &Setup,
) -> Result<(crate::scene::Scene, Option<scene_data::SceneBuffers>, fill::Fills), HarnessError> {
    Ok(match &setup.scene {
        Some(s) => {
            let b = scene_data::SceneBuffers::new(gpu, &s.loaded, &s.fills)?;
            let fills = b.placed(&s.loaded, &setup.fills, &s.fills);
            (scene::loaded(&s.loaded, SIZE), Some(b), fills)
        }
        None => (scene::build(SIZE), None, setup.fills.clone()),
    })
}

/// The supplied raygen's TLAS binding: it traces the scene, so it gets the scene TLAS.
fn scene_tlas_binding(modules: &[&UserModule]) -> Option<(u32, u32)> {
    modules
        .iter()
        .filter(|m| m.name == supply::RAYGEN_NAME)
        .flat_map(|m| &m.iface.bindings)
        .find(|b| b.kind == BindingKind::AccelerationStructure)
        .map(|b| (b.set, b.binding))
}

/// `--scene`'s images on the device, when a `scene.textures` fill puts them in a texture array.
fn scene_images(
    gpu: &Gpu,
    setup: &Setup,
    fenced: (&Submitter, Duration),
) -> Result<Option<scene_textures::SceneTextures>, HarnessError> {
    match &setup.scene {
        Some(s) => {
            let targets = scene_data::texture_targets(&s.fills);
            scene_textures::SceneTextures::new(gpu, &s.loaded, targets, fenced)
        }
        None => Ok(None),
    }
}

impl Harness {
    /// The scene and resources for `modules` (every module the pipelines will use, unpatched:
    /// the patched ones read the same resources through addresses), push constants of
    /// `push_size` bytes, each submission fenced with `timeout`, the sink of `sink_size` bytes
    /// (`Sizes::sink`).
    pub fn new(
        gpu: Gpu,
        modules: &[&UserModule],
        push_size: u32,
        timeout: Duration,
        sink_size: u64,
    ) -> Result<Harness, HarnessError> {
        Harness::with_setup(
            gpu,
            modules,
            push_size,
            timeout,
            Setup { sink: sink_size, ..Setup::default() },
        )
    }

    /// [`Harness::new`] binding as `setup.model` says, specializing with `setup.spec`.
    pub fn with_setup(
        gpu: Gpu,
        modules: &[&UserModule],
        push_size: u32,
        timeout: Duration,
        setup: Setup,
    ) -> Result<Harness, HarnessError> {
        let submitter = Submitter::new(&gpu)?;
        // The setup's builds and uploads wait as long as the setup may take: a large scene's
        // build outlasts a trace's deadline.
        let wait = setup.setup_timeout.unwrap_or(timeout);
        let (mut built, scene_buffers, fills) = traced_scene(&gpu, &setup)?;
        // A given any-hit runs on every candidate, as on an engine's alpha-tested geometry.
        built.no_opaque = modules.iter().any(|m| m.iface.stage == "any_hit");
        let geometries = built.meshes.iter().map(|m| m.geometries.len() as u32).max().unwrap_or(1);
        let types = groups(modules)?.types.len() as u32;
        let procedural = hit_table::layout(modules, types, geometries)?.procedural;
        built.procedural_sbt_offset = procedural;
        let scene = SceneGpu::build_with(&gpu, &built, &submitter, wait, scene::variant_custom)?;
        let bindings: Vec<reflect::Binding> =
            modules.iter().flat_map(|m| m.iface.bindings.iter().cloned()).collect();
        let extent = vk::Extent2D { width: SIZE, height: SIZE };
        let scene_at = scene_tlas_binding(modules);
        let buffer_model = setup.model == DescriptorModel::DescriptorBuffer;
        let made = (setup.sink, buffer_model, binding_flags(&setup));
        let scene_textures = scene_images(&gpu, &setup, (&submitter, wait))?;
        let given = (&fills, scene_textures.as_ref());
        let res = Resources::new(&gpu, &bindings, scene_at, &scene, extent, made, given)?;
        let record = record::data(modules, res.sink.address, &fills);
        if let Some(p) = gpu.info.properties.rt_pipeline {
            record::check(record.len(), p.shader_group_handle_size, p.max_shader_group_stride)?;
        }
        res.textures.upload(&gpu, &submitter, wait)?;
        let bound = bind_model(&gpu, &setup, modules, &res, &scene)?;
        let push_size = push_size.div_ceil(4) * 4;
        let push_ints = push_ints(modules);
        let range =
            [vk::PushConstantRange::default().stage_flags(resources::rt_stages()).size(push_size)];
        let mut ci = vk::PipelineLayoutCreateInfo::default().set_layouts(&res.set_layouts);
        if push_size > 0 {
            ci = ci.push_constant_ranges(&range);
        }
        // A heap pipeline has no layout (VK_NULL_HANDLE with the descriptor-heap flag).
        let layout = match bound {
            Bound::Heap(_) => vk::PipelineLayout::null(),
            Bound::Sets | Bound::Buffers(_) => {
                unsafe { gpu.device.create_pipeline_layout(&ci, None) }
                    .at("vkCreatePipelineLayout")?
            }
        };
        let spec = setup.spec;
        Ok(Harness {
            gpu,
            submitter,
            scene,
            res,
            layout,
            push_size,
            push_ints,
            timeout,
            bound,
            spec,
            fills,
            record,
            scene_buffers,
            geometries,
            procedural,
            scene_textures,
        })
    }

    pub fn device_name(&self) -> String {
        self.gpu.info.label()
    }

    /// The SPIR-V, stage flags and entry names of `modules`, plus the reporting-nothing
    /// intersection shader when they have none; and the index of the intersection shader.
    fn stage_sources(modules: &[&UserModule], g: &Groups) -> Result<Sources, HarnessError> {
        let mut spirv: Vec<Vec<u32>> = modules.iter().map(|m| m.words.clone()).collect();
        let mut flags: Vec<vk::ShaderStageFlags> =
            modules.iter().map(|m| stage_flag(&m.iface.stage)).collect();
        let mut names: Vec<CString> = modules
            .iter()
            .map(|m| CString::new(m.iface.entry.clone()).unwrap_or_default())
            .collect();
        let given = g.types.iter().find_map(|t| t.intersection);
        if let (Some(i), true) = (given, g.types.iter().all(|t| t.intersection.is_some())) {
            return Ok((spirv, flags, names, i));
        }
        let unsupported =
            |e: crate::shadergen::compile::CompileError| HarnessError::Unsupported(e.to_string());
        let mut c = crate::shadergen::compile::Compiler::new().map_err(unsupported)?;
        spirv.push(
            c.compile_glsl(shaderc::ShaderKind::Intersection, "harness.rint", NO_INTERSECTION)
                .map_err(unsupported)?,
        );
        flags.push(vk::ShaderStageFlags::INTERSECTION_KHR);
        names.push(CString::new("main").expect("no NUL"));
        let i = spirv.len() - 1;
        Ok((spirv, flags, names, i))
    }

    /// The RT pipeline of `modules`.
    fn pipeline(&self, modules: &[&UserModule]) -> Result<Pipeline, HarnessError> {
        let g = groups(modules)?;
        let (spirv, flags, names, intersection) = Self::stage_sources(modules, &g)?;
        let words: Vec<&[u32]> = spirv.iter().map(|w| w.as_slice()).collect();
        let shader_modules = pipeline::shader_modules(&self.gpu, &words)?;
        // Each given stage's specialization (the supplied intersection shader has none).
        let specs: Vec<_> = (0..shader_modules.len())
            .map(|i| modules.get(i).map(|m| spec::stage_info(m, &self.spec)))
            .collect();
        let infos: Vec<Option<vk::SpecializationInfo>> = specs
            .iter()
            .map(|s| {
                s.as_ref()
                    .filter(|(e, _)| !e.is_empty())
                    .map(|(e, d)| vk::SpecializationInfo::default().map_entries(e).data(d))
            })
            .collect();
        let stages: Vec<vk::PipelineShaderStageCreateInfo> = shader_modules
            .iter()
            .zip(&flags)
            .zip(&names)
            .zip(&infos)
            .map(|(((m, f), n), info)| {
                let mut st =
                    vk::PipelineShaderStageCreateInfo::default().stage(*f).module(*m).name(n);
                if let Some(info) = info {
                    st = st.specialization_info(info);
                }
                match &self.bound {
                    Bound::Heap(h) => st.p_next = h.mapping.stage_next(),
                    Bound::Sets | Bound::Buffers(_) => {}
                }
                st
            })
            .collect();
        let table = hit_table::layout(modules, g.types.len() as u32, self.geometries)?;
        if table.procedural != self.procedural {
            return Err(HarnessError::Unsupported(format!("this variant's rays need the sphere instances' SBT offset at {}, the unpatched pipeline's at {}: a patch must not change the rays' SBT offsets or strides", table.procedural, self.procedural)));
        }
        let groups = shader_groups(&g, &table, intersection);
        let max = self.gpu.info.properties.rt_pipeline.map_or(1, |p| p.max_ray_recursion_depth);
        let depth = traces::recursion_depth(modules, max)?;
        let counts = SbtCounts {
            miss: g.misses.len() as u32,
            hit: table.records.len() as u32,
            callable: g.callables.len() as u32,
        };
        let p = RtPipeline { stages: &stages, groups: &groups, counts, depth, layout: self.layout };
        let mut f2 = match &self.bound {
            Bound::Heap(_) => Some(
                vk::PipelineCreateFlags2CreateInfoKHR::default()
                    .flags(pipeline::flags2(DescriptorModel::DescriptorIndexing, true)),
            ),
            Bound::Sets | Bound::Buffers(_) => None,
        };
        let flags = match &self.bound {
            Bound::Buffers(_) => vk::PipelineCreateFlags::DESCRIPTOR_BUFFER_EXT,
            Bound::Sets | Bound::Heap(_) => vk::PipelineCreateFlags::empty(),
        };
        let r = pipeline::create_rt_pipeline(
            &self.gpu,
            vk::PipelineCache::null(),
            &p,
            flags,
            f2.as_mut(),
            &|_| self.record.as_slice(),
        );
        for m in &shader_modules {
            unsafe { self.gpu.device.destroy_shader_module(*m, None) };
        }
        Ok(r?)
    }

    /// The push-constant bytes: floats `0.5 + w / 4` for word `w`, small integers in the words a
    /// module's block reads as integers (a material index: [`ints`]), the sink's address in its
    /// 64-bit integers and pointers, `--fill push.OFFSET`'s bytes over them, then each contract
    /// address.
    fn push_bytes(&self, addresses: &[(u32, u64)]) -> Vec<u8> {
        let mut p: Vec<u8> = (0..self.push_size / 4)
            .flat_map(|w| match self.push_ints.at(4 * w) {
                ints::Fill::Float => (0.5 + w as f32 / 4.0).to_le_bytes(),
                fill => resources::word(0, w, fill, self.res.sink.address),
            })
            .collect();
        self.fills.overlay(false, &mut p);
        for (off, a) in addresses {
            p[*off as usize..*off as usize + 8].copy_from_slice(&a.to_le_bytes());
        }
        p
    }

    /// Trace `modules` (fed as `contract` says, when given) and read back every storage image.
    pub fn trace(
        &self,
        modules: &[&UserModule],
        contract: Option<&HostContract>,
    ) -> Result<Vec<Part>, HarnessError> {
        let pipeline = self.pipeline(modules)?;
        self.res.refill();
        let (addresses, tables) = match contract {
            Some(c) => self.res.contract_addresses(&self.gpu, c)?,
            None => (Vec::new(), Vec::new()),
        };
        let push = self.push_bytes(&addresses);
        let images: Vec<(String, &crate::vk::memory::Image, u32)> = self
            .res
            .bindings
            .iter()
            .flat_map(|((set, binding), (b, elems))| {
                elems.iter().enumerate().filter_map(move |(k, e)| match (e, b.kind) {
                    (Element::Image(i), BindingKind::StorageImage(f)) => Some((
                        format!("set {set} binding {binding}[{k}]"),
                        i,
                        resources::format(f).map_or(4, |x| x.1),
                    )),
                    _ => None,
                })
            })
            .collect();
        let readback: Vec<Buffer> = images
            .iter()
            .map(|(_, _, t)| {
                Buffer::new(
                    &self.gpu,
                    (SIZE * SIZE * t) as u64,
                    vk::BufferUsageFlags::TRANSFER_DST,
                    Location::Host,
                    "readback",
                )
            })
            .collect::<Result<_, _>>()?;
        let waited = self.submitter.run(&self.gpu, self.timeout, |cmd| {
            self.record(cmd, &pipeline, &push, &images, &readback)
        });
        let result = match waited {
            Ok(Waited::Done(_)) => Ok(images
                .iter()
                .zip(&readback)
                .map(|((label, _, t), b)| Part {
                    label: label.clone(),
                    kind: PartKind::Image,
                    bytes: b.read((SIZE * SIZE * t) as usize),
                    texel: *t,
                    initial: None,
                    scheduled: false,
                    records: None,
                })
                .chain(self.written_buffers())
                .collect()),
            Ok(Waited::TimedOut) => Err(HarnessError::Timeout(self.timeout)),
            Err(e) => Err(e.into()),
        };
        if result.is_ok() {
            pipeline.destroy(&self.gpu);
            for b in readback.iter().chain(&tables) {
                b.destroy(&self.gpu);
            }
        }
        result
    }

    /// Every element of every writable storage buffer, as the trace left it, with the data it
    /// held before (numbered over every buffer element as [`Resources::refill`] numbers them).
    /// The sink's address reads as `resources::SINK_MARK` in them: each child makes its own sink.
    fn written_buffers(&self) -> Vec<Part> {
        let sink = self.res.sink.address;
        let mut out = Vec::new();
        let mut d = 0;
        for ((set, binding), (b, elems)) in &self.res.bindings {
            let (BindingKind::StorageBuffer(size) | BindingKind::UniformBuffer(size)) = b.kind
            else {
                continue;
            };
            for (k, e) in elems.iter().enumerate() {
                if let (Element::Buffer(buf), true) = (e, b.writable) {
                    out.push(Part {
                        label: format!("storage buffer set {set} binding {binding}[{k}]"),
                        kind: PartKind::Buffer,
                        bytes: resources::mask_sink(buf.read(size as usize), sink),
                        texel: 4,
                        initial: Some(resources::mask_sink(
                            self.res.element_data(d, (*set, *binding), k as u32, b),
                            sink,
                        )),
                        scheduled: b.atomic,
                        records: b.records,
                    });
                }
                d += 1;
            }
        }
        out
    }

    /// Bind the descriptors as the model says, and push `push`.
    unsafe fn bind(&self, cmd: vk::CommandBuffer, push: &[u8]) {
        let (gpu, d) = (&self.gpu, &self.gpu.device);
        match &self.bound {
            Bound::Heap(h) => {
                h.heaps.bind(gpu, cmd);
                if !push.is_empty() {
                    h.heaps.push(gpu, cmd, push);
                }
            }
            Bound::Buffers(b) => {
                b.bind(gpu, cmd, self.layout);
                if !push.is_empty() {
                    d.cmd_push_constants(cmd, self.layout, resources::rt_stages(), 0, push);
                }
            }
            Bound::Sets => {
                if !self.res.sets.is_empty() {
                    d.cmd_bind_descriptor_sets(
                        cmd,
                        vk::PipelineBindPoint::RAY_TRACING_KHR,
                        self.layout,
                        0,
                        &self.res.sets,
                        &[],
                    );
                }
                if !push.is_empty() {
                    d.cmd_push_constants(cmd, self.layout, resources::rt_stages(), 0, push);
                }
            }
        }
    }

    /// Clear the images, trace, copy the images out.
    fn record(
        &self,
        cmd: vk::CommandBuffer,
        p: &Pipeline,
        push: &[u8],
        images: &[(String, &crate::vk::memory::Image, u32)],
        readback: &[Buffer],
    ) {
        let (gpu, d) = (&self.gpu, &self.gpu.device);
        for (_, i, _) in images {
            let t = Transition {
                from: (
                    vk::ImageLayout::UNDEFINED,
                    vk::AccessFlags::empty(),
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                ),
                to: (
                    vk::ImageLayout::GENERAL,
                    vk::AccessFlags::TRANSFER_WRITE,
                    vk::PipelineStageFlags::TRANSFER,
                ),
            };
            transition(gpu, cmd, i.raw, t);
            unsafe {
                d.cmd_clear_color_image(
                    cmd,
                    i.raw,
                    vk::ImageLayout::GENERAL,
                    &vk::ClearColorValue::default(),
                    &[color_range()],
                )
            };
        }
        full_barrier(gpu, cmd);
        let rt = gpu.rt.as_ref().expect("ray tracing pipeline enabled");
        let sbt = p.sbt.as_ref().expect("RT pipelines have an SBT");
        unsafe {
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::RAY_TRACING_KHR, p.raw);
            self.bind(cmd, push);
            rt.cmd_trace_rays(cmd, &sbt.raygen, &sbt.miss, &sbt.hit, &sbt.callable, SIZE, SIZE, 1);
        }
        full_barrier(gpu, cmd);
        for ((_, i, _), b) in images.iter().zip(readback) {
            let region = vk::BufferImageCopy::default()
                .image_subresource(vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: 0,
                    base_array_layer: 0,
                    layer_count: 1,
                })
                .image_extent(vk::Extent3D { width: SIZE, height: SIZE, depth: 1 });
            unsafe {
                d.cmd_copy_image_to_buffer(cmd, i.raw, vk::ImageLayout::GENERAL, b.raw, &[region])
            };
        }
        full_barrier(gpu, cmd);
    }
}

impl Drop for Harness {
    fn drop(&mut self) {
        unsafe { self.gpu.device.device_wait_idle().ok() };
        match &self.bound {
            Bound::Heap(h) => h.destroy(&self.gpu),
            Bound::Buffers(b) => b.destroy(&self.gpu),
            Bound::Sets => {}
        }
        self.res.destroy(&self.gpu);
        if let Some(b) = &self.scene_buffers {
            b.destroy(&self.gpu);
        }
        if let Some(t) = &self.scene_textures {
            t.destroy(&self.gpu);
        }
        self.scene.destroy(&self.gpu);
        unsafe { self.gpu.device.destroy_pipeline_layout(self.layout, None) };
        self.submitter.destroy(&self.gpu);
    }
}

fn stage_flag(stage: &str) -> vk::ShaderStageFlags {
    match stage {
        "raygen" => vk::ShaderStageFlags::RAYGEN_KHR,
        "miss" => vk::ShaderStageFlags::MISS_KHR,
        "closest_hit" => vk::ShaderStageFlags::CLOSEST_HIT_KHR,
        "any_hit" => vk::ShaderStageFlags::ANY_HIT_KHR,
        "intersection" => vk::ShaderStageFlags::INTERSECTION_KHR,
        _ => vk::ShaderStageFlags::CALLABLE_KHR,
    }
}

/// The unpatched pipeline `before` and the patched one `after` (fed as `contract` says) on the
/// device, their images and writable buffers compared.
pub fn verify(
    gpu: Gpu,
    before: &[UserModule],
    after: &[UserModule],
    contract: &HostContract,
) -> Result<(String, Vec<Compared>), HarnessError> {
    verify_with(gpu, before, after, contract, TIMEOUT, &mut |_| {})
}

/// [`verify`] with a fence deadline of `timeout` per submission, telling `step` each step
/// before taking it (`scene`, `trace unpatched`, `trace unpatched again`, `trace patched`).
pub fn verify_with(
    gpu: Gpu,
    before: &[UserModule],
    after: &[UserModule],
    contract: &HostContract,
    timeout: Duration,
    step: &mut dyn FnMut(&str),
) -> Result<(String, Vec<Compared>), HarnessError> {
    // Stages the modules lack (a closest-hit alone) supplied, the same for both pipelines.
    // The raygen's buffers at the same bindings in both: past every binding either declares.
    let at = supply::free_binding(before).max(supply::free_binding(after));
    let before = supply::supply_at(before.to_vec(), at)?;
    let after = supply::supply_at(after.to_vec(), at)?;
    let b: Vec<&UserModule> = before.iter().collect();
    let a: Vec<&UserModule> = after.iter().collect();
    let push =
        b.iter().chain(&a).map(|m| m.iface.push_end).max().unwrap_or(0).max(contract.push_end);
    step("scene");
    let h = Harness::new(gpu, &b, push, timeout, sizes::SINK_SIZE)?;
    step("trace unpatched");
    let unpatched = h.trace(&b, None)?;
    // Twice: what differs between two unpatched runs (an append queue's order) is not compared.
    step("trace unpatched again");
    let again = h.trace(&b, None)?;
    step("trace patched");
    let patched = h.trace(&a, Some(contract))?;
    Ok((h.device_name(), compare(&unpatched, &again, &patched)))
}

/// The descriptors bound for `setup`'s descriptor model: the heaps (the layout from
/// `--heap-layout` or the modules), the sets, or the descriptor buffers.
fn bind_model(
    gpu: &Gpu,
    setup: &Setup,
    modules: &[&UserModule],
    res: &Resources,
    scene: &SceneGpu,
) -> Result<Bound, HarnessError> {
    Ok(match setup.model {
        DescriptorModel::DescriptorHeap => {
            let owned: Vec<UserModule> = modules.iter().map(|m| (*m).clone()).collect();
            let arrays = match setup.heap_layout.clone() {
                Some(a) => a,
                None => heap::arrays(&owned)?,
            };
            let first = res.bindings.values().map(|(_, e)| e.len() as u32).sum::<u32>() + 1;
            let data = (first, res.sink.address);
            Bound::Heap(heap::HeapModel::new(gpu, &arrays, &res.bindings, scene, data)?)
        }
        DescriptorModel::DescriptorIndexing => Bound::Sets,
        DescriptorModel::DescriptorBuffer => {
            Bound::Buffers(buffers::DescriptorBuffers::new(gpu, &res.set_layouts, &res.bindings)?)
        }
    })
}
