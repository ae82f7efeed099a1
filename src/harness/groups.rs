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
    g.hit = [chits.first().copied(), chits.get(1).copied()];
    Ok(g)
}
