//! Reflection of engine-like shaders written for these tests (a bindless closest-hit, a glTF-style
//! closest-hit reading through buffer references, a struct payload, an intersection with its hit
//! attribute, spec constants, a shader record, a DXC-style module in assembly with two entry
//! points, a heap closest-hit where the sid root's glslang is found); each assertion's twin is a
//! variant missing or changing the thing read.
use super::*;
use crate::patches::compiled;
use rspirv::spirv::ImageFormat;
use shaderc::ShaderKind;

const HEAD: &str = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
    #extension GL_EXT_nonuniform_qualifier : require\n";

fn of(kind: ShaderKind, body: &str) -> Reflection {
    reflect(&compiled(kind, "t.glsl", &format!("{HEAD}{body}")), None).unwrap()
}

const BINDLESS: &str = r#"
struct Material { vec4 albedo; uint texture; uint flags; };
layout(set = 1, binding = 0, std430) readonly buffer Materials { vec4 tint; Material m[]; } materials[];
layout(set = 1, binding = 1) uniform texture2D textures[];
layout(set = 1, binding = 2) uniform sampler linear;
layout(set = 0, binding = 3, r32ui) uniform uimage2D counts;
layout(push_constant) uniform Frame { uint materialBase; uint textureBase; } frame;
layout(location = 0) rayPayloadInEXT vec4 color;
hitAttributeEXT vec2 bary;
void main() {
    uint i = frame.materialBase + gl_InstanceCustomIndexEXT;
    Material mat = materials[nonuniformEXT(i)].m[gl_PrimitiveID];
    vec4 t = textureLod(sampler2D(textures[nonuniformEXT(frame.textureBase + mat.texture)], linear), bary, 0.0);
    imageAtomicAdd(counts, ivec2(gl_LaunchIDEXT.xy), 1u);
    color = mat.albedo * t;
}
"#;

#[test]
fn a_bindless_closest_hit_reads_its_arrays_blocks_and_push_range() {
    let r = of(ShaderKind::ClosestHit, BINDLESS);
    assert_eq!((r.stage.as_str(), r.entry.as_str()), ("closest_hit", "main"));
    let b: Vec<(u32, u32, Descriptor, Count, bool)> =
        r.bindings.iter().map(|b| (b.set, b.binding, b.descriptor, b.count, b.writable)).collect();
    assert_eq!(
        b,
        vec![
            (0, 3, Descriptor::StorageImage(ImageFormat::R32ui), Count::One, true),
            (1, 0, Descriptor::StorageBuffer, Count::Runtime, false),
            (1, 1, Descriptor::SampledImage, Count::Runtime, false),
            (1, 2, Descriptor::Sampler, Count::One, false),
        ]
    );
    assert!(r.bindings[0].atomic && !r.bindings[1].atomic);
    // vec4 tint, then Material (vec4 + 2 uints, std430: 32 bytes) from byte 16
    let block = r.bindings[1].block.as_ref().unwrap();
    assert_eq!(block.tail, Some(Tail { offset: 16, stride: 32, runtime: true }));
    assert_eq!((block.start, block.end), (0, 16));
    let push = r.push.as_ref().unwrap();
    assert_eq!((push.start, push.end, push.ty.members.len()), (0, 8, 2));
    assert_eq!(push.ty.members[1].name, "textureBase");
    // glslang writes no Location on an incoming payload (only the outgoing one's selects it)
    assert_eq!(r.incoming_payload.as_ref().map(|p| (p.location, p.size)), Some((None, 16)));
    assert_eq!(r.hit_attribute.as_ref().map(|h| h.size), Some(8));
    assert!(r.pointers.is_empty() && !r.heap.resource && r.spec_constants.is_empty());
    // Twin: a fixed array of 8 textures, no push block, no hit attribute
    let fixed = BINDLESS
        .replace("uniform texture2D textures[];", "uniform texture2D textures[8];")
        .replace("frame.textureBase + mat.texture", "mat.texture & 7u")
        .replace("frame.materialBase + ", "")
        .replace(
            "layout(push_constant) uniform Frame { uint materialBase; uint textureBase; } frame;",
            "",
        )
        .replace("hitAttributeEXT vec2 bary;", "vec2 bary = vec2(0.5);");
    let r = of(ShaderKind::ClosestHit, &fixed);
    assert_eq!(r.bindings[2].count, Count::Fixed(8));
    assert!(r.push.is_none() && r.hit_attribute.is_none());
}

