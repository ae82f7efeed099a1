//! `run --shader --entry NAME`: a module with several entry points (DXC and slangc libraries put
//! many in one file) reduced to the one named, so the harness's reflection and the pipeline read
//! that one. The other `OpEntryPoint`s go, with the execution modes of functions no remaining
//! entry point names; their functions stay (unreferenced functions are valid SPIR-V). Entry
//! points of one name in several stages are told apart by the stage the file name says.
use rspirv::dr::{Module, Operand};
use rspirv::spirv::{ExecutionModel, Op};

/// The name of an `OpEntryPoint`.
fn name(i: &rspirv::dr::Instruction) -> Option<&str> {
    match i.operands.get(2) {
        Some(Operand::LiteralString(s)) => Some(s),
        _ => None,
    }
}

/// The execution model of an `OpEntryPoint`.
fn model(i: &rspirv::dr::Instruction) -> Option<ExecutionModel> {
    match i.operands.first() {
        Some(Operand::ExecutionModel(x)) => Some(*x),
        _ => None,
    }
}

/// Keep only the entry point called `entry` (of the stage `stage`, the file name's, where
/// several stages have one of that name); an error names the ones the module has.
pub fn select_entry(
    m: &mut Module,
    entry: &str,
    stage: Option<ExecutionModel>,
) -> Result<(), String> {
    let names: Vec<String> = m.entry_points.iter().filter_map(name).map(String::from).collect();
    let named: Vec<usize> =
        (0..m.entry_points.len()).filter(|k| name(&m.entry_points[*k]) == Some(entry)).collect();
    let chosen: Vec<usize> = match (named.len(), stage) {
        (0 | 1, _) | (_, None) => named.clone(),
        (_, Some(s)) => {
            named.iter().copied().filter(|k| model(&m.entry_points[*k]) == Some(s)).collect()
        }
    };
    let kept = match chosen.as_slice() {
        [k] => m.entry_points[*k].clone(),
        [] if named.is_empty() => {
            return Err(format!(
                "has no entry point {entry:?}; its entry points: {}",
                if names.is_empty() { "none".into() } else { names.join(", ") }
            ))
        }
        _ => {
            let stages: Vec<String> = named
                .iter()
                .filter_map(|k| model(&m.entry_points[*k]))
                .map(crate::reflect::stage_name)
                .collect();
            return Err(format!(
                "has entry points {entry:?} in several stages ({}): name the file for its stage (.rgen, .rchit, .rmiss, …)",
                stages.join(", ")
            ));
        }
    };
    let function = kept.operands.get(1).and_then(|o| o.id_ref_any());
    m.entry_points.retain(|e| *e == kept);
    m.execution_modes.retain(|x| {
        matches!(x.class.opcode, Op::ExecutionMode | Op::ExecutionModeId)
            && x.operands.first().and_then(|o| o.id_ref_any()) == function
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::patches::{assemble, compiled, validate, Validation};

    /// A raygen with a second entry point, `second`, on the same function.
    fn two_entries() -> Module {
        let src = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 0, binding = 0, r32f) uniform image2D img;\n\
            void main() { imageStore(img, ivec2(gl_LaunchIDEXT.xy), vec4(1.0)); }\n";
        let mut m = compiled(shaderc::ShaderKind::RayGeneration, "two.rgen", src);
        let mut second = m.entry_points[0].clone();
        second.operands[2] = Operand::LiteralString("second".into());
        m.entry_points.push(second);
        m
    }

    fn valid(m: &Module) {
        let v = validate(&assemble(m));
        assert!(matches!(v, Validation::Valid | Validation::Unavailable), "{v:?}");
    }

    #[test]
    fn the_named_entry_point_is_the_only_one_left() {
        let mut m = two_entries();
        valid(&m);
        select_entry(&mut m, "second", None).unwrap();
        assert_eq!(m.entry_points.len(), 1);
        assert_eq!(name(&m.entry_points[0]), Some("second"));
        valid(&m);
        let stage = crate::patches::pipeline::stage_of(&m).unwrap();
        assert_eq!(stage, ("raygen".to_string(), "second".to_string()));
    }

    #[test]
    fn an_unknown_entry_point_names_the_ones_there() {
        let mut m = two_entries();
        let e = select_entry(&mut m, "mian", None).unwrap_err();
        assert!(e.contains("\"mian\"") && e.contains("main, second"), "{e}");
        assert_eq!(m.entry_points.len(), 2, "nothing changed");
    }

    #[test]
    fn one_name_in_two_stages_is_picked_by_the_file_names_stage() {
        // `main` twice on the same function: once raygen, once (made up) miss.
        let mut two = two_entries();
        two.entry_points[1].operands[0] = Operand::ExecutionModel(ExecutionModel::MissKHR);
        two.entry_points[1].operands[2] = Operand::LiteralString("main".into());
        let mut m = two.clone();
        let e = select_entry(&mut m, "main", None).unwrap_err();
        assert!(e.contains("several stages (raygen, miss)"), "{e}");
        assert_eq!(m.entry_points.len(), 2, "nothing changed");
        let mut m = two.clone();
        select_entry(&mut m, "main", Some(ExecutionModel::MissKHR)).unwrap();
        assert_eq!(m.entry_points.len(), 1);
        assert_eq!(model(&m.entry_points[0]), Some(ExecutionModel::MissKHR));
        let mut m = two;
        select_entry(&mut m, "main", Some(ExecutionModel::RayGenerationKHR)).unwrap();
        assert_eq!(model(&m.entry_points[0]), Some(ExecutionModel::RayGenerationKHR));
    }
}
