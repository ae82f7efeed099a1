//! The stages a user's pipeline lacks, supplied ([`supply`]): without a raygen, one whose
//! payload mirrors the hit and miss shaders' incoming payload (its type tree printed as GLSL,
//! `reflect::glsl`), zeroed, traced once per pixel of the harness scene (`scene::Scene::
//! primary_ray`'s orthographic rays) and written back word by word — each 32-bit scalar member
//! by member (`floatBitsToUint`, `uint(…)`) — to a storage buffer of `SIZE·SIZE·words` uints at
//! set 0, at the two bindings after the highest one any user module declares there (the TLAS
//! first); without a miss shader, one that writes [`MISS_MARKER`] (a bool: `false`) into the
//! payload's first scalar — one per miss index the rays use, each receiving that ray's payload (`traces`), after
//! the given misses. Hit groups stay as `Harness::pipeline` makes them (a procedural group without an
//! intersection shader gets the one that reports nothing), except that a ray type (SBT record
//! offset, `ray_types`) above 0 without a hit shader of its own, whose rays do not all skip the
//! closest-hit, gets a closest-hit that writes its payload zero ([`closest_hit_glsl`]; one whose
//! rays all skip it keeps an empty group). A payload the GLSL cannot mirror word
//! for word (a pointer, a runtime array, a scalar not 32 bits wide) is a typed error naming it.
use super::error::HarnessError;
use super::module::UserModule;
use super::scene::TRACE_SIZE as SIZE;
use super::traces;
use crate::reflect::glsl::{self, Glsl};
use crate::reflect::{Scalar, Ty};
use crate::scene::{RAY_TMAX, RAY_TMIN, RAY_Z, VIEW_HALF};
use shaderc::ShaderKind;

/// The supplied raygen's module name (the harness binds the scene TLAS at its TLAS binding).
pub const RAYGEN_NAME: &str = "supplied raygen";

/// What the supplied miss shader writes into the payload's first scalar ("MISS").
pub const MISS_MARKER: u32 = 0x4D49_5353;

/// The payload the supplied stages use: the first incoming payload of a closest-hit, any-hit or
/// miss module (in that order), else the raygen's first outgoing one, with the module's and the
/// variable's names; a `uint` when there is none.
fn payload(modules: &[UserModule]) -> (Ty, String) {
    for stage in ["closest_hit", "any_hit", "miss"] {
        let found = modules.iter().filter(|m| m.iface.stage == stage).find_map(|m| {
            let p = m.iface.reflection.incoming_payload.as_ref()?;
            Some((p.ty.clone(), format!("{}'s payload `{}`", m.name, p.name)))
        });
        if let Some(f) = found {
            return f;
        }
    }
    let sent = modules.iter().filter(|m| m.iface.stage == "raygen").find_map(|m| {
        let p = m.iface.reflection.payloads.first()?;
        Some((p.ty.clone(), format!("{}'s payload `{}`", m.name, p.name)))
    });
    if let Some(f) = sent {
        return f;
    }
    (Ty::Scalar(Scalar::Int { bits: 32, signed: false }), "the default payload".into())
}

/// The scalars of the payload as lvalues of `payload`, or why they cannot be mirrored.
fn leaves(ty: &Ty, what: &str) -> Result<Vec<(Scalar, String)>, HarnessError> {
    let refuse = |why: String| {
        HarnessError::Unsupported(format!(
            "{what} cannot be mirrored by a generated raygen ({why}); give your raygen with --shader"
        ))
    };
    let l = glsl::scalars(ty, "payload").map_err(|e| refuse(e.to_string()))?;
    if let Some((s, at)) = l.iter().find(|(s, _)| s.bytes() != 4) {
        return Err(refuse(format!("{at} is a {s:?}, not a 32-bit scalar")));
    }
    Ok(l)
}

/// The payload declaration and preamble.
fn declared(ty: &Ty, what: &str, storage: &str) -> Result<(String, String), HarnessError> {
    let mut g = Glsl::default();
    let decl = g.declare(ty, "payload").map_err(|e| {
        HarnessError::Unsupported(format!("{what}: {e}; give your raygen with --shader"))
    })?;
    Ok((g.preamble(), format!("layout(location = 0) {storage} {decl};\n")))
}

