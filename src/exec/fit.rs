//! Whether a cell's modules fit what its pipeline provides them, checked before the pipeline is
//! created (`interface::check`): a bundle's or a user's SPIR-V that declares another binding,
//! kind, count, push block, payload or hit attribute than the cell's layout is the cell's
//! `error`, naming what does not fit — never handed to the driver, so never a driver finding.
use super::bindings::LayoutKey;
use super::error::CellError;
use super::executor::Executor;
use super::resources::descriptor_type;
use crate::interface::{self, BindingDesc, DescriptorKind, HitGroup, PipelineDesc, PushRange};
use crate::shadergen::{CellShaders, Role};
use std::sync::Arc;

/// What a pipeline of `key` provides its modules (`shaders`, in pipeline order): the records
/// buffer (binding 0), the scene TLAS (1) and the probed array of `slots` descriptors (2; not
/// under a direct heap, whose probe reads the heap itself), each seen by the key's stages; the
/// push range of the probes' block and the patches' table address; the hit groups of
/// `pipeline::rt_groups`.
pub(super) fn pipeline_desc(
    key: LayoutKey,
    shaders: &CellShaders,
    slots: u32,
    max_hit_attribute: u32,
) -> PipelineDesc {
    let kind = |r| DescriptorKind::of_vk(descriptor_type(r)).expect("rtprobe's own kinds");
    let binding =
        |binding, kind, count| BindingDesc { set: 0, binding, kind, count, stages: key.stages };
    let mut bindings = vec![binding(0, DescriptorKind::StorageBuffer, 1)];
    if key.scene_tlas {
        bindings.push(binding(1, DescriptorKind::AccelerationStructure, 1));
    }
    if let Some(r) = key.probe.filter(|_| !key.heap_direct) {
        bindings.push(binding(2, kind(r), slots));
        if key.textures && key.per_mesh {
            // a per_mesh texture cell's mesh buffers, one per mesh slot (as many as the textures')
            let meshes = crate::scene::layout::TEXTURE_CELL_MESH_BINDING;
            bindings.push(binding(meshes, DescriptorKind::StorageBuffer, slots));
        }
    }
    let at = |role| shaders.shaders.iter().position(|s| s.role == role);
    let hit_groups = if at(Role::Raygen).is_some() {
        vec![
            HitGroup {
                closest_hit: at(Role::ClosestHitTriangles),
                any_hit: at(Role::AnyHit),
                intersection: None,
            },
            HitGroup {
                closest_hit: at(Role::ClosestHitProcedural),
                any_hit: at(Role::AnyHit),
                intersection: at(Role::Intersection),
            },
        ]
    } else {
        vec![]
    };
    PipelineDesc {
        bindings,
        push: Some(PushRange {
            offset: 0,
            size: crate::probe::PUSH_CONSTANT_BYTES,
            stages: key.stages,
        }),
        max_hit_attribute,
        hit_groups,
    }
}

impl Executor {
    /// `shaders`' modules (`spirv`) against what a pipeline of `key` provides them. Each distinct
    /// module is reflected once per executor (`interfaces`, keyed by a hash of its words): most
    /// cells share their raygen and miss, and reading a module costs more than checking it.
    /// `keys`: the modules' keys, where the prebuild's threads hashed them (`analysed`).
    pub(super) fn fit(
        &mut self,
        key: LayoutKey,
        shaders: &CellShaders,
        (spirv, keys): (&[Arc<Vec<u32>>], Option<&[u128]>),
    ) -> Result<(), CellError> {
        let slots = key.probe.map(|r| self.slots(r)).unwrap_or(0);
        let max_hit = self.gpu.info.properties.rt_pipeline.map(|p| p.max_ray_hit_attribute_size);
        let desc = pipeline_desc(key, shaders, slots, max_hit.unwrap_or(0));
        let mut read = Vec::with_capacity(spirv.len());
        for (k, w) in spirv.iter().enumerate() {
            let key = match keys.and_then(|keys| keys.get(k)) {
                Some(&key) => key,
                None => module_key(w),
            };
            let m = match self.interfaces.get(&key) {
                Some(m) => m.clone(),
                None => interface::read(k, w).map_err(CellError::Interface)?,
            };
            self.interfaces.entry(key).or_insert_with(|| m.clone());
            read.push(m);
        }
        interface::check_read(&read, &desc).map_err(CellError::Interface)
    }
}

/// The key of a module's interface in the executor's cache: its words hashed.
pub(super) fn module_key(words: &[u32]) -> u128 {
    crate::stable_hash::StableHash::default().words(words).finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Cell, HeapAccess, Resource};
    use crate::probe::spec::ProbeSpec;
    use crate::shadergen::compile::Compiler;

    /// The modules of `cell` (its workarounds applied), compiled.
    fn modules(c: &mut Compiler, cell: &Cell) -> (CellShaders, Vec<Vec<u32>>) {
        let shaders = crate::shadergen::generate_with(cell, None, false);
        let mut spirv: Vec<Vec<u32>> = shaders
            .shaders
            .iter()
            .map(|s| c.compile(s.role, &s.glsl).unwrap().0.to_vec())
            .collect();
        for w in ProbeSpec::of(cell).workarounds() {
            for words in spirv.iter_mut() {
                if let Some(p) = crate::patches::workaround::patch_module(words, w).unwrap() {
                    *words = p;
                }
            }
        }
        (shaders, spirv)
    }

    fn fits(
        cell: &Cell,
        modules: &(CellShaders, Vec<Vec<u32>>),
    ) -> Result<(), interface::Mismatch> {
        let key = super::super::bind::layout_key(&ProbeSpec::of(cell), &modules.0, false);
        let slots = crate::probe::slot_count(cell.resource, 16);
        let desc = pipeline_desc(key, &modules.0, slots, 32);
        let words: Vec<&[u32]> = modules.1.iter().map(|w| w.as_slice()).collect();
        interface::check(&words, &desc)
    }

    /// Every planned cell rtprobe compiles itself (all but the direct heap ones, which need the
    /// sid root's glslang) fits the layout its pipeline is made with. Twin (issue 21, item 7): a
    /// bundle whose SPIR-V is another cell's — a storage-buffer probe in a sampled-image cell's
    /// pipeline — does not, and the mismatch names binding 2.
    #[test]
    fn every_cell_fits_its_layout_and_another_cells_spirv_does_not() {
        let mut c = Compiler::new().unwrap();
        let (cells, _) = crate::matrix::plan::all_cells();
        let mut checked = 0;
        for cell in
            cells.iter().filter(|c| c.heap_access != Some(HeapAccess::Direct) && c.canary.is_none())
        {
            let m = modules(&mut c, cell);
            fits(cell, &m).unwrap_or_else(|e| panic!("{}: {e}", cell.id()));
            checked += 1;
        }
        assert!(checked > 1000, "{checked}");
        let ssbo = cells
            .iter()
            .find(|c| c.id() == "compute.storage_buffer.literal.descriptor_indexing")
            .unwrap();
        let image = Cell { resource: Resource::SampledImage, ..*ssbo };
        let e = fits(&image, &modules(&mut c, ssbo)).unwrap_err();
        assert!(matches!(e, interface::Mismatch::Kind { set: 0, binding: 2, .. }), "{e}");
        assert!(e.to_string().contains("set 0 binding 2: the COMPUTE shader declares a storage buffer, the pipeline provides a combined image sampler"), "{e}");
    }
}
