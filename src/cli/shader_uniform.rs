//! `run --shader`'s `nonuniform` variant against a shader that reads descriptors with dynamic
//! indices and no `NonUniform`: where the patched pipeline (the same modules with the decoration
//! added) differs from the unpatched one, the variant's detail says what the descriptor-index
//! check saw of each such binding's index — that it differed among a subgroup's active
//! invocations (subgroup vote, where the device has it in its ray tracing stages), that it only
//! varied over the trace, or that it was uniform in every subgroup — and the rule that would
//! make the unpatched reads undefined: `VUID-RuntimeSpirv-subgroupSize-10149` (Vulkan 1.4.360,
//! checked against Vulkan-Docs: with an effective subgroup size above 1, a resource "not uniform
//! within the invocation group, and not uniform within the subgroup" must be decorated
//! `NonUniform`, in a module that does not declare `DescriptorHeapEXT`).
//!
//! The judgement stays `patch_differs`: a ray tracing invocation group is "an
//! implementation-dependent subset" of a trace's invocations (chapter Shaders, Scope) and a
//! subgroup need only share a device scope instance, so no observation proves the index not
//! uniform within its invocation group; and the patch decorates every access at once, so one
//! uniform access whose decoration changes the result (a driver bug) looks the same.
use crate::harness::child::JobModule;
use crate::model::index_bounds::{IndexBounds, IndexSeen, IndexedArray};
use crate::model::shader_run::{Judgement, ShaderVariant};

/// The variant the rule applies to.
const NONUNIFORM: &str = "nonuniform";

/// The (set, binding)s the given modules index without `NonUniform`, each once.
fn undecorated(modules: &[JobModule]) -> Vec<(u32, u32)> {
    let mut all: Vec<(u32, u32)> =
        modules.iter().flat_map(|m| crate::patches::uniformity::undecorated(&m.words)).collect();
    all.sort_unstable();
    all.dedup();
    all
}

/// What the check saw of one binding's dynamic indices without `NonUniform`, merged over its
/// declarations' slots: the widest range; differed within a subgroup if any did, uniform only if
/// every one that ran was measured uniform.
fn seen(arrays: &[&IndexedArray]) -> String {
    if arrays.is_empty() {
        return "not checked".into();
    }
    let ran: Vec<&IndexSeen> = arrays.iter().filter_map(|a| a.undecorated.as_ref()).collect();
    if ran.is_empty() {
        return "not reached".into();
    }
    let smallest = ran.iter().map(|a| a.smallest).min().unwrap_or(0);
    let largest = ran.iter().map(|a| a.largest).max().unwrap_or(0);
    if ran.iter().any(|a| a.nonuniform == Some(true)) {
        return "differed within a subgroup".into();
    }
    if ran.iter().all(|a| a.nonuniform == Some(false)) {
        return "uniform in every subgroup".into();
    }
    if smallest != largest {
        return format!("{smallest}..{largest} over the trace, no subgroup vote here");
    }
    format!("{largest} throughout")
}

