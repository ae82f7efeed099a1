//! A user pipeline's shader groups from its modules ([`groups`]): which module is the raygen,
//! each miss, the triangle and procedural hit groups' shaders and each callable.
use super::error::HarnessError;
use super::module::UserModule;

/// The groups of a pipeline from its modules (by index): raygen, misses, the triangle hit group
/// (closest-hit, any-hit), the procedural one (intersection, second closest-hit), callables.
pub struct Groups {
    pub raygen: usize,
    pub misses: Vec<usize>,
    pub hit: [Option<usize>; 2],
    pub any_hit: Option<usize>,
    pub intersection: Option<usize>,
    pub callables: Vec<usize>,
}

pub fn groups(modules: &[&UserModule]) -> Result<Groups, HarnessError> {
    let mut g = Groups {
        raygen: usize::MAX,
        misses: vec![],
        hit: [None, None],
        any_hit: None,
        intersection: None,
        callables: vec![],
    };
    let mut chits = Vec::new();
    for (i, m) in modules.iter().enumerate() {
        match m.iface.stage.as_str() {
            "raygen" if g.raygen == usize::MAX => g.raygen = i,
            "miss" => g.misses.push(i),
            "closest_hit" => chits.push(i),
            "any_hit" if g.any_hit.is_none() => g.any_hit = Some(i),
            "intersection" if g.intersection.is_none() => g.intersection = Some(i),
            "callable" => g.callables.push(i),
            s => return Err(HarnessError::Unsupported(format!("{}: the harness runs one raygen with its misses, hit shaders and callables; a {s} module is not one of them", m.name))),
        }
    }
    if g.raygen == usize::MAX || g.misses.is_empty() {
        return Err(HarnessError::Unsupported(
            "the harness needs a raygen and a miss shader (`supply` adds them where missing)"
                .into(),
        ));
    }
    if chits.len() > 2 {
        let names: Vec<&str> = chits.iter().map(|&i| modules[i].name.as_str()).collect();
        return Err(HarnessError::Unsupported(format!("{}: the harness has one triangle and one procedural hit group, so it runs at most two closest-hit shaders (the second with your intersection shader); run the others in runs of their own", names.join(", "))));
    }
    if let (Some(&second), None) = (chits.get(1), g.intersection) {
        return Err(HarnessError::Unsupported(format!("{}: a second closest-hit runs only in the procedural hit group, on geometry your intersection shader reports, and none is given; give the intersection shader with --shader, or run each closest-hit in a run of its own", modules[second].name)));
    }
    g.hit = [chits.first().copied(), chits.get(1).copied()];
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shaderc::ShaderKind;

    fn module(kind: ShaderKind, name: &str, body: &str) -> UserModule {
        let glsl = format!(
            "#version 460\n#extension GL_EXT_ray_tracing : require\n{body}\nvoid main() {{}}\n"
        );
        let words = crate::shadergen::compile::Compiler::new()
            .unwrap()
            .compile_glsl(kind, name, &glsl)
            .unwrap();
        UserModule::new(name, &words).unwrap()
    }

    fn chit(name: &str) -> UserModule {
        module(ShaderKind::ClosestHit, name, "layout(location = 0) rayPayloadInEXT vec4 c;")
    }

    fn run(names: &[UserModule]) -> Result<Groups, HarnessError> {
        let base = [
            module(ShaderKind::RayGeneration, "r.rgen", ""),
            module(ShaderKind::Miss, "m.rmiss", "layout(location = 0) rayPayloadInEXT vec4 c;"),
        ];
        let all: Vec<&UserModule> = base.iter().chain(names).collect();
        groups(&all)
    }

    /// A closest-hit the pipeline never invokes would pass without evidence: two without an
    /// intersection shader, or three, are refused in one line naming them.
    #[test]
    fn closest_hits_that_would_never_run_are_refused() {
        let g = run(&[chit("a.rchit")]).unwrap();
        assert_eq!((g.hit, g.intersection), ([Some(2), None], None));
        let isect = module(ShaderKind::Intersection, "s.rint", "hitAttributeEXT vec2 h;");
        let g = run(&[chit("a.rchit"), isect, chit("b.rchit")]).unwrap();
        assert_eq!((g.hit, g.intersection), ([Some(2), Some(4)], Some(3)));
        let e = run(&[chit("a.rchit"), chit("b.rchit")]).err().unwrap().to_string();
        assert!(
            e.starts_with("b.rchit: a second closest-hit runs only") && !e.contains('\n'),
            "{e}"
        );
        let e =
            run(&[chit("a.rchit"), chit("b.rchit"), chit("c.rchit")]).err().unwrap().to_string();
        assert!(e.starts_with("a.rchit, b.rchit, c.rchit: the harness has one triangle"), "{e}");
    }
}
