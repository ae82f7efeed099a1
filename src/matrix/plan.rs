//! From options and a device to a [`RunPlan`], before any GPU work: which cells exist, which the
//! filter keeps, which the device cannot run (and why, from its queried features), and which
//! combinations are never generated because an axis value cannot matter there.
use crate::caps::support::{self, Support};
use crate::model::{
    AsAccess, BaseSource, DescriptorModel, HeapAccess, IndexSource, Reorder, Resource,
    SamplerIndex, SceneLayout, Stage,
};
use crate::model::{
    Canary, Cell, Filter, NotGenerated, PatchMode, PlanStatus, PlannedCell, RunPlan,
};
use crate::vk::DeviceInfo;

pub struct PlanOptions {
    pub filters: Vec<Filter>,
    pub canaries: bool,
    pub patches: PatchMode,
    /// `--inject-fault`: an injected invalid-address load needs what address probes need.
    pub inject: Vec<crate::model::inject::Injection>,
}

/// Why the device cannot run `cell`, from its queried features; `None` when it can.
pub fn device_support(info: &DeviceInfo, cell: &Cell) -> Support {
    let mut checks = vec![
        support::stage(info, cell.stage),
        support::resource(info, cell.resource),
        support::descriptor_model(info, cell.descriptor_model),
    ];
    if let Some(h) = cell.heap_access {
        checks.push(support::heap_access(info, h));
        if h == HeapAccess::Direct && cell.as_access == Some(AsAccess::AddressPatched) {
            // After the device's reasons: rtprobe's gap is never reported over them.
            checks.push(Support::NotImplemented {
                reason: "as-to-address cannot rewrite heap_access=direct SPIR-V (rspirv 0.13 predates SPV_KHR_untyped_pointers)".into(),
            });
        }
    }
    if cell.index == IndexSource::Dynamic {
        checks.push(support::dynamic_index(info, cell.resource, cell.nonuniform));
    }
    // A dynamic sampler index is a dynamic index into an array of samplers (the sampled-image
    // array features cover sampler arrays).
    if cell.sampler == Some(SamplerIndex::Dynamic) {
        checks.push(support::dynamic_index(
            info,
            Resource::SampledImage,
            cell.sampler_nonuniform(),
        ));
    }
    if let Some(a) = cell.as_access {
        checks.push(support::as_access(info, a));
    }
    if let Some(r) = cell.reorder {
        checks.push(support::reorder(info, r));
    }
    if let Some(b) = cell.base {
        checks.push(support::base(info, b));
    }
    if let Some(m) = cell.mutant {
        checks.push(support::mutant(info, m, Some(cell.stage)));
    }
    if let Some(l) = cell.scene_layout {
        checks.push(support::scene_layout(info, l));
        if cell.resource == Resource::SampledImage {
            // every texture cell reads its material table through the SceneDesc's address
            checks.push(support::scene_layout(info, SceneLayout::SharedBuffers));
        }
    }
    if matches!(
        cell.patch,
        Some(crate::model::Workaround::AsToAddress | crate::model::Workaround::SsboToAddress)
    ) {
        checks.push(support::as_access(info, AsAccess::Address));
    }
    if cell.resource == Resource::AccelerationStructure {
        if !cell.stage.can_trace_ray()
            && info.features.ray_query.is_none_or(|r| r.ray_query != ash::vk::TRUE)
        {
            checks.push(Support::Unsupported {
                reason: format!(
                    "device lacks rayQuery (VK_KHR_ray_query), which a {} shader needs to trace",
                    cell.stage
                ),
            });
        }
        let depth = info.properties.rt_pipeline.map(|p| p.max_ray_recursion_depth).unwrap_or(0);
        if matches!(cell.stage, Stage::ClosestHit | Stage::Miss) && depth < 2 {
            checks.push(Support::Unsupported {
                reason: format!(
                    "maxRayRecursionDepth is {depth}; tracing from {} needs 2",
                    cell.stage
                ),
            });
        }
    }
    Support::all(checks)
}

/// How many combinations each rule of [`all_cells`] kept out of the matrix.
#[derive(Default)]
struct Skipped {
    nonuniform_static: usize,
    nonuniform_address: usize,
    reorder_elsewhere: usize,
    record_outside_rt: usize,
    heap_index_without_binding: usize,
    packed_elsewhere: usize,
    base_elsewhere: usize,
    sampler_elsewhere: usize,
    layout_elsewhere: usize,
}