/// Add to a differing `nonuniform` variant's detail what the check saw of each binding the
/// unpatched modules index without `NonUniform`, and the rule.
pub fn explain(unpatched: &[JobModule], bounds: &IndexBounds, variants: &mut [ShaderVariant]) {
    let Some(v) = variants
        .iter_mut()
        .find(|v| v.patch.as_deref() == Some(NONUNIFORM) && v.judgement == Judgement::PatchDiffers)
    else {
        return;
    };
    let bindings = undecorated(unpatched);
    if bindings.is_empty() {
        return;
    }
    let each: Vec<String> = bindings
        .iter()
        .map(|&(s, b)| {
            let arrays: Vec<&IndexedArray> =
                bounds.arrays.iter().filter(|a| (a.set, a.binding) == (s, b)).collect();
            format!("set {s} binding {b} ({})", seen(&arrays))
        })
        .collect();
    let was = v.detail.take().unwrap_or_default();
    v.detail = Some(format!(
        "{was}; the shader indexes {} without nonuniformEXT: where such an index is not uniform \
         within its invocation group and its subgroup the unpatched reads are undefined \
         (VUID-RuntimeSpirv-subgroupSize-10149, Vulkan 1.4.360, a must) — add nonuniformEXT; a \
         difference is evidence against the driver only where the index is uniform",
        each.join(", ")
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::shader_run::ShaderAttempt;
    use crate::model::{Attempt, Outcome};

    fn words(nonuniform: bool) -> Vec<u32> {
        let index = if nonuniform { "nonuniformEXT(k)" } else { "k" };
        let glsl = format!(
            "#version 460\n#extension GL_EXT_ray_tracing : require\n\
             #extension GL_EXT_nonuniform_qualifier : require\n\
             layout(set = 1, binding = 3) uniform sampler2D maps[];\n\
             layout(location = 0) rayPayloadInEXT vec4 c;\n\
             void main() {{ uint k = uint(gl_InstanceCustomIndexEXT);\n\
             c = textureLod(maps[{index}], vec2(0), 0.0); }}\n"
        );
        let m = crate::patches::compiled(shaderc::ShaderKind::ClosestHit, "t.rchit", &glsl);
        crate::patches::assemble(&m)
    }

    fn variant(name: &str, differs: bool) -> ShaderVariant {
        let mut a = ShaderAttempt::bare(Attempt::new(Outcome::Pass, true));
        a.differs = differs.then(|| "2780 of 12288 words differ".to_string());
        ShaderVariant::judged(name, Some(name.into()), vec![], vec![a], None)
    }

    fn bounds(nonuniform: Option<bool>, smallest: u32) -> IndexBounds {
        let a = IndexedArray {
            set: 1,
            binding: 3,
            elements: 64,
            runtime: true,
            seen: Some(IndexSeen { smallest: 0, largest: 63, nonuniform: Some(true) }),
            undecorated: Some(IndexSeen { smallest, largest: 9, nonuniform }),
        };
        IndexBounds { arrays: vec![a], ..IndexBounds::default() }
    }

    fn detail(nonuniform: bool, b: &IndexBounds) -> (Judgement, String) {
        let m = vec![JobModule { name: "t".into(), words: words(nonuniform), ray_type: None }];
        let mut vs = vec![variant("as-to-address", true), variant(NONUNIFORM, true)];
        explain(&m, b, &mut vs);
        assert!(
            !vs[0].detail.clone().unwrap_or_default().contains("nonuniformEXT"),
            "another patch's"
        );
        (vs[1].judgement, vs[1].detail.clone().unwrap_or_default())
    }

    /// A differing `nonuniform` variant of undecorated modules says what the check saw and the
    /// rule, and stays `patch_differs` whatever it saw; a decorated module's gets nothing.
    #[test]
    fn a_differing_nonuniform_variant_says_what_the_check_saw() {
        let (j, d) = detail(false, &bounds(Some(true), 2));
        assert_eq!(j, Judgement::PatchDiffers);
        assert!(d.starts_with("2780 of 12288") || d.contains("2780 of 12288"), "{d}");
        assert!(d.contains("set 1 binding 3 (differed within a subgroup)"), "{d}");
        assert!(d.contains("VUID-RuntimeSpirv-subgroupSize-10149"), "{d}");
        let (_, d) = detail(false, &bounds(Some(false), 2));
        assert!(d.contains("(uniform in every subgroup)"), "{d}");
        let (_, d) = detail(false, &bounds(None, 2));
        assert!(d.contains("(2..9 over the trace, no subgroup vote here)"), "{d}");
        let (_, d) = detail(false, &IndexBounds::unchecked("x"));
        assert!(d.contains("(not checked)"), "{d}");
        // Two declarations of the binding: the widest range, and "uniform" only if both are.
        let mut two = bounds(Some(false), 2);
        let other = IndexSeen { smallest: 12, largest: 116, nonuniform: Some(true) };
        two.arrays.push(IndexedArray { undecorated: Some(other), ..two.arrays[0].clone() });
        let (_, d) = detail(false, &two);
        assert!(d.contains("(differed within a subgroup)"), "{d}");
        two.arrays[1].undecorated.as_mut().unwrap().nonuniform = None;
        two.arrays[0].undecorated.as_mut().unwrap().nonuniform = None;
        let (_, d) = detail(false, &two);
        assert!(d.contains("(2..116 over the trace"), "{d}");
        let (j, d) = detail(true, &bounds(Some(true), 2));
        assert_eq!(j, Judgement::PatchDiffers);
        assert!(!d.contains("nonuniformEXT"), "a decorated module: {d}");
    }
}
