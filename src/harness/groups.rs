//! A user pipeline's shader groups from its modules ([`groups`]): which module is the raygen,
//! each miss, each callable, and per ray type (`ray_types`) the triangle and procedural hit
//! groups' shaders.
use super::error::HarnessError;
use super::module::UserModule;
use super::ray_types;

/// One ray type's hit shaders (by module index): the triangle group's closest-hit, the
/// procedural group's (`hit[1]`, with the intersection shader), the any-hit both groups share.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TypeGroups {
    pub hit: [Option<usize>; 2],
    pub any_hit: Option<usize>,
    pub intersection: Option<usize>,
}

/// The groups of a pipeline from its modules (by index): raygen, misses, per ray type (SBT
/// record offset) its hit groups' shaders, callables.
pub struct Groups {
    pub raygen: usize,
    pub misses: Vec<usize>,
    pub types: Vec<TypeGroups>,
    pub callables: Vec<usize>,
}

fn unsupported(s: String) -> HarnessError {
    HarnessError::Unsupported(s)
}

pub fn groups(modules: &[&UserModule]) -> Result<Groups, HarnessError> {
    let types = ray_types::count(modules)?;
    let payloads = ray_types::payloads(modules, types);
    let mut g = Groups {
        raygen: usize::MAX,
        misses: vec![],
        types: vec![TypeGroups::default(); types as usize],
        callables: vec![],
    };
    let mut chits = vec![Vec::new(); types as usize];
    let mut shared_isect = Vec::new();
    for (i, m) in modules.iter().enumerate() {
        let stage = m.iface.stage.as_str();
        let hit = matches!(stage, "closest_hit" | "any_hit" | "intersection");
        let k = if hit { ray_types::assign(m, types, &payloads)? } else { None };
        match (stage, k) {
            ("raygen", _) if g.raygen == usize::MAX => g.raygen = i,
            ("miss", _) => g.misses.push(i),
            ("closest_hit", Some(k)) => chits[k as usize].push(i),
            ("any_hit", Some(k)) => set(&mut g.types[k as usize].any_hit, i, modules, k)?,
            ("intersection", Some(k)) => set(&mut g.types[k as usize].intersection, i, modules, k)?,
            ("intersection", None) => shared_isect.push(i),
            ("callable", _) => g.callables.push(i),
            (s, _) => return Err(unsupported(format!("{}: the harness runs one raygen with its misses, hit shaders and callables; a {s} module is not one of them", m.name))),
        }
    }
    if g.raygen == usize::MAX || g.misses.is_empty() {
        return Err(HarnessError::Unsupported(
            "the harness needs a raygen and a miss shader (`supply` adds them where missing)"
                .into(),
        ));
    }
    shared(&mut g, &shared_isect, modules)?;
    for (k, list) in chits.iter().enumerate() {
        g.types[k].hit = closest_hits(list, g.types[k].intersection, modules, k)?;
    }
    Ok(g)
}

/// One shader of kind `slot` for ray type `k`: a second one is refused.
fn set(
    slot: &mut Option<usize>,
    i: usize,
    modules: &[&UserModule],
    k: u32,
) -> Result<(), HarnessError> {
    if let Some(first) = slot.replace(i) {
        let (a, b) = (&modules[first].name, &modules[i].name);
        return Err(unsupported(format!("{a}, {b}: both are {} shaders of ray type {k} (SBT record offset {k}); a hit group holds one: give them to different ray types with --hit-group K=FILE, or run them in runs of their own", modules[i].iface.stage)));
    }
    Ok(())
}

/// An intersection shader without a ray type of its own serves every ray type lacking one.
fn shared(g: &mut Groups, isects: &[usize], modules: &[&UserModule]) -> Result<(), HarnessError> {
    match isects {
        [] => Ok(()),
        [i] => {
            g.types.iter_mut().filter(|t| t.intersection.is_none()).for_each(|t| t.intersection = Some(*i));
            Ok(())
        }
        [a, b, ..] => Err(unsupported(format!("{}, {}: intersection shaders have no payload, so rtprobe cannot tell which ray type each serves: say it with --hit-group K=FILE", modules[*a].name, modules[*b].name))),
    }
}

/// Ray type `k`'s closest-hits: the first in the triangle group, a second in the procedural one
/// (only with an intersection shader); more are refused, naming them.
fn closest_hits(
    chits: &[usize],
    intersection: Option<usize>,
    modules: &[&UserModule],
    k: usize,
) -> Result<[Option<usize>; 2], HarnessError> {
    if chits.len() > 2 {
        let names: Vec<&str> = chits.iter().map(|&i| modules[i].name.as_str()).collect();
        return Err(unsupported(format!("{}: the harness has one triangle and one procedural hit group per ray type, so it runs at most two closest-hit shaders of ray type {k} (the second with your intersection shader); run the others in runs of their own", names.join(", "))));
    }
    if let (Some(&second), None) = (chits.get(1), intersection) {
        return Err(unsupported(format!("{}: a second closest-hit runs only in the procedural hit group (here ray type {k}'s), on geometry your intersection shader reports, and none is given; give the intersection shader with --shader, or run each closest-hit in a run of its own", modules[second].name)));
    }
    Ok([chits.first().copied(), chits.get(1).copied()])
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
        assert_eq!((g.types[0].hit, g.types[0].intersection), ([Some(2), None], None));
        let isect = module(ShaderKind::Intersection, "s.rint", "hitAttributeEXT vec2 h;");
        let g = run(&[chit("a.rchit"), isect, chit("b.rchit")]).unwrap();
        assert_eq!((g.types[0].hit, g.types[0].intersection), ([Some(2), Some(4)], Some(3)));
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