impl Skipped {
    fn not_generated(&self) -> Vec<NotGenerated> {
        vec![
            NotGenerated { rule: "nonuniform only applies to index=dynamic".into(), count: self.nonuniform_static },
            NotGenerated { rule: "nonuniform has no descriptor to qualify with as_access=address".into(), count: self.nonuniform_address },
            NotGenerated { rule: "index=dynamic_element is the recommended pattern of storage buffers (geometry) and sampled images (materials) only".into(), count: self.packed_elsewhere },
            NotGenerated { rule: "reorder only applies to stage=closest_hit with index=dynamic (push-data base, set-based models)".into(), count: self.reorder_elsewhere },
            NotGenerated {
                rule: "base=shader_record|buffer only applies to stage=closest_hit with index=dynamic|dynamic_element into buffers and images, without reorder (the original fault's shape)".into(),
                count: self.base_elsewhere,
            },
            NotGenerated {
                rule: "sampler=constant|dynamic only applies to heap_access=direct sampled images (set/binding shaders sample combined image samplers)".into(),
                count: self.sampler_elsewhere,
            },
            NotGenerated {
                rule: "scene_layout only applies to stage=closest_hit index=dynamic cells of set-based models without base or reorder: storage_buffer ones, per_mesh with nonuniform (without it the descriptor read is undefined), shared_buffers without (it indexes no descriptor); sampled_image ones with nonuniform in both layouts, with the scene's textures in a descriptor array".into(),
                count: self.layout_elsewhere,
            },
            NotGenerated { rule: "heap_access=mapped_shader_record_index needs a shader record (ray tracing pipelines only)".into(), count: self.record_outside_rt },
            NotGenerated {
                rule: "heap_access=mapped_push_index|mapped_indirect_index|mapped_shader_record_index only move the probed binding, which as_access=address has not".into(),
                count: self.heap_index_without_binding,
            },
        ]
    }
}

/// Every cell of the full matrix in plan order, with the rules that kept others out.
pub fn all_cells() -> (Vec<Cell>, Vec<NotGenerated>) {
    let mut cells = Vec::new();
    let mut skipped = Skipped::default();
    for &stage in Stage::ALL {
        for &resource in Resource::ALL {
            let accesses: Vec<Option<AsAccess>> = if resource == Resource::AccelerationStructure {
                AsAccess::ALL.iter().map(|a| Some(*a)).collect()
            } else {
                vec![None]
            };
            for &index in IndexSource::ALL {
                for nonuniform in [false, true] {
                    for &as_access in &accesses {
                        for &descriptor_model in DescriptorModel::ALL {
                            if nonuniform && index != IndexSource::Dynamic {
                                skipped.nonuniform_static += 1;
                                continue;
                            }
                            if nonuniform && as_access == Some(AsAccess::Address) {
                                skipped.nonuniform_address += 1;
                                continue;
                            }
                            if index == IndexSource::DynamicElement
                                && !Cell::dynamic_element_applies(resource)
                            {
                                skipped.packed_elsewhere += 1;
                                continue;
                            }
                            let base = Cell {
                                nonuniform,
                                as_access,
                                ..Cell::new(stage, resource, index, descriptor_model)
                            };
                            heap_cells(base, &mut cells, &mut skipped);
                        }
                    }
                }
            }
        }
    }
    (cells, skipped.not_generated())
}