const GLTF: &str = r#"
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_scalar_block_layout : require
struct Vertex { vec3 position; vec3 normal; vec2 uv; };
layout(buffer_reference, scalar) readonly buffer Vertices { Vertex v[]; };
layout(buffer_reference, scalar) readonly buffer Indices { uvec3 i[]; };
layout(buffer_reference, scalar) readonly buffer Materials { vec4 baseColor[]; };
struct Mesh { Vertices vertices; Indices indices; uint material; uint firstIndex; };
layout(buffer_reference, scalar) readonly buffer SceneDesc { Materials materials; Mesh meshes[]; };
layout(push_constant) uniform Push { SceneDesc scene; uint64_t unconverted; } push;
layout(location = 0) rayPayloadInEXT vec3 color;
hitAttributeEXT vec2 bary;
void main() {
    Mesh mesh = push.scene.meshes[gl_InstanceCustomIndexEXT];
    uvec3 tri = mesh.indices.i[mesh.firstIndex / 3 + gl_PrimitiveID];
    Vertex a = mesh.vertices.v[tri.x];
    color = a.normal * push.scene.materials.baseColor[mesh.material].rgb + float(push.unconverted);
}
"#;

#[test]
fn a_gltf_closest_hit_names_every_pointer_path() {
    let body = GLTF.replace(
        "#extension GL_EXT_buffer_reference : require",
        "#extension GL_EXT_buffer_reference : require\n#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require",
    );
    let r = of(ShaderKind::ClosestHit, &body);
    let paths: Vec<(String, u32, Option<u32>)> =
        r.pointers.iter().map(|p| (p.path.join(" → "), p.size, p.stride)).collect();
    assert_eq!(
        paths,
        vec![
            ("push.scene".to_string(), 8, Some(24)),
            ("push.scene → SceneDesc.materials".to_string(), 0, Some(16)),
            ("push.scene → SceneDesc.meshes[].vertices".to_string(), 0, Some(32)),
            ("push.scene → SceneDesc.meshes[].indices".to_string(), 0, Some(12)),
        ],
        "{paths:#?}"
    );
    // the pointee of the first hop is the scene description struct, by name
    assert!(matches!(&r.pointers[0].pointee, Ty::Struct(s) if s.name == "SceneDesc"));
    // the uint64_t address is no pointer: only typed members count
    assert!(!r.pointers.iter().any(|p| p.path[0].contains("unconverted")));
    // Twin: the scene as a uint64_t address converted in the shader has no paths at all
    let converted = body
        .replace("SceneDesc scene;", "uint64_t scene;")
        .replace("push.scene.", "SceneDesc(push.scene).");
    assert!(of(ShaderKind::ClosestHit, &converted).pointers.is_empty());
}

const STRUCT_PAYLOAD: &str = r#"
struct Hit { vec3 normal; float t; };
struct Shade { Hit hit; vec3 color; uint bounces[3]; int material; };
layout(location = 2) rayPayloadInEXT Shade shade;
void main() { shade.hit.t = gl_HitTEXT; shade.color = vec3(1.0); shade.bounces[1] += 1u; shade.material = -1; }
"#;

