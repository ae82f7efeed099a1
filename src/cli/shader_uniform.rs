//! `run --shader`'s `nonuniform` variant against a shader that reads descriptors with dynamic
//! indices and no `NonUniform`: where the patched pipeline (the same modules with the decoration
//! added) differs from the unpatched one, the unpatched reads were the undefined ones —
//! `VUID-RuntimeSpirv-None-10148` and `-subgroupSize-10149` (Vulkan 1.4.360, checked against
//! Vulkan-Docs: "must be decorated NonUniform" where the resource is not uniform, for modules
//! that do not declare `DescriptorHeapEXT`). A must broken is a failure, but the shader's: the
//! variant is judged [`Judgement::ShaderUndefined`], its outcome still a mismatch.
use crate::harness::child::JobModule;
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

/// Judge a differing `nonuniform` variant the shader's undefined read, naming the bindings.
pub fn judge(unpatched: &[JobModule], variants: &mut [ShaderVariant]) {
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
    let list: Vec<String> = bindings.iter().map(|(s, b)| format!("set {s} binding {b}")).collect();
    let was = v.detail.take().unwrap_or_default();
    v.judgement = Judgement::ShaderUndefined;
    v.detail = Some(format!(
        "the shader indexes {} with dynamic indices and no nonuniformEXT: where an index differs \
         within a subgroup the unpatched reads are undefined (VUID-RuntimeSpirv-None-10148, \
         Vulkan 1.4.360: must be decorated NonUniform), and adding the decoration changed the \
         outputs, so the difference is the shader's, not the driver's: add nonuniformEXT to \
         those indices ({was})",
        list.join(", ")
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

    /// Only a differing `nonuniform` variant of undecorated modules is the shader's; a
    /// decorated module's, or another patch's, difference stays `patch_differs`.
    #[test]
    fn a_differing_nonuniform_variant_of_undecorated_reads_is_the_shaders() {
        let m = |nonuniform| {
            vec![JobModule { name: "t".into(), words: words(nonuniform), ray_type: None }]
        };
        let mut vs = vec![variant("as-to-address", true), variant(NONUNIFORM, true)];
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers);
        judge(&m(true), &mut vs);
        assert_eq!(vs[1].judgement, Judgement::PatchDiffers);
        judge(&m(false), &mut vs);
        assert_eq!(vs[0].judgement, Judgement::PatchDiffers);
        assert_eq!(vs[1].judgement, Judgement::ShaderUndefined);
        assert_eq!(vs[1].outcome, Outcome::Mismatch, "still a failure");
        let d = vs[1].detail.as_deref().unwrap();
        assert!(d.contains("set 1 binding 3") && d.contains("VUID-RuntimeSpirv-None-10148"), "{d}");
        assert!(d.contains("2780 of 12288"), "{d}");
        let mut same = vec![variant(NONUNIFORM, false)];
        judge(&m(false), &mut same);
        assert_eq!(same[0].judgement, Judgement::Pass);
    }
}