/// The cells of `base` (its stage, resource, index, nonuniform, AS access and descriptor model
/// set): one per heap access its model has, each with its samplers, reorders and bases.
fn heap_cells(base: Cell, cells: &mut Vec<Cell>, skipped: &mut Skipped) {
    let heap: Vec<Option<HeapAccess>> = if base.descriptor_model == DescriptorModel::DescriptorHeap
    {
        HeapAccess::ALL.iter().map(|h| Some(*h)).collect()
    } else {
        vec![None]
    };
    for heap_access in heap {
        let mapped_index = matches!(
            heap_access,
            Some(
                HeapAccess::MappedPushIndex
                    | HeapAccess::MappedIndirectIndex
                    | HeapAccess::MappedShaderRecordIndex
            )
        );
        if heap_access == Some(HeapAccess::MappedShaderRecordIndex) && !base.stage.is_ray_tracing()
        {
            skipped.record_outside_rt += 1;
            continue;
        }
        if mapped_index && base.as_access == Some(AsAccess::Address) {
            skipped.heap_index_without_binding += 1;
            continue;
        }
        let cell = Cell { heap_access, ..base };
        let samplers: Vec<Option<SamplerIndex>> = if cell.sampler_applies() {
            SamplerIndex::ALL.iter().map(|s| Some(*s)).collect()
        } else {
            skipped.sampler_elsewhere += SamplerIndex::ALL.len();
            vec![None]
        };
        for sampler in samplers {
            let cell = Cell { sampler, ..cell };
            cells.push(cell);
            if cell.reorder_applies() {
                cells.extend(Reorder::ALL.iter().map(|r| Cell { reorder: Some(*r), ..cell }));
            } else {
                skipped.reorder_elsewhere += Reorder::ALL.len();
            }
            if cell.base_applies() {
                cells.extend(BaseSource::ALL.iter().map(|b| Cell { base: Some(*b), ..cell }));
            } else {
                skipped.base_elsewhere += BaseSource::ALL.len();
            }
            let layouts = cell.planned_layouts();
            cells.extend(layouts.iter().map(|l| Cell { scene_layout: Some(*l), ..cell }));
            skipped.layout_elsewhere += SceneLayout::ALL.len() - layouts.len();
        }
    }
}