#[test]
fn a_struct_payload_is_a_type_tree_with_its_location_and_size() {
    let r = of(ShaderKind::ClosestHit, STRUCT_PAYLOAD);
    let p = r.incoming_payload.unwrap();
    // Hit: 12 + 4; color 12; 3 uints; int: 16 + 12 + 12 + 4 at scalar alignment
    assert_eq!((p.location, p.size, p.ty.scalars()), (None, 44, 11));
    let Ty::Struct(s) = &p.ty else { panic!("{:?}", p.ty) };
    let names: Vec<&str> = s.members.iter().map(|m| m.name.as_str()).collect();
    assert_eq!((s.name.as_str(), names), ("Shade", vec!["hit", "color", "bounces", "material"]));
    assert!(matches!(&s.members[0].ty, Ty::Struct(h) if h.name == "Hit" && h.members.len() == 2));
    assert_eq!(s.members[1].ty, Ty::Vector(Scalar::Float { bits: 32 }, 3));
    assert!(matches!(&s.members[2].ty, Ty::Array { len: 3, .. }));
    // Twin: a vec4 color is 4 bytes more and one scalar more
    let r = of(
        ShaderKind::ClosestHit,
        &STRUCT_PAYLOAD.replace("vec3 color;", "vec4 color;").replace("vec3(1.0)", "vec4(1.0)"),
    );
    let p = r.incoming_payload.unwrap();
    assert_eq!((p.size, p.ty.scalars()), (48, 12));
}

/// The GLSL a type prints as compiles into a payload of the same shape (a round trip).
#[test]
fn a_type_prints_as_glsl_that_compiles_back_to_the_same_shape() {
    let p = of(ShaderKind::ClosestHit, STRUCT_PAYLOAD).incoming_payload.unwrap();
    let mut g = glsl::Glsl::default();
    let decl = g.declare(&p.ty, "mirror").unwrap();
    let src = format!(
        "{}layout(location = 0) rayPayloadEXT {decl};\n\
         layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;\n\
         void main() {{ traceRayEXT(tlas, 0u, 0xFF, 0, 0, 0, vec3(0), 0.0, vec3(1), 1.0, 0); }}\n",
        g.preamble()
    );
    let r = of(ShaderKind::RayGeneration, &src);
    assert_eq!(r.payloads[0].ty.shape(), p.ty.shape(), "{src}");
    // KHR SPIR-V names the payload variable in OpTraceRayKHR: glslang writes no Location
    assert_eq!((r.payloads[0].size, r.payloads[0].location), (p.size, None));
    assert!(src.find("struct Hit").unwrap() < src.find("struct Shade").unwrap(), "{src}");
    // Twin: another type's shape differs
    assert_ne!(Ty::Vector(Scalar::Float { bits: 32 }, 4).shape(), p.ty.shape());
    // names made unique and valid
    assert_eq!(glsl::ident("type.ConstantBuffer.X", "S"), "type_ConstantBuffer_X");
    assert_eq!(glsl::ident("gl_Thing", "S"), "xgl_Thing");
    assert_eq!(glsl::ident("", "S"), "S");
    assert_eq!(glsl::ident("sample", "S"), "sample_");
}

#[test]
fn an_intersection_writes_its_hit_attribute_struct() {
    let body = "struct Sphere { vec3 normal; float u; uint face; };\nhitAttributeEXT Sphere attr;\n\
        void main() { attr.normal = vec3(0, 0, 1); attr.face = 2u; reportIntersectionEXT(1.0, 0u); }\n";
    let r = of(ShaderKind::Intersection, body);
    assert_eq!(r.stage, "intersection");
    let h = r.hit_attribute.unwrap();
    assert_eq!((h.size, h.location), (20, None));
    assert!(matches!(&h.ty, Ty::Struct(s) if s.name == "Sphere" && s.members.len() == 3));
    // Twin: two floats
    let r = of(ShaderKind::Intersection, "hitAttributeEXT vec2 uv;\nvoid main() { uv = vec2(0.5); reportIntersectionEXT(1.0, 0u); }\n");
    assert_eq!(r.hit_attribute.unwrap().size, 8);
}

