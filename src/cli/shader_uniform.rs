//! `run --shader`'s `nonuniform` variant against a shader that reads descriptors with dynamic
//! indices and no `NonUniform`: where the patched pipeline (the same modules with the decoration
//! added) differs from the unpatched one, and the descriptor-index check saw such an index
//! differ among a subgroup's active invocations, the unpatched reads were the undefined ones —
//! `VUID-RuntimeSpirv-subgroupSize-10149` (Vulkan 1.4.360, checked against Vulkan-Docs: with an
//! effective subgroup size above 1, a resource "not uniform within the invocation group, and not
//! uniform within the subgroup" must be decorated `NonUniform`, in a module that does not declare
//! `DescriptorHeapEXT`). A must broken is a failure, but the shader's: the variant is judged
//! [`Judgement::ShaderUndefined`], its outcome still a mismatch. Without that evidence (an
//! index uniform in every subgroup needs no decoration, and adding one must change nothing) the
//! difference stays `patch_differs`.
use crate::harness::child::JobModule;
use crate::model::index_bounds::IndexBounds;
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

/// Judge a differing `nonuniform` variant the shader's undefined read, naming the bindings:
/// those indexed without `NonUniform` whose index the check saw differ within a subgroup.
pub fn judge(unpatched: &[JobModule], bounds: &IndexBounds, variants: &mut [ShaderVariant]) {
    let Some(v) = variants
        .iter_mut()
        .find(|v| v.patch.as_deref() == Some(NONUNIFORM) && v.judgement == Judgement::PatchDiffers)
    else {
        return;
    };
    let seen = |b: &(u32, u32)| {
        bounds.arrays.iter().any(|a| (a.set, a.binding) == *b && a.nonuniform == Some(true))
    };
    let undecorated = undecorated(unpatched);
    let bindings: Vec<(u32, u32)> = undecorated.iter().copied().filter(seen).collect();
    if bindings.is_empty() {
        hint(&undecorated, bounds, v);
        return;
    }
    let list: Vec<String> = bindings.iter().map(|(s, b)| format!("set {s} binding {b}")).collect();
    let was = v.detail.take().unwrap_or_default();
    v.judgement = Judgement::ShaderUndefined;
    v.detail = Some(format!(
        "the shader indexes {} without nonuniformEXT, and the index check saw the index differ \
         within a subgroup: those reads are undefined (VUID-RuntimeSpirv-subgroupSize-10149, \
         Vulkan 1.4.360: must be decorated NonUniform), and adding the decoration changed the \
         outputs, so the difference is the shader's, not the driver's: add nonuniformEXT to \
         those indices ({was})",
        list.join(", ")
    ));
}

/// Without subgroup evidence: where an undecorated binding's index varied over the trace,
/// say what would make the difference the shader's (the judgement stays `patch_differs`).
fn hint(undecorated: &[(u32, u32)], bounds: &IndexBounds, v: &mut ShaderVariant) {
    let varied: Vec<String> = bounds
        .arrays
        .iter()
        .filter(|a| a.nonuniform.is_none() && a.accessed && a.smallest != a.largest)
        .filter(|a| undecorated.contains(&(a.set, a.binding)))
        .map(|a| format!("set {} binding {} ({}..{})", a.set, a.binding, a.smallest, a.largest))
        .collect();
    if varied.is_empty() {
        return;
    }
    let was = v.detail.take().unwrap_or_default();
    v.detail = Some(format!(
        "{was}; the shader indexes {} without nonuniformEXT and the index varied over the trace: \
         where it differs within a subgroup the reads are undefined \
         (VUID-RuntimeSpirv-subgroupSize-10149), which this device's ray tracing stages cannot \
         show (no subgroup vote there), so the difference is not judged the shader's",
        varied.join(", ")
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

    fn seen(nonuniform: bool) -> IndexBounds {
        let a = crate::model::index_bounds::IndexedArray {
            set: 1,
            binding: 3,
            elements: 64,
            runtime: true,
            largest: 9,
            smallest: 2,
            accessed: true,
            nonuniform: Some(nonuniform),
        };
        IndexBounds { arrays: vec![a], ..IndexBounds::default() }
    }

    /// Only a differing `nonuniform` variant of undecorated modules whose index the check saw
    /// differ within a subgroup is the shader's; a decorated module's, a uniform index's, an
    /// unchecked run's or another patch's difference stays `patch_differs`.
    #[test]
    fn a_differing_nonuniform_variant_of_undecorated_reads_is_the_shaders() {
        let m = |nonuniform| {
            vec![JobModule { name: "t".into(), words: words(nonuniform), ray_type: None }]
        };
        let mut vs = vec![variant("as-to-address", true), variant(NONUNIFORM, true)];
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers);
        judge(&m(true), &seen(true), &mut vs);
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers);
        judge(&m(false), &seen(false), &mut vs);
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers, "uniform in every subgroup");
        judge(&m(false), &IndexBounds::unchecked("x"), &mut vs);
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers, "no evidence");
        let mut unmeasured = seen(false);
        unmeasured.arrays[0].nonuniform = None;
        judge(&m(false), &unmeasured, &mut vs);
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers, "not measured");
        let d = vs[1].detail.clone().unwrap();
        assert!(d.contains("set 1 binding 3 (2..9)") && d.contains("no subgroup vote"), "{d}");
        judge(&m(false), &seen(true), &mut vs);
        assert_eq!(vs[0].judgement, Judgement::PatchDiffers);
        assert_eq!(vs[1].judgement, Judgement::ShaderUndefined);
        let d = vs[1].detail.as_deref().unwrap();
        assert!(
            d.contains("set 1 binding 3") && d.contains("VUID-RuntimeSpirv-subgroupSize-10149"),
            "{d}"
        );
        assert!(d.contains("2780 of 12288"), "{d}");
        let mut same = vec![variant(NONUNIFORM, false)];
        judge(&m(false), &seen(true), &mut same);
        assert_eq!(same[0].judgement, Judgement::Pass);
    }
}
