//! The classifier on modules assembled for these tests.
use super::*;
use crate::model::IndexSource;

/// A closest-hit reading `mats[base + gl_InstanceCustomIndexEXT]` (an SSBO array), `base` from
/// push constants, the index `NonUniform` when `nonuniform`; the index replaced by `index` when given.
fn module(nonuniform: bool, index: Option<&str>) -> Module {
    let dec = if nonuniform { "OpDecorate %idx NonUniform\n" } else { "" };
    let idx = index.unwrap_or("%idx");
    let text = format!(
        "OpCapability RayTracingKHR
OpCapability RuntimeDescriptorArray
OpCapability StorageBufferArrayNonUniformIndexing
OpExtension \"SPV_KHR_ray_tracing\"
OpExtension \"SPV_EXT_descriptor_indexing\"
OpMemoryModel Logical GLSL450
OpEntryPoint ClosestHitKHR %main \"main\" %mats %cidx %pc
OpName %mats \"mats\"
OpDecorate %mats DescriptorSet 1
OpDecorate %mats Binding 0
OpDecorate %cidx BuiltIn InstanceCustomIndexKHR
OpDecorate %Mat Block
OpMemberDecorate %Mat 0 Offset 0
OpDecorate %Pc Block
OpMemberDecorate %Pc 0 Offset 0
{dec}%void = OpTypeVoid
%fn = OpTypeFunction %void
%uint = OpTypeInt 32 0
%int = OpTypeInt 32 1
%Mat = OpTypeStruct %uint
%rt = OpTypeRuntimeArray %Mat
%prt = OpTypePointer StorageBuffer %rt
%mats = OpVariable %prt StorageBuffer
%pu = OpTypePointer StorageBuffer %uint
%pint = OpTypePointer Input %int
%cidx = OpVariable %pint Input
%Pc = OpTypeStruct %uint
%ppc = OpTypePointer PushConstant %Pc
%pc = OpVariable %ppc PushConstant
%ppcu = OpTypePointer PushConstant %uint
%int_0 = OpConstant %int 0
%uint_7 = OpConstant %uint 7
%uint_99 = OpConstant %uint 99
%und = OpUndef %uint
%main = OpFunction %void None %fn
%l = OpLabel
%bp = OpAccessChain %ppcu %pc %int_0
%base = OpLoad %uint %bp
%ci = OpLoad %int %cidx
%ciu = OpBitcast %uint %ci
%idx = OpIAdd %uint %base %ciu
%p = OpAccessChain %pu %mats {idx} %int_0
%v = OpLoad %uint %p
OpReturn
OpFunctionEnd
"
    );
    let words = assemble(&text);
    rspirv::dr::load_words(&words).unwrap()
}