#[test]
fn spec_constants_have_their_id_type_and_default() {
    let body = "layout(constant_id = 7) const uint MAX_BOUNCES = 4u;\n\
        layout(constant_id = 2) const float EXPOSURE = 1.5;\n\
        layout(constant_id = 3) const bool SHADOWS = true;\n\
        layout(constant_id = 4) const int BIAS = -3;\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() { c = vec4(float(MAX_BOUNCES) * EXPOSURE, SHADOWS ? 1.0 : 0.0, float(BIAS), 0.0); }\n";
    let r = of(ShaderKind::Miss, body);
    let s: Vec<(u32, &str, Scalar, u64)> = r
        .spec_constants
        .iter()
        .map(|s| (s.spec_id, s.name.as_str(), s.scalar, s.default))
        .collect();
    assert_eq!(
        s,
        vec![
            (2, "EXPOSURE", Scalar::Float { bits: 32 }, 1.5f32.to_bits() as u64),
            (3, "SHADOWS", Scalar::Bool, 1),
            (4, "BIAS", Scalar::Int { bits: 32, signed: true }, (-3i32) as u32 as u64),
            (7, "MAX_BOUNCES", Scalar::Int { bits: 32, signed: false }, 4),
        ]
    );
    // Twin: plain constants are none
    let plain = body
        .replace("layout(constant_id = 7) ", "")
        .replace("layout(constant_id = 2) ", "")
        .replace("layout(constant_id = 3) ", "")
        .replace("layout(constant_id = 4) ", "");
    assert!(of(ShaderKind::Miss, &plain).spec_constants.is_empty());
}

#[test]
fn the_shader_record_block_has_its_members_and_offsets() {
    let body = "#extension GL_EXT_buffer_reference : require\n\
        layout(buffer_reference, std430) readonly buffer Colors { vec4 c[]; };\n\
        layout(shaderRecordEXT, std430) buffer Record { uint material; vec4 tint; Colors colors; } record;\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() { c = record.tint * float(record.material) + record.colors.c[gl_PrimitiveID]; }\n";
    let r = of(ShaderKind::ClosestHit, body);
    let rec = r.record.unwrap();
    let m: Vec<(&str, Option<u32>)> =
        rec.ty.members.iter().map(|m| (m.name.as_str(), m.offset)).collect();
    assert_eq!(m, vec![("material", Some(0)), ("tint", Some(16)), ("colors", Some(32))]);
    assert_eq!(rec.end, 40);
    assert_eq!(r.pointers[0].path, vec!["record.colors".to_string()]);
    assert_eq!(r.pointers[0].stride, Some(16));
    // Twin: without it, none
    assert!(of(
        ShaderKind::ClosestHit,
        "layout(location = 0) rayPayloadInEXT vec4 c;\nvoid main() { c = vec4(1); }\n"
    )
    .record
    .is_none());
}

/// A DXC-style module (written here as assembly): a `type.ConstantBuffer.Camera` block in the
/// Uniform storage class, a `type.RWStructuredBuffer.float` as a storage buffer, two entry points.
const DXC: &str = r#"
               OpCapability RayTracingKHR
               OpExtension "SPV_KHR_ray_tracing"
               OpMemoryModel Logical GLSL450
               OpEntryPoint MissKHR %sky "Sky" %cam %payload
               OpEntryPoint MissKHR %shadow "Shadow" %out %payload
               OpName %type_ConstantBuffer_Camera "type.ConstantBuffer.Camera"
               OpMemberName %type_ConstantBuffer_Camera 0 "exposure"
               OpName %type_RWStructuredBuffer_float "type.RWStructuredBuffer.float"
               OpName %cam "Camera"
               OpName %out "Out"
               OpDecorate %cam DescriptorSet 0
               OpDecorate %cam Binding 0
               OpDecorate %out DescriptorSet 0
               OpDecorate %out Binding 1
               OpMemberDecorate %type_ConstantBuffer_Camera 0 Offset 0
               OpDecorate %type_ConstantBuffer_Camera Block
               OpDecorate %_runtimearr_float ArrayStride 4
               OpMemberDecorate %type_RWStructuredBuffer_float 0 Offset 0
               OpDecorate %type_RWStructuredBuffer_float Block
               OpDecorate %payload Location 0
       %void = OpTypeVoid
      %float = OpTypeFloat 32
        %int = OpTypeInt 32 1
      %int_0 = OpConstant %int 0
    %float_1 = OpConstant %float 1
