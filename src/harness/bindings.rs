//! The pipeline's bindings, one per set and binding ([`merged`]): the same binding declared by
//! several modules, or by several blocks of one module (aliased storage or uniform blocks at one
//! binding, as bindless engines declare `buffer Floats {vec4 v[];}` and `buffer Words {uint
//! u[];}` at one set/binding), is one binding: of the largest buffer size, the largest array
//! count, every declaration's integer and address words (`ints::IntWords::merge`), writable or
//! atomic when any declaration is; a texture or a sampler at a combined image sampler's binding is
//! that combined image sampler. Kinds that cannot share one descriptor (a storage buffer and
//! a uniform buffer, an image and a buffer, two image formats) are refused with an error naming
//! the binding, before any device work (`run::check_pipeline`).
use super::error::HarnessError;
use super::module::UserModule;
use super::reflect::{Binding, BindingKind};
use std::collections::BTreeMap;

/// The kind both `a` and `b` can be bound as, or `None` when no one descriptor serves both.
fn common_kind(a: BindingKind, b: BindingKind) -> Option<BindingKind> {
    use BindingKind::*;
    match (a, b) {
        (StorageBuffer(x), StorageBuffer(y)) => Some(StorageBuffer(x.max(y))),
        (UniformBuffer(x), UniformBuffer(y)) => Some(UniformBuffer(x.max(y))),
        (AccelerationStructure, AccelerationStructure) => Some(AccelerationStructure),
        (StorageImage(f), StorageImage(g)) if f == g => Some(a),
        (SampledImage, SampledImage) => Some(SampledImage),
        (Sampler, Sampler) => Some(Sampler),
        // A combined image sampler serves a texture or a sampler declared at its binding.
        (CombinedImageSampler, CombinedImageSampler | SampledImage | Sampler)
        | (SampledImage | Sampler, CombinedImageSampler) => Some(CombinedImageSampler),
        (
            StorageBuffer(_)
            | UniformBuffer(_)
            | AccelerationStructure
            | StorageImage(_)
            | SampledImage
            | Sampler
            | CombinedImageSampler,
            _,
        ) => None,
    }
}

/// Every binding of `bindings` once, aliases merged, keyed by set and binding.
pub fn merged(bindings: &[Binding]) -> Result<BTreeMap<(u32, u32), Binding>, HarnessError> {
    let mut unique: BTreeMap<(u32, u32), Binding> = BTreeMap::new();
    for b in bindings {
        let Some(old) = unique.get_mut(&(b.set, b.binding)) else {
            unique.insert((b.set, b.binding), b.clone());
            continue;
        };
        old.kind = common_kind(old.kind, b.kind).ok_or_else(|| {
            HarnessError::Interface(format!(
                "set {} binding {} is declared as {} and as {}: one descriptor cannot be both; \
                 give each its own binding",
                b.set,
                b.binding,
                describe(old.kind),
                describe(b.kind)
            ))
        })?;
        old.count = old.count.max(b.count);
        old.runtime |= b.runtime;
        // Written by any module: compared after the trace.
        old.writable |= b.writable;
        old.atomic |= b.atomic;
        old.records = old.records.or(b.records);
        old.ints.merge(&b.ints);
    }
    Ok(unique)
}

/// Whether the harness can bind every declaration of `modules` (see [`merged`]).
pub fn check(modules: &[UserModule]) -> Result<(), HarnessError> {
    let all: Vec<Binding> = modules.iter().flat_map(|m| m.iface.bindings.iter().cloned()).collect();
    merged(&all).map(|_| ())
}

fn describe(k: BindingKind) -> String {
    match k {
        BindingKind::AccelerationStructure => "an acceleration structure".into(),
        BindingKind::StorageImage(f) => format!("a {f:?} storage image"),
        BindingKind::StorageBuffer(_) => "a storage buffer".into(),
        BindingKind::UniformBuffer(_) => "a uniform buffer".into(),
        BindingKind::SampledImage => "a sampled image".into(),
        BindingKind::Sampler => "a sampler".into(),
        BindingKind::CombinedImageSampler => "a combined image sampler".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::ints::IntWords;

    fn b(binding: u32, kind: BindingKind, count: u32) -> Binding {
        Binding {
            set: 1,
            binding,
            kind,
            count,
            runtime: false,
            writable: false,
            ints: IntWords::default(),
            atomic: false,
            records: None,
        }
    }

    /// Aliased blocks at one binding are one binding of the largest size and count; the words
    /// one reads as an address stay addresses whatever the other reads there.
    #[test]
    fn aliased_buffer_blocks_are_one_binding_of_the_largest_size() {
        let mut f = b(0, BindingKind::StorageBuffer(64), 4);
        f.ints.fixed.low.insert(8);
        let mut u = b(0, BindingKind::StorageBuffer(4096), 64);
        u.ints.fixed.addr.insert(8);
        u.writable = true;
        let m = merged(&[f, u, b(1, BindingKind::UniformBuffer(16), 1)]).unwrap();
        let one = &m[&(1, 0)];
        assert_eq!(
            (one.kind, one.count, one.writable),
            (BindingKind::StorageBuffer(4096), 64, true)
        );
        use crate::harness::ints::Fill;
        assert_eq!((one.ints.at(8), one.ints.at(12)), (Fill::AddressLow, Fill::AddressHigh));
        assert_eq!(m.len(), 2);
    }

    /// A texture or a sampler declared at a combined image sampler's binding is that combined
    /// image sampler; a texture and a sampler at one binding are not.
    #[test]
    fn textures_at_a_combined_samplers_binding_are_it() {
        use BindingKind::{CombinedImageSampler, SampledImage, Sampler};
        for other in [SampledImage, Sampler, CombinedImageSampler] {
            let m = merged(&[b(0, other, 1), b(0, CombinedImageSampler, 8)]).unwrap();
            assert_eq!((m[&(1, 0)].kind, m[&(1, 0)].count), (CombinedImageSampler, 8));
        }
        let e = merged(&[b(0, SampledImage, 1), b(0, Sampler, 1)]).unwrap_err().to_string();
        assert!(e.contains("as a sampled image and as a sampler"), "{e}");
    }

    /// Twin: kinds no one descriptor serves are refused, naming the binding.
    #[test]
    fn incompatible_kinds_at_one_binding_are_refused() {
        use rspirv::spirv::ImageFormat::{R32f, Rgba32f};
        for (x, y) in [
            (BindingKind::StorageBuffer(16), BindingKind::UniformBuffer(16)),
            (BindingKind::StorageImage(Rgba32f), BindingKind::StorageImage(R32f)),
            (BindingKind::AccelerationStructure, BindingKind::StorageBuffer(16)),
        ] {
            let e = merged(&[b(0, x, 1), b(0, y, 1)]).unwrap_err().to_string();
            assert!(e.starts_with("set 1 binding 0 is declared as "), "{e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }
}