fn assemble(text: &str) -> Vec<u32> {
    let dir = crate::tempdir::tempdir().unwrap();
    let (src, out) = (dir.path().join("m.spvasm"), dir.path().join("m.spv"));
    std::fs::write(&src, text).unwrap();
    crate::tools::spirv::assemble(&src, &out, "vulkan1.2").unwrap();
    let b = std::fs::read(&out).unwrap();
    b.chunks(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

#[test]
fn a_bindless_read_is_dynamic_from_the_custom_index_and_push_constants() {
    let found = classify(&module(true, None));
    assert_eq!(found.len(), 1, "{found:?}");
    let c = &found[0].class;
    assert_eq!(
        (c.stage, c.resource, c.index),
        (Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic)
    );
    assert_eq!(c.index_from, ["gl_InstanceCustomIndexEXT", "push_constant"]);
    assert!(c.nonuniform);
    assert_eq!((c.set, c.binding, c.variable.as_str()), (Some(1), Some(0), "mats"));
    assert_eq!(
        crate::model::reduce::predicate(std::slice::from_ref(c)),
        "stage=closest_hit,resource=storage_buffer,index=dynamic"
    );
    let text = render::render(&module(true, None), &found);
    assert!(text.contains("mats[nonuniformEXT((%"), "{text}");
}

#[test]
fn twins_a_literal_index_and_no_nonuniform() {
    let found = classify(&module(false, Some("%uint_7")));
    let c = &found[0].class;
    assert_eq!((c.index, c.nonuniform), (IndexSource::Literal, false));
    assert_eq!(c.index_from, ["literal"]);
}

#[test]
fn undefined_and_constant_past_the_array_indices_are_refused() {
    assert_eq!(bounds::check(&module(true, None), 64), Ok(()));
    assert_eq!(bounds::check(&module(false, Some("%uint_7")), 64), Ok(()));
    let e = bounds::check(&module(false, Some("%und")), 64).unwrap_err();
    assert!(matches!(e, bounds::OutOfBounds::Undef { .. }), "{e}");
    let e = bounds::check(&module(false, Some("%uint_99")), 64).unwrap_err();
    assert_eq!(e.to_string(), "mats[99]: a constant index past its 64 descriptors");
    assert_eq!(bounds::check(&module(false, Some("%uint_99")), 100), Ok(()));
}

#[test]
fn function_bodies_count_from_op_function_to_op_function_end() {
    // OpFunction, OpLabel, 7 instructions, OpReturn, OpFunctionEnd.
    assert_eq!(count::function_body(&module(true, None)), 11);
}

#[test]
fn an_undefined_image_handle_is_refused() {
    let text = "OpCapability Shader
OpCapability StorageImageReadWithoutFormat
OpMemoryModel Logical GLSL450
OpEntryPoint GLCompute %main \"main\"
OpExecutionMode %main LocalSize 1 1 1
%void = OpTypeVoid
%fn = OpTypeFunction %void
%float = OpTypeFloat 32
%v4 = OpTypeVector %float 4
%int = OpTypeInt 32 1
%v2 = OpTypeVector %int 2
%img = OpTypeImage %float 2D 0 0 0 2 Unknown
%u = OpUndef %img
%c = OpConstantNull %v2
%main = OpFunction %void None %fn
%l = OpLabel
%r = OpImageRead %v4 %u %c
OpReturn
OpFunctionEnd
";
    let m = rspirv::dr::load_words(assemble(text)).unwrap();
    let e = bounds::check(&m, 64).unwrap_err();
    assert!(matches!(e, bounds::OutOfBounds::UndefHandle { what: "image", .. }), "{e}");
}

#[test]
fn dead_decorated_loads_go_with_their_decorations_and_live_ones_stay() {
    let mut m = module(true, None);
    // %v is loaded and used by nothing: it goes, then %p, %idx (NonUniform), and so on.
    let n = dead::strip(&mut m);
    assert_eq!(n, 7, "every instruction but OpReturn");
    assert!(m
        .annotations
        .iter()
        .all(|a| a.operands.get(1) != Some(&Operand::Decoration(Decoration::NonUniform))));
    assert!(classify(&m).is_empty());
    // Twin: nothing dead, nothing removed.
    let mut again = m.clone();
    assert_eq!(dead::strip(&mut again), 0);
}

/// Issue 25: DXC's `NonUniformResourceIndex(InstanceID() % 3)` is an `OpUMod` decorated
/// `NonUniform`; once its access is gone, it goes too (it stayed, one instruction over the
/// DXC closest-hit's third).
#[test]
fn dead_decorated_arithmetic_of_any_kind_goes() {
    for op in [Op::UMod, Op::UDiv, Op::ShiftRightLogical, Op::BitwiseXor] {
        let mut m = module(true, None);
        let body = m.functions[0].blocks[0].instructions.iter_mut();
        let add = body.into_iter().find(|i| i.class.opcode == Op::IAdd).unwrap();
        *add =
            rspirv::dr::Instruction::new(op, add.result_type, add.result_id, add.operands.clone());
        assert_eq!(dead::strip(&mut m), 7, "{op:?}: every instruction but OpReturn");
    }
}

/// A raygen's storage image, `write` only (`OpImageWrite`) or also read (`OpImageRead`).
fn storage_image(read: bool) -> Module {
    let read = if read { "%t = OpImageRead %v4 %h %c\n" } else { "" };
    let text = format!(
        "OpCapability RayTracingKHR
OpCapability StorageImageReadWithoutFormat
OpExtension \"SPV_KHR_ray_tracing\"
OpMemoryModel Logical GLSL450
OpEntryPoint RayGenerationKHR %main \"main\" %target
OpDecorate %target DescriptorSet 0
OpDecorate %target Binding 1
%void = OpTypeVoid
%fn = OpTypeFunction %void
%float = OpTypeFloat 32
%int = OpTypeInt 32 1
%v4 = OpTypeVector %float 4
%v2i = OpTypeVector %int 2
%img = OpTypeImage %float 2D 0 0 0 2 Unknown
%pimg = OpTypePointer UniformConstant %img
%target = OpVariable %pimg UniformConstant
%c = OpConstantNull %v2i
%zero = OpConstantNull %v4
%main = OpFunction %void None %fn
%l = OpLabel
%h = OpLoad %img %target
{read}OpImageWrite %h %c %zero
OpReturn
OpFunctionEnd
"
    );
    rspirv::dr::load_words(assemble(&text)).unwrap()
}

/// Issue 25: a raygen's colour target, only written, is no read: the reduced raygen's
/// predicate names its uniform buffer alone. Twin: an image read through the same handle is.
#[test]
fn a_storage_image_only_written_is_no_access() {
    assert!(classify(&storage_image(false)).is_empty());
    let read = classify(&storage_image(true));
    assert_eq!(read.len(), 1, "{read:?}");
    assert_eq!(read[0].class.resource, Resource::StorageImage);
}

/// Issue 25: the heap closest-hit's reads are classified through the heap: storage buffers of
/// `resource_heap`, their indices dynamic from the custom index, the material's from push
/// data too.
#[test]
fn descriptor_heap_reads_are_classified_through_the_heap() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/heap/heap.rchit.spv");
    let m = crate::patches::load(&std::fs::read(path).unwrap()).unwrap();
    let found = classify(&m);
    assert_eq!(found.len(), 4, "{found:?}");
    for c in found.iter().map(|f| &f.class) {
        assert_eq!((c.resource, c.index), (Resource::StorageBuffer, IndexSource::Dynamic), "{c:?}");
        assert_eq!((c.through.as_str(), c.variable.as_str()), ("heap", "resource_heap"));
        assert_eq!((c.set, c.binding), (None, None));
        assert!(c.index_from.iter().any(|f| f == "gl_InstanceCustomIndexEXT"), "{c:?}");
    }
    let pushed = found.iter().filter(|f| f.class.index_from.iter().any(|x| x == "push_constant"));
    assert_eq!(pushed.count(), 1, "the material's index alone reads push data");
}

/// Issue 25: a heap reduction kept a heap index loaded from a never-written local (an undefined
/// index): refused like a descriptor array's. Twin: heap.rchit as compiled passes.
#[test]
fn an_undefined_heap_index_is_refused() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/heap/heap.rchit.spv");
    let mut m = crate::patches::load(&std::fs::read(path).unwrap()).unwrap();
    assert_eq!(bounds::check(&m, 64), Ok(()));
    let body = m.functions[0].blocks.iter().flat_map(|b| &b.instructions);
    let chain = body.clone().find(|i| i.class.opcode == Op::UntypedAccessChainKHR).unwrap();
    let Some(Operand::IdRef(index)) = chain.operands.get(2).cloned() else { panic!() };
    let ty = body.clone().find(|i| i.result_id == Some(index)).and_then(|i| i.result_type).unwrap();
    let undef = crate::patches::edit::next_id(&mut m);
    m.types_global_values.push(rspirv::dr::Instruction::new(
        Op::Undef,
        Some(ty),
        Some(undef),
        vec![],
    ));
    for b in &mut m.functions[0].blocks {
        for i in b.instructions.iter_mut().filter(|i| i.class.opcode == Op::UntypedAccessChainKHR) {
            i.operands[2] = Operand::IdRef(undef);
        }
    }
    let e = bounds::check(&m, 64).unwrap_err();
    assert!(matches!(e, bounds::OutOfBounds::Undef { .. }), "{e}");
}

