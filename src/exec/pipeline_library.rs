//! Ray tracing pipelines linked from pipeline libraries (VK_KHR_pipeline_library): each shader
//! group of a cell's pipeline (raygen, the two misses, the two hit groups, the callable) is a
//! library of its own, made once per identity (its stages' SPIR-V, its group, the layout, the
//! descriptor model's flags, the heap mapping, the specialization and the recursion depth) and
//! shared by every cell whose group is the same; a cell's pipeline links its groups' libraries in
//! SBT order, so the linked pipeline's group handles come in the order [`super::pipeline`]'s SBT
//! expects ("a pipeline's groups, then each library's, in the order of `pLibraries`", Vulkan
//! 1.4.363, "Ray Tracing Pipeline Libraries"). Every library and the linked pipeline share one
//! `VkRayTracingPipelineInterfaceCreateInfoKHR` and the recursion depth
//! (VUID-VkRayTracingPipelineCreateInfoKHR-pLibraries-03591). Libraries live as long as the
//! executor.
use super::pipeline::{self, Desc, Pipeline};
use crate::stable_hash::StableHash;
use crate::vk::{Gpu, VkError};
use ash::vk;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// The payload and hit-attribute bytes every library declares: the probes' `Record` payload and
/// the intersection probe's `ProbeAttr` (32 bytes, `shadergen`'s `PROBE_ATTR`: the most every
/// device allows) fit.
fn interface() -> vk::RayTracingPipelineInterfaceCreateInfoKHR<'static> {
    vk::RayTracingPipelineInterfaceCreateInfoKHR::default()
        .max_pipeline_ray_payload_size(crate::probe::RECORD_SIZE as u32)
        .max_pipeline_ray_hit_attribute_size(32)
}

/// One library slot: filled by the first thread that needs it, waited for by the others.
type Slot = Arc<Mutex<Option<vk::Pipeline>>>;

/// The group libraries made so far, by identity.
#[derive(Default)]
pub struct Libraries {
    made: Mutex<HashMap<u128, Slot>>,
}

impl Libraries {
    /// The ray tracing pipeline `d` (layout contents hashed as `layout`), linked from its groups'
    /// libraries, each made with `cache` where it does not exist yet.
    pub fn make(
        &self,
        gpu: &Gpu,
        cache: vk::PipelineCache,
        d: &Desc,
        layout: u128,
    ) -> Result<Pipeline, VkError> {
        let groups = pipeline::rt_group_stages(d.shaders);
        let mut libs = Vec::with_capacity(groups.len());
        for g in &groups {
            libs.push(self.library(gpu, cache, d, layout, g)?);
        }
        pipeline::link_rt(gpu, cache, d, &libs, &interface())
    }

    /// The library of group `g` (stage indices into `d`'s shaders), made unless it exists.
    fn library(
        &self,
        gpu: &Gpu,
        cache: vk::PipelineCache,
        d: &Desc,
        layout: u128,
        g: &pipeline::GroupStages,
    ) -> Result<vk::Pipeline, VkError> {
        let id = group_id(d, layout, g);
        let slot =
            self.made.lock().unwrap_or_else(|p| p.into_inner()).entry(id).or_default().clone();
        let mut slot = slot.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(p) = *slot {
            return Ok(p);
        }
        let p = pipeline::create_rt_library(gpu, cache, d, g, &interface())?;
        *slot = Some(p);
        Ok(p)
    }

    pub fn destroy(&self, gpu: &Gpu) {
        for slot in self.made.lock().unwrap_or_else(|p| p.into_inner()).values() {
            if let Some(p) = *slot.lock().unwrap_or_else(|p| p.into_inner()) {
                unsafe { gpu.device.destroy_pipeline(p, None) };
            }
        }
    }
}

/// A group library's identity: everything that makes it — its group and stages' SPIR-V, the
/// specialization, the recursion depth, the descriptor model's flags, the layout's contents and
/// the heap mapping structs.
fn group_id(d: &Desc, layout: u128, g: &pipeline::GroupStages) -> u128 {
    let mut h = StableHash::default();
    h.str("rt group library").u32(g.ty.as_raw() as u32);
    for &i in &g.stages {
        h.str(d.shaders.shaders[i].role.file_name()).words(&d.spirv[i]);
    }
    h.bytes(d.specialization.data());
    h.u32(d.shaders.recursion_depth).str(d.model.as_str());
    h.u64(pipeline::flags2(d.model, d.heap.is_some()).as_raw());
    h.u64(layout as u64).u64((layout >> 64) as u64);
    match d.heap {
        Some(m) => h.u32(1).words(&m.words()),
        None => h.u32(0),
    };
    h.finish()
}