pub fn plan(info: &DeviceInfo, opts: &PlanOptions) -> RunPlan {
    let (all, not_generated) = all_cells();
    let generated = all.len();
    let mut cells = Vec::new();
    let mut filtered_out = 0;
    // Every planned cell stays in the plan: what the device cannot run is `unsupported`, what
    // rtprobe itself cannot run yet is `not_implemented`, both with their reason.
    let push = |cell: Cell, cells: &mut Vec<PlannedCell>| {
        let mut support = device_support(info, &cell);
        if crate::model::inject::for_cell(&opts.inject, &cell)
            .is_some_and(|i| i.fault.reads_bad_address())
        {
            support = Support::all(vec![support, support::device_address_loads(info)]);
        }
        let status = match support {
            Support::Supported => PlanStatus::Run,
            Support::Unsupported { reason } => PlanStatus::Unsupported { reason },
            Support::NotImplemented { reason } => PlanStatus::NotImplemented { reason },
        };
        cells.push(PlannedCell { cell, status });
    };
    for cell in all {
        let variants = std::iter::once(cell).chain(
            if opts.patches == PatchMode::All {
                cell.applicable_patches()
            } else {
                Default::default()
            }
            .into_iter()
            .map(move |p| Cell { patch: Some(p), ..cell }),
        );
        for cell in variants {
            if opts.filters.iter().all(|f| f.matches(&cell)) {
                push(cell, &mut cells);
            } else {
                filtered_out += 1;
            }
        }
    }
    // Canaries last: on a real GPU a canary may wedge the device for every process after it
    // (seen on NVIDIA 580: the invalid read hung instead of faulting), so no probe cell may
    // run after one.
    if opts.canaries {
        for &c in Canary::ALL {
            push(Cell::canary(c), &mut cells);
        }
    }
    RunPlan { generated, cells, not_generated, filtered_out }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrix_has_no_meaningless_cells_and_unique_ids() {
        let (cells, skipped) = all_cells();
        assert!(cells.iter().all(|c| !c.nonuniform || c.index == IndexSource::Dynamic));
        assert!(cells
            .iter()
            .all(|c| c.as_access.is_some() == (c.resource == Resource::AccelerationStructure)));
        let mut ids: Vec<String> = cells.iter().map(|c| c.id()).collect();
        let n = ids.len();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), n, "cell ids are unique");
        // 8 stages x (4 resources x 5 index variants + AS: 5 descriptor + 4 address + 5 patched) x
        // 2 set-based models, plus the heap model once per heap access way (5 in RT stages, 4 in
        // fragment/compute; as_access=address only mapped_constant_offset and direct).
        // Each closest-hit cell with a dynamic index of a set-based model (4 x 2 + AS 2 + 1 + 2, x 2
        // models) again with each reorder value.
        let per_stage_heap = |ways: usize| (4 * 5 + 10) * ways + 4 * 2;
        let dynamic_closest_hit = (4 * 2 + 5) * 2;
        // index=dynamic_element: storage buffers and sampled images, per model and heap access way.
        let packed = |ways: usize| 2 * (2 + ways);
        // sampler: every direct sampled-image cell (5 index variants + dynamic_element per stage)
        // twice, constant and dynamic.
        let sampler_extra = 8 * 6;
        // base: closest-hit dynamic (x nonuniform) and dynamic_element cells of buffers and images
        // (4 x 2 + 2) in 2 set-based models and 5 heap ways, plus the direct sampled ones' second
        // sampler value (3), again with each of the 2 non-default bases.
        let base_extra = 2 * ((4 * 2 + 2) * 7 + 3);
        // scene_layout: closest-hit dynamic storage-buffer cells of the 2 set-based models, one
        // layout each (per_mesh with nonuniform, shared_buffers without), and the nonuniform
        // sampled-image ones (the texture cells) in both layouts.
        let layouts = 2 * 2 + 2 * 2;
        assert_eq!(
            n,
            8 * (4 * 5 + 14) * 2
                + 6 * per_stage_heap(5)
                + 2 * per_stage_heap(4)
                + dynamic_closest_hit * 2
                + 6 * packed(5)
                + 2 * packed(4)
                + sampler_extra
                + base_extra
                + layouts
        );
        assert!(cells.iter().all(|c| c.sampler.is_some() == c.sampler_applies()));
        assert!(cells.iter().all(|c| c.base.is_none() || c.base_applies()));
        // Every base_applies cell has both other bases; reorder never combines with a base.
        for c in cells.iter().filter(|c| c.base.is_none() && c.base_applies()) {
            for b in BaseSource::ALL {
                assert!(
                    cells.contains(&Cell { base: Some(*b), ..*c }),
                    "{} without base {b}",
                    c.id()
                );
            }
        }
        assert!(cells.iter().filter(|c| c.index == IndexSource::DynamicElement).all(|c| {
            Cell::dynamic_element_applies(c.resource)
                && !c.nonuniform
                && c.applicable_patches().is_empty()
        }));
        // Every dynamic storage-buffer / sampled-image cell has its recommended pattern in the
        // matrix (a scene-layout cell is an engine's layout itself: its alternative is the other).
        for c in cells.iter().filter(|c| {
            c.index == IndexSource::Dynamic
                && Cell::dynamic_element_applies(c.resource)
                && c.scene_layout.is_none()
        }) {
            let (_, r) = c.recommended_pattern().unwrap();
            assert!(cells.contains(&r), "{} -> {}", c.id(), r.id());
        }
        assert!(cells
            .iter()
            .all(|c| c.heap_access.is_some()
                == (c.descriptor_model == DescriptorModel::DescriptorHeap)));
        assert!(cells.iter().all(|c| c.reorder.is_none() || c.reorder_applies()));
        assert!(skipped.iter().all(|s| s.count > 0));
    }

    #[test]
    fn filters_parse_and_match() {
        let f = Filter::parse("stage=closest_hit|raygen,index=dynamic").unwrap();
        let (cells, _) = all_cells();
        let kept: Vec<_> = cells.iter().filter(|c| f.matches(c)).collect();
        assert!(!kept.is_empty());
        assert!(kept.iter().all(|c| matches!(c.stage, Stage::ClosestHit | Stage::Raygen)
            && c.index == IndexSource::Dynamic));
        assert!(Filter::parse("stage=nope").unwrap_err().to_string().contains("closest_hit"));
        assert!(Filter::parse("colour=red").unwrap_err().to_string().contains("unknown axis"));
        assert!(Filter::parse("stage").is_err());
    }

    /// Every planned cell, its workaround variants, its mutants (`--mutants`: those with a site
    /// in its probe) and the canaries.
    fn every_cell() -> Vec<Cell> {
        let (cells, _) = all_cells();
        let variants = cells.iter().flat_map(|c| {
            c.applicable_patches().into_iter().map(move |p| Cell { patch: Some(p), ..*c })
        });
        let mutants = cells.iter().flat_map(|c| {
            let spec = crate::probe::spec::ProbeSpec::of(c);
            crate::model::Mutant::ALL
                .iter()
                .filter(move |m| crate::mutants::site(&spec, **m, 20).is_ok())
                .map(move |m| Cell { mutant: Some(*m), ..*c })
        });
        let canaries = Canary::ALL.iter().map(|k| Cell::canary(*k));
        cells.iter().copied().chain(variants).chain(mutants).chain(canaries).collect()
    }

    /// Every shader the plan generates (each cell, its workaround variants, the canaries)
    /// compiles with the linked shaderc and, after the cell's workaround patches, passes
    /// spirv-val (when installed): the system shaderc (glslang 12) and the bundled one alike.
    /// Sources for the external glslangValidator (heap `direct`) are compiled by the heap tests
    /// in the sid root.
    #[test]
    fn every_generated_shader_compiles_and_validates() {
        use crate::shadergen::{self, compile};
        let mut sources = std::collections::BTreeMap::new();
        let mut variants = std::collections::BTreeSet::new();
        for c in every_cell() {
            let workarounds = crate::patches::workaround::of_cell(&c);
            for s in shadergen::generate(&c).shaders {
                if compile::uses_external(&s.glsl) {
                    continue;
                }
                let key = compile::source_hash(s.role, &s.glsl);
                variants.insert((key, workarounds.clone()));
                sources.entry(key).or_insert((s.role, s.glsl, c.id()));
            }
        }
        let mut compiler = compile::Compiler::new().unwrap();
        let list: Vec<_> = sources.values().map(|(r, g, _)| (*r, g.as_str())).collect();
        compiler.precompile(&list, 2, &|_, _| {});
        let mut modules = Vec::new();
        for (key, workarounds) in &variants {
            let (role, glsl, id) = &sources[key];
            let (words, _) = compiler
                .compile(*role, glsl)
                .unwrap_or_else(|e| panic!("{id} {role:?}: {e}\n{glsl}"));
            let mut words = words.to_vec();
            for w in workarounds {
                if let Some(p) = crate::patches::workaround::patch_module(&words, *w)
                    .unwrap_or_else(|e| panic!("{id} {role:?} {w:?}: {e}"))
                {
                    words = p;
                }
            }
            modules.push((id.clone(), *role, words));
        }
        modules.sort_by(|a, b| a.2.cmp(&b.2));
        modules.dedup_by(|a, b| a.2 == b.2);
        let failures: Vec<String> = crate::pool::map(
            modules.len(),
            2,
            || Some(()),
            |_, i| match crate::patches::validate(&modules[i].2) {
                crate::patches::Validation::Invalid(m) => {
                    Some(format!("{} {:?}: {m}", modules[i].0, modules[i].1))
                }
                _ => None,
            },
            &|_, _| {},
        )
        .into_iter()
        .flatten()
        .flatten()
        .collect();
        assert!(sources.len() > 100, "{} sources", sources.len());
        assert_eq!(failures, Vec::<String>::new(), "{} modules", modules.len());
    }

    #[test]
    fn the_plan_filters_ids_and_sentences_cover_every_registry_value() {
        use crate::model::registry::{self, AXES};
        let all = every_cell();
        let known: std::collections::HashSet<Cell> = all.iter().copied().collect();
        assert_eq!(uncovered(&all), Vec::<String>::new());
        for c in &all {
            assert_eq!(Cell::parse_id(&c.id()).as_ref(), Ok(c), "{}", c.id());
            // A cell that differs in one axis reads differently in an isolation line.
            for a in AXES {
                for v in a.values {
                    let mut d = *c;
                    if (a.set)(&mut d, v) && d != *c && known.contains(&d) {
                        assert_ne!(
                            registry::describe(c),
                            registry::describe(&d),
                            "{} vs {}",
                            c.id(),
                            d.id()
                        );
                    }
                }
            }
        }
        // The report's cell fields are the registry's axes.
        let keys: std::collections::BTreeSet<String> = all
            .iter()
            .flat_map(|c| {
                serde_json::to_value(c)
                    .unwrap()
                    .as_object()
                    .unwrap()
                    .keys()
                    .cloned()
                    .collect::<Vec<_>>()
            })
            .collect();
        assert_eq!(keys, registry::names().map(String::from).collect());
    }

    /// `axis=value` of every registry value no cell holds (its filter selects nothing).
    fn uncovered(all: &[Cell]) -> Vec<String> {
        let mut out = Vec::new();
        for a in crate::model::registry::AXES {
            for v in a.filter_values() {
                let f =
                    Filter::parse(&format!("{}={v}", a.name)).expect("a registry value filters");
                if !all.iter().any(|c| f.matches(c)) {
                    out.push(format!("{}={v}", a.name));
                }
            }
        }
        out
    }

    #[test]
    fn a_value_the_plan_never_makes_is_caught() {
        let all: Vec<Cell> = every_cell()
            .into_iter()
            .filter(|c| {
                c.sampler != Some(SamplerIndex::Dynamic)
                    && c.patch != Some(crate::model::Workaround::PinIndex)
            })
            .collect();
        assert_eq!(uncovered(&all), ["patch=pin-index", "sampler=dynamic"]);
    }
}