/// GLSL of a scalar's value as a uint, and of its zero.
fn to_uint(s: Scalar, v: &str) -> String {
    match s {
        Scalar::Float { .. } => format!("floatBitsToUint({v})"),
        Scalar::Int { signed: false, .. } => v.to_string(),
        Scalar::Int { signed: true, .. } | Scalar::Bool => format!("uint({v})"),
    }
}

fn zero(s: Scalar) -> &'static str {
    match s {
        Scalar::Float { .. } => "0.0",
        Scalar::Int { signed: false, .. } => "0u",
        Scalar::Int { signed: true, .. } => "0",
        Scalar::Bool => "false",
    }
}

const HEAD: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n";

/// The raygen's GLSL: TLAS at `binding`, the words buffer at `binding + 1`.
pub fn raygen_glsl(ty: &Ty, what: &str, binding: u32) -> Result<String, HarnessError> {
    let l = leaves(ty, what)?;
    let (preamble, decl) = declared(ty, what, "rayPayloadEXT")?;
    let words = l.len().max(1);
    let init: String = l.iter().map(|(s, at)| format!("    {at} = {};\n", zero(*s))).collect();
    let out: String = l
        .iter()
        .enumerate()
        .map(|(k, (s, at))| format!("    rtprobeOut.words[base + {k}u] = {};\n", to_uint(*s, at)))
        .collect();
    let (h, z) = (VIEW_HALF, RAY_Z);
    Ok(format!(
        "{HEAD}{preamble}\
        layout(set = 0, binding = {binding}) uniform accelerationStructureEXT rtprobeScene;\n\
        layout(set = 0, binding = {b1}, std430) buffer RtprobeWords {{ uint words[{n}]; }} rtprobeOut;\n\
        {decl}\
        void main() {{\n\
        \x20   vec2 px = vec2(gl_LaunchIDEXT.xy) + 0.5;\n\
        \x20   vec2 step = 2.0 * {h:?} / vec2(gl_LaunchSizeEXT.xy);\n\
        \x20   vec3 origin = vec3(-{h:?} + px.x * step.x, {h:?} - px.y * step.y, {z:?});\n\
        {init}\
        \x20   traceRayEXT(rtprobeScene, gl_RayFlagsNoneEXT, 0xFF, 0, 0, 0, origin, {tmin:?}, vec3(0.0, 0.0, 1.0), {tmax:?}, 0);\n\
        \x20   uint base = (gl_LaunchIDEXT.y * {SIZE}u + gl_LaunchIDEXT.x) * {words}u;\n\
        {out}}}\n",
        b1 = binding + 1,
        n = SIZE * SIZE * words as u32,
        tmin = RAY_TMIN,
        tmax = RAY_TMAX,
    ))
}

/// The miss shader's GLSL: the marker in the payload's first scalar — a bool gets `false`, the
/// shadow-ray idiom's miss (the tracer sets `shadowed = true`, a miss clears it).
pub fn miss_glsl(ty: &Ty, what: &str) -> Result<String, HarnessError> {
    let l = leaves(ty, what)?;
    let (preamble, decl) = declared(ty, what, "rayPayloadInEXT")?;
    let mark = match l.first() {
        Some((Scalar::Float { .. }, at)) => {
            format!("    {at} = uintBitsToFloat({MISS_MARKER:#x}u);\n")
        }
        Some((Scalar::Int { signed: false, .. }, at)) => format!("    {at} = {MISS_MARKER:#x}u;\n"),
        Some((Scalar::Int { signed: true, .. }, at)) => format!("    {at} = {MISS_MARKER:#x};\n"),
        Some((Scalar::Bool, at)) => format!("    {at} = false;\n"),
        None => String::new(),
    };
    Ok(format!("{HEAD}{preamble}{decl}void main() {{\n{mark}}}\n"))
}

/// A closest-hit for a ray type without one: every scalar of its payload zero.
pub fn closest_hit_glsl(ty: &Ty, what: &str) -> Result<String, HarnessError> {
    let l = leaves(ty, what)?;
    let (preamble, decl) = declared(ty, what, "rayPayloadInEXT")?;
    let zeros: String = l.iter().map(|(s, at)| format!("    {at} = {};\n", zero(*s))).collect();
    Ok(format!("{HEAD}{preamble}{decl}void main() {{\n{zeros}}}\n"))
}

