//! The failing cell's probed shader against its closest passing sibling's: GLSL, `spirv-dis`
//! disassembly, unified diffs of both (from the sibling to the failing shader), and the excerpt
//! the one screen shows — the probed array's declaration and the lines of `main` that compute
//! the index and read through it.
use super::diff::{unified, Match};
use super::types::{IssueError, ShaderComparison};
use crate::bisect::scope::cell_by_id;
use crate::model::inject::for_cell;
use crate::model::{Bisection, Cell, Injection, RunReport};
use crate::report::shaders::{cell_shaders, lanes_in, probed_role, spirv_dis};

/// Where the generated GLSL starts what the probe adds (`shadergen::probe_code`).
const PROBE_MARK: &str = "// ---- probe declarations ----";

/// The probed read and its declarations in `glsl`: the probe section's declarations of
/// descriptors, heaps and shader records, and `main`'s lines that compute the probed slot and
/// element and read the value (`probeSlot`, `probeElement`, `probeValue`, `probeSampler`).
pub fn excerpt(glsl: &str) -> String {
    let Some(at) = glsl.find(PROBE_MARK) else { return String::new() };
    let probe = &glsl[at + PROBE_MARK.len()..];
    let main = probe.find("void main()").unwrap_or(probe.len());
    let mut out = String::new();
    for l in probe[..main].lines() {
        let t = l.trim_start();
        let declares = t.starts_with("layout(")
            && ["binding", "descriptor_heap", "shaderRecordEXT"].iter().any(|k| t.contains(k));
        if declares {
            out += l;
            out.push('\n');
        }
    }
    out += "void main() {\n";
    let reads = ["probeSlot =", "probeElement =", "probeValue =", "probeSampler =", "probeBase ="];
    for l in probe[main..].lines().filter(|l| reads.iter().any(|r| l.contains(r))) {
        out += l;
        out.push('\n');
    }
    out += "    ...\n}\n";
    out
}

/// The probed shader of the failing cell and of its closest passing sibling (preferring a
/// sibling that differs in the index, then the resource, then the other axes in registry order).
pub(super) fn comparison(
    report: &RunReport,
    rep: &Cell,
    bi: &Bisection,
    inject: &[Injection],
) -> Result<ShaderComparison, IssueError> {
    const FIRST: [&str; 3] = ["index", "nonuniform", "resource"];
    let order: Vec<&str> = FIRST
        .into_iter()
        .chain(crate::model::registry::names().filter(|a| !FIRST.contains(a)))
        .collect();
    let sibling = order
        .iter()
        .find_map(|ax| {
            bi.isolation.iter().find(|l| l.varied.as_deref() == Some(*ax) && l.verdict == "pass")
        })
        .and_then(|l| cell_by_id(&l.cell));
    let role = probed_role(rep.stage);
    let pick = |c: &Cell| -> Result<(String, Vec<u32>), IssueError> {
        let fault = for_cell(inject, c).map(|i| i.fault);
        let shaders = cell_shaders(c, fault, lanes_in(report, c))
            .map_err(|err| IssueError::Shaders { cell: c.id(), err })?;
        let sh = shaders
            .into_iter()
            .find(|s| s.role == probed_role(c.stage))
            .ok_or_else(|| IssueError::NoProbedShader { cell: c.id() })?;
        Ok((sh.glsl, sh.spirv))
    };
    let (glsl, spirv) = pick(rep)?;
    let dis = spirv_dis(&spirv);
    let file = role.file_name();
    let (glsl_diff, spirv_diff) = match &sibling {
        Some(sib) => {
            let (g2, s2) = pick(sib)?;
            let names = (format!("passing/{file} ({})", sib.id()), format!("failing/{file}"));
            let sd = match (&dis, spirv_dis(&s2)) {
                (Some(a), Some(b)) => unified(&b, a, &names.0, &names.1, Match::SpirvIds),
                _ => None,
            };
            (unified(&g2, &glsl, &names.0, &names.1, Match::Exact), sd)
        }
        None => (None, None),
    };
    Ok(ShaderComparison {
        failing_cell: rep.id(),
        passing_cell: sibling.map(|c| c.id()),
        file: file.to_string(),
        excerpt: excerpt(&glsl),
        glsl,
        glsl_diff,
        spirv: dis.unwrap_or_else(|| "spirv-dis is not installed (SPIRV-Tools): no disassembly; `rtprobe repro` writes the .spv files".into()),
        spirv_diff,
    })
}