#[test]
fn an_index_read_from_a_never_written_local_is_undefined() {
    let text = |store: &str| {
        format!(
            "OpCapability Shader
OpCapability RuntimeDescriptorArray
OpExtension \"SPV_EXT_descriptor_indexing\"
OpMemoryModel Logical GLSL450
OpEntryPoint GLCompute %main \"main\" %mats
OpExecutionMode %main LocalSize 1 1 1
OpDecorate %mats DescriptorSet 0
OpDecorate %mats Binding 0
OpDecorate %Mat Block
OpMemberDecorate %Mat 0 Offset 0
%void = OpTypeVoid
%fn = OpTypeFunction %void
%uint = OpTypeInt 32 0
%Mat = OpTypeStruct %uint
%rt = OpTypeRuntimeArray %Mat
%prt = OpTypePointer StorageBuffer %rt
%mats = OpVariable %prt StorageBuffer
%pu = OpTypePointer StorageBuffer %uint
%pf = OpTypePointer Function %uint
%uint_0 = OpConstant %uint 0
%uint_3 = OpConstant %uint 3
%main = OpFunction %void None %fn
%l = OpLabel
%local = OpVariable %pf Function
{store}%x = OpLoad %uint %local
%idx = OpIAdd %uint %uint_3 %x
%p = OpAccessChain %pu %mats %idx %uint_0
%v = OpLoad %uint %p
OpReturn
OpFunctionEnd
"
        )
    };
    let never = rspirv::dr::load_words(assemble(&text(""))).unwrap();
    let e = bounds::check(&never, 64).unwrap_err();
    assert!(matches!(e, bounds::OutOfBounds::Undef { .. }), "{e}");
    // Twin: the local written with a constant first is a literal index, in bounds.
    let written = rspirv::dr::load_words(assemble(&text("OpStore %local %uint_3\n"))).unwrap();
    assert_eq!(bounds::check(&written, 64), Ok(()));
    assert_eq!(classify(&written)[0].class.index, IndexSource::Literal);
}