/// A generated closest-hit for each ray type above 0 that has no hit shader, where some of its
/// rays do not skip the closest-hit.
fn closest_hits(modules: &mut Vec<UserModule>) -> Result<(), HarnessError> {
    let refs: Vec<&UserModule> = modules.iter().collect();
    let g = super::groups::groups(&refs)?;
    let payloads = super::ray_types::payloads(&refs, g.types.len() as u32);
    let runs_chit = |k: usize| {
        refs.iter().flat_map(|m| &m.iface.reflection.traces).any(|t| {
            t.sbt_offset == Some(k as u32) && !t.has_flag(crate::reflect::FLAG_SKIP_CLOSEST_HIT)
        })
    };
    let mut made = Vec::new();
    for (k, t) in g.types.iter().enumerate().skip(1) {
        let (Some((ty, what)), true) = (&payloads[k], t.hit == [None, None] && t.any_hit.is_none())
        else {
            continue;
        };
        if runs_chit(k) {
            let name = format!("supplied closest-hit {k}");
            let glsl = closest_hit_glsl(ty, what)?;
            let mut m = compiled(ShaderKind::ClosestHit, &name, &glsl)?;
            m.ray_type = Some(k as u32);
            made.push(m);
        }
    }
    modules.extend(made);
    Ok(())
}

fn compiled(kind: ShaderKind, name: &str, glsl: &str) -> Result<UserModule, HarnessError> {
    let fail = |e: crate::shadergen::compile::CompileError| {
        HarnessError::Unsupported(format!("{name}: the supplied stage does not compile: {e}"))
    };
    let words = crate::shadergen::compile::Compiler::new()
        .map_err(fail)?
        .compile_glsl(kind, name, glsl)
        .map_err(fail)?;
    UserModule::new(name, &words)
}

/// The first set-0 binding after every one `modules` declare there.
pub fn free_binding(modules: &[UserModule]) -> u32 {
    modules
        .iter()
        .flat_map(|m| m.iface.bindings.iter().filter(|b| b.set == 0).map(|b| b.binding + 1))
        .max()
        .unwrap_or(0)
}

/// `modules` with a raygen and a miss shader supplied where they have none.
pub fn supply(modules: Vec<UserModule>) -> Result<Vec<UserModule>, HarnessError> {
    let binding = free_binding(&modules);
    supply_at(modules, binding)
}

/// [`supply`] with the raygen's TLAS at set 0 `binding` and its words at `binding + 1` (a
/// patched pipeline that no longer declares a binding keeps the unpatched one's). Misses are
/// supplied after the given ones, one per miss index the rays use ([`traces::miss_payloads`]),
/// and every ray is then held to the stages it invokes ([`traces::check`]).
pub fn supply_at(
    mut modules: Vec<UserModule>,
    binding: u32,
) -> Result<Vec<UserModule>, HarnessError> {
    let has = |s: &str, m: &[UserModule]| m.iter().any(|m| m.iface.stage == s);
    let raygen = has("raygen", &modules);
    let (ty, what) = payload(&modules);
    let needed = traces::miss_payloads(&modules, (!raygen).then_some((&ty, what.as_str())))?;
    let given = modules.iter().filter(|m| m.iface.stage == "miss").count();
    for k in given..needed.len().max(1) {
        let (ty, what) = needed.get(k).cloned().flatten().unwrap_or((ty.clone(), what.clone()));
        let name = match k {
            0 => "supplied miss".to_string(),
            k => format!("supplied miss {k}"),
        };
        modules.push(compiled(ShaderKind::Miss, &name, &miss_glsl(&ty, &what)?)?);
    }
    if !raygen {
        let glsl = raygen_glsl(&ty, &what, binding)?;
        modules.insert(0, compiled(ShaderKind::RayGeneration, RAYGEN_NAME, &glsl)?);
    }
    closest_hits(&mut modules)?;
    traces::check(&modules)?;
    Ok(modules)
}

#[cfg(test)]
mod tests;