%type_ConstantBuffer_Camera = OpTypeStruct %float
%_ptr_Uniform_Camera = OpTypePointer Uniform %type_ConstantBuffer_Camera
%_runtimearr_float = OpTypeRuntimeArray %float
%type_RWStructuredBuffer_float = OpTypeStruct %_runtimearr_float
%_ptr_SB_out = OpTypePointer StorageBuffer %type_RWStructuredBuffer_float
%_ptr_Uniform_float = OpTypePointer Uniform %float
%_ptr_SB_float = OpTypePointer StorageBuffer %float
%_ptr_Payload_float = OpTypePointer IncomingRayPayloadKHR %float
         %fn = OpTypeFunction %void
        %cam = OpVariable %_ptr_Uniform_Camera Uniform
        %out = OpVariable %_ptr_SB_out StorageBuffer
    %payload = OpVariable %_ptr_Payload_float IncomingRayPayloadKHR
        %sky = OpFunction %void None %fn
         %l1 = OpLabel
         %p1 = OpAccessChain %_ptr_Uniform_float %cam %int_0
         %e1 = OpLoad %float %p1
               OpStore %payload %e1
               OpReturn
               OpFunctionEnd
     %shadow = OpFunction %void None %fn
         %l2 = OpLabel
         %p2 = OpAccessChain %_ptr_SB_float %out %int_0 %int_0
               OpStore %p2 %float_1
               OpStore %payload %float_1
               OpReturn
               OpFunctionEnd
"#;

fn assembled(src: &str) -> Option<Module> {
    let d = crate::tempdir::tempdir().ok()?;
    let (s, o) = (d.path().join("m.spvasm"), d.path().join("m.spv"));
    std::fs::write(&s, src).ok()?;
    if crate::tools::spirv::tool(crate::tools::spirv::SpirvTool::As).is_none() {
        eprintln!("skipped: no spirv-as");
        return None;
    }
    crate::tools::spirv::assemble(&s, &o, "vulkan1.2").unwrap();
    Some(crate::patches::load(&std::fs::read(&o).unwrap()).unwrap())
}

#[test]
fn a_dxc_module_with_two_entry_points_needs_one_named() {
    let Some(m) = assembled(DXC) else { return };
    let e = reflect(&m, None).unwrap_err();
    assert_eq!(e, ReflectError::SeveralEntries(vec!["Sky".into(), "Shadow".into()]));
    assert!(e.to_string().contains("Sky, Shadow") && e.to_string().contains("--entry"), "{e}");
    let e = reflect(&m, Some("Sun")).unwrap_err();
    assert!(matches!(e, ReflectError::NoSuchEntry { .. }), "{e}");
    // each entry point sees the binding its function uses
    let sky = reflect(&m, Some("Sky")).unwrap();
    assert_eq!(sky.stage, "miss");
    assert_eq!(
        sky.bindings.iter().map(|b| (b.binding, b.descriptor)).collect::<Vec<_>>(),
        vec![(0, Descriptor::UniformBuffer)]
    );
    let block = sky.bindings[0].block.as_ref().unwrap();
    let mut g = glsl::Glsl::default();
    let text = g.block("set = 0, binding = 0", "uniform", &block.ty, "camera").unwrap();
    assert!(
        text.contains("type_ConstantBuffer_Camera_ {")
            && text.contains("layout(offset = 0) float exposure;"),
        "{text}"
    );
    let shadow = reflect(&m, Some("Shadow")).unwrap();
    let b = &shadow.bindings;
    assert_eq!(
        (b.len(), b[0].binding, b[0].descriptor, b[0].writable),
        (1, 1, Descriptor::StorageBuffer, true)
    );
    assert_eq!(
        b[0].block.as_ref().unwrap().tail,
        Some(Tail { offset: 0, stride: 4, runtime: true })
    );
}

