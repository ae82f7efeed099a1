//! `run`'s scene held to the plan and the device once the plan is made, before the report is
//! reserved and any GPU work: the images the planned texture cells sample decoded (only those,
//! and only when such a cell is planned, so a run filtered to geometry cells decodes none), a
//! broken one the loader's one line naming `images[N]` and its URI (exit 9, as a missing `.bin`);
//! each texture cell whose images or array exceed the device's queried limits made `unsupported`
//! with why (`scene::texture_limits`); a scene without textures makes them not run, with that
//! reason, in the plan (counted there, not found by the worker); and the device memory a `--scene` file needs — its
//! geometry and those textures — printed and held to the device's largest device-local heap
//! (exit 5, as `run --shader --scene`).
use super::exit::{self, coded};
use super::out::errln;
use crate::model::{DescriptorModel, PlanStatus, RunPlan};
use crate::probe::spec::ProbeSpec;
use crate::scene::texture_limits::{self, ImageSize, TextureLimits};
use crate::scene::textures::{element_count, ImageSource, TextureError};
use crate::scene::Scene;
use crate::vk::DeviceInfo;
use anyhow::Result;
use std::time::Instant;

/// The scene `scene` checked against `plan` (its texture cells' statuses set) and `info`.
pub fn check(scene: &Scene, plan: &mut RunPlan, info: &DeviceInfo) -> Result<()> {
    let cells: Vec<usize> = (0..plan.cells.len())
        .filter(|&i| {
            let c = &plan.cells[i];
            c.status == PlanStatus::Run
                && c.cell.scene_layout.is_some()
                && ProbeSpec::of(&c.cell).layout_textures()
        })
        .collect();
    let mut texture_bytes = 0;
    if !cells.is_empty() {
        let t = Instant::now();
        match scene.textures.sizes() {
            // Nothing to sample: no device feature is missing, so not `unsupported`; the cells
            // are counted as not run with the reason, in the plan, before any worker starts.
            Err(e @ TextureError::NoTextures) => {
                for &i in &cells {
                    plan.cells[i].status = PlanStatus::NotImplemented { reason: e.to_string() };
                }
            }
            Err(TextureError::Load(e)) => return Err(coded(exit::BAD_INPUT, e)),
            Ok(sizes) => {
                if limit_cells(scene, &sizes, (plan, &cells), info) {
                    // Within the limits: each image decoded once and dropped, so a broken body
                    // is the one-line error here, not a worker's finding.
                    scene.textures.validate().map_err(|e| coded(exit::BAD_INPUT, e))?;
                    if matches!(scene.textures.source, ImageSource::File(_)) {
                        errln!(
                            "scene: {} image{} the texture cells sample decoded in {:.0} ms",
                            sizes.len(),
                            if sizes.len() == 1 { "" } else { "s" },
                            t.elapsed().as_secs_f64() * 1e3
                        );
                    }
                    texture_bytes =
                        sizes.iter().map(|(_, w, h)| 4 * u64::from(*w) * u64::from(*h)).sum();
                }
            }
        }
    }
    fits_heap(scene, texture_bytes, info)
}

/// Each texture cell of `cells` over the device's limits (its images `sizes`) made
/// `unsupported` with why; whether any still runs.
fn limit_cells(
    scene: &Scene,
    sizes: &[(String, u32, u32)],
    (plan, cells): (&mut RunPlan, &[usize]),
    info: &DeviceInfo,
) -> bool {
    let sized: Vec<ImageSize> = sizes
        .iter()
        .map(|(name, width, height)| ImageSize { name, width: *width, height: *height })
        .collect();
    let slots =
        crate::probe::slot_count(crate::model::Resource::SampledImage, scene.params.instances);
    let elements = element_count(sizes.len(), slots) as u64;
    let uab_features = info
        .features
        .v12
        .is_some_and(|f| f.descriptor_binding_sampled_image_update_after_bind == ash::vk::TRUE);
    let mut runs = false;
    for &i in cells {
        let c = &mut plan.cells[i];
        // As `exec::bindings::layout` binds the array: update-after-bind under descriptor
        // indexing where the device allows it.
        let uab = uab_features && c.cell.descriptor_model == DescriptorModel::DescriptorIndexing;
        match texture_limits::over(&sized, elements, &TextureLimits::of(info, uab)) {
            Some(reason) => c.status = PlanStatus::Unsupported { reason },
            None => runs = true,
        }
    }
    runs
}

/// A `--scene` file's geometry (the tutorial's shared buffers) and `texture_bytes` printed and
/// held to the device's largest device-local heap; the procedural scene is not.
fn fits_heap(scene: &Scene, texture_bytes: u64, info: &DeviceInfo) -> Result<()> {
    let ImageSource::File(loaded) = &scene.textures.source else {
        return Ok(());
    };
    let geometry = loaded.geometry_bytes();
    let need = geometry + texture_bytes;
    let heap = crate::harness::scene_data::largest_device_heap(&info.memory);
    let mib = |b: u64| b.div_ceil(1 << 20);
    errln!(
        "scene: needs {} of device memory (geometry {}, textures {}), the device's largest device-local heap {} MiB",
        size(need),
        size(geometry),
        if texture_bytes == 0 { "none".into() } else { size(texture_bytes) },
        mib(heap)
    );
    if need <= heap {
        return Ok(());
    }
    Err(coded(
        exit::UNSUPPORTED_DEVICE,
        format!(
            "--scene {}: needs {} MiB of device memory, more than the device's largest device-local heap ({} MiB); give a smaller scene, or leave the texture cells out (--filter resource=storage_buffer)",
            loaded.path.display(),
            mib(need),
            mib(heap)
        ),
    ))
}

/// `b` bytes in KiB below a MiB, else in MiB.
fn size(b: u64) -> String {
    if b < 1 << 20 {
        format!("{:.1} KiB", b as f64 / 1024.0)
    } else {
        format!("{:.1} MiB", b as f64 / (1 << 20) as f64)
    }
}