/// A shadow ray through a TLAS and a ray query through an AS array element (GLSL written for
/// this test).
const AS_HIT: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_EXT_ray_query : require
layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 1) uniform accelerationStructureEXT cascades[2];
layout(location = 0) rayPayloadInEXT vec4 shade;
layout(location = 1) rayPayloadEXT bool shadowed;
void main() {
    traceRayEXT(tlas, 4u, 0xFF, 0, 0, 1, vec3(0.0), 0.01, vec3(0.0, 1.0, 0.0), 100.0, 1);
    rayQueryEXT q;
    rayQueryInitializeEXT(q, cascades[1], 4u, 0xFF, vec3(0.0), 0.01, vec3(0.0, 1.0, 0.0), 100.0);
    rayQueryProceedEXT(q);
    shade = vec4(shadowed ? 0.2 : 1.0);
}
"#;

/// An acceleration structure read renders as the call that traces with it (a buffer's
/// `... = NAME...;` said nothing of a handle); after `as-to-address` as one made from its
/// address. Twin: a handle no trace uses renders bare.
#[test]
fn an_acceleration_structure_read_renders_as_its_trace() {
    use crate::patches::{compiled, PatchName};
    let m = compiled(shaderc::ShaderKind::ClosestHit, "as.rchit", AS_HIT);
    let found = classify(&m);
    assert_eq!(found.len(), 2, "{found:?}");
    let text = render::render(&m, &found);
    for part in [
        "layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;",
        "traceRayEXT(tlas, ...);",
        "uniform accelerationStructureEXT cascades[];",
        "rayQueryInitializeEXT(q, cascades[1u], ...);",
    ] {
        assert!(text.contains(part), "{part}: {text}");
    }
    assert!(!text.contains("... = tlas"), "{text}");
    let mut patched = m.clone();
    crate::patches::apply(&mut patched, &[PatchName::AsToAddress], &Default::default()).unwrap();
    let found = classify(&patched);
    assert!(found.iter().all(|f| f.class.through == "address"), "{found:?}");
    let text = render::render(&patched, &found);
    assert!(text.contains("traceRayEXT(accelerationStructureEXT(%"), "{text}");
    // Twin: the trace removed, the load renders bare.
    let mut bare = m.clone();
    for f in bare.functions.iter_mut() {
        for b in f.blocks.iter_mut() {
            b.instructions.retain(|i| i.class.opcode != Op::TraceRayKHR);
        }
    }
    let text = render::render(&bare, &classify(&bare));
    assert!(text.contains("... tlas ...;") && !text.contains("traceRayEXT"), "{text}");
}