/// The DXC module reduced to one entry point (as `run --shader --entry` reduces it): its
/// reflection still counts only the globals that entry point's call tree uses.
#[test]
fn a_single_entry_point_left_in_a_library_sees_only_its_globals() {
    let Some(mut m) = assembled(DXC) else { return };
    m.entry_points
        .retain(|e| matches!(e.operands.get(2), Some(Operand::LiteralString(n)) if n == "Sky"));
    let sky = reflect(&m, None).unwrap();
    assert_eq!(sky.entry, "Sky");
    assert_eq!(
        sky.bindings.iter().map(|b| (b.binding, b.descriptor)).collect::<Vec<_>>(),
        vec![(0, Descriptor::UniformBuffer)],
        "Shadow's storage buffer is not Sky's"
    );
}

/// Any bytes — garbage, a truncated module, a module cut at every word — give a typed error or a
/// reflection, never a panic.
#[test]
fn arbitrary_and_truncated_bytes_never_panic() {
    assert!(matches!(reflect_words(&[1, 2, 3], None), Err(ReflectError::NotSpirv(_))));
    let m = compiled(ShaderKind::ClosestHit, "t", &format!("{HEAD}{GLTF}").replace(
        "#extension GL_EXT_buffer_reference : require",
        "#extension GL_EXT_buffer_reference : require\n#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require"));
    let words = rspirv::binary::Assemble::assemble(&m);
    for cut in 0..words.len() {
        let _ = reflect_words(&words[..cut], None);
    }
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..2000 {
        let mut w = words.clone();
        for _ in 0..4 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let k = 5 + (seed as usize) % (w.len() - 5);
            w[k] = (seed >> 32) as u32 & if seed & 1 == 0 { 0xffff } else { u32::MAX };
        }
        let _ = reflect_words(&w, None);
    }
    assert_eq!(reflect_words(&words, None).unwrap().pointers.len(), 4);
}

/// A heap closest-hit (`layout(descriptor_heap)`, the sid root's glslang): both heaps, the
/// capability, and each access's element type and stride (the descriptor size).
#[test]
fn a_heap_closest_hit_reads_its_heaps_and_strides() {
    let glsl = format!(
        "{HEAD}#extension GL_EXT_descriptor_heap : require\n\
        layout(descriptor_heap) buffer Mat {{ vec4 albedo[]; }} mats[];\n\
        layout(descriptor_heap) uniform texture2D texs[];\n\
        layout(descriptor_heap) uniform sampler samps[];\n\
        layout(location = 0) rayPayloadInEXT vec4 c;\n\
        void main() {{ c = mats[gl_InstanceCustomIndexEXT].albedo[gl_PrimitiveID] + \
        textureLod(sampler2D(texs[gl_InstanceCustomIndexEXT + 3], samps[1]), vec2(0.5), 0.0); }}\n"
    );
    let words = match crate::shadergen::glslang::compile_with(
        "h.rchit",
        "rchit",
        &glsl,
        "GL_EXT_descriptor_heap",
        &["--target-env", "vulkan1.3"],
    ) {
        Ok(w) => w,
        Err(e) => return eprintln!("skipped: {e}"),
    };
    let r = reflect_words(&words, None).unwrap();
    assert!(r.heap.capability && r.heap.resource && r.heap.sampler, "{:?}", r.heap);
    let a: Vec<(HeapKind, &str, &HeapStride)> =
        r.heap.accesses.iter().map(|a| (a.heap, a.element.as_str(), &a.stride)).collect();
    assert!(
        a.contains(&(
            HeapKind::Resource,
            "StorageBuffer buffer",
            &HeapStride::SizeOf("StorageBuffer buffer".into())
        )),
        "{a:?}"
    );
    assert!(a.iter().any(|x| x.0 == HeapKind::Resource && x.1 == "sampled image"), "{a:?}");
    assert!(a.iter().any(|x| x.0 == HeapKind::Sampler && x.1 == "sampler"), "{a:?}");
    assert!(r.bindings.is_empty());
    // Twin: a set/binding module has no heap
    let plain = of(ShaderKind::ClosestHit, BINDLESS);
    assert!(!plain.heap.capability && plain.heap.accesses.is_empty());
}
