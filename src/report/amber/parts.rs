//! The parts every rtprobe Amber script shares: a shader as `SPIRV-HEX` with its GLSL as
//! comments, the records `STRUCT` (generated from `probe::RECORD_FIELDS`) and its buffer, the
//! push constants, the probed descriptor array's buffers, and numbers as AmberScript's tokenizer
//! reads them back exactly.
use crate::model::{Resource, SceneParams};
use crate::probe::spec::ProbeSpec;
use crate::probe::{self, RECORD_FIELDS, RECORD_SIZE};
use crate::report::shaders::Shader;

/// Set and binding of the records buffer and of the probed array (`shadergen::probe_code`; a
/// test holds the generated GLSL to them), and of the scene TLAS of ray tracing pipelines.
pub const RECORDS_BINDING: u32 = 0;
pub const TLAS_BINDING: u32 = 1;
pub const PROBE_BINDING: u32 = 2;

/// The name of the records `STRUCT` and of its buffer.
pub const RECORD_STRUCT: &str = "record";
pub const RECORDS: &str = "records";

/// An f32 as AmberScript reads it back exactly: the shortest round-trip form, always with a `.`
/// (AmberScript's tokenizer reads a number without one as an integer: `1e-7` would be `1`).
pub fn fmt_f32(v: f32) -> String {
    let s = format!("{v:?}");
    match (s.contains('.'), s.find('e')) {
        (true, _) | (false, None) => s,
        (false, Some(e)) => format!("{}.0{}", &s[..e], &s[e..]),
    }
}

/// Little-endian bytes as AmberScript uint32 values.
pub fn u32_words(bytes: &[u8]) -> Vec<String> {
    bytes.chunks(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]).to_string()).collect()
}

/// `SHADER {kind} {name} SPIRV-HEX` with the exact binary, the GLSL before it as comments.
pub fn shader(kind: &str, name: &str, s: &Shader) -> String {
    let mut out = format!("# {name}: the GLSL rtprobe generated ({}", s.compiler);
    if !s.patched.is_empty() {
        out += &format!(", then patched with {}", s.patched.join(", "));
    }
    out += "):\n";
    for l in s.glsl.lines() {
        out += &format!("#   {l}\n");
    }
    out += &format!("SHADER {kind} {name} SPIRV-HEX\n");
    let lines: Vec<String> = crate::report::shaders::spirv_bytes(&s.spirv)
        .chunks(32)
        .map(|chunk| chunk.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" "))
        .collect();
    // `END` right after the last byte: Amber's ParseHex (src/shader_compiler.cc) loops forever
    // on whitespace after the last number (strtol makes no progress there) until it runs out of
    // memory, and the shader's text is everything up to `END`.
    out + &lines.join("\n") + "END\n\n"
}

/// The AmberScript type of a record member's GLSL type.
fn member_type(glsl: &str) -> &'static str {
    match glsl {
        "uint" => "uint32",
        "float" => "float",
        "vec2" => "vec2<float>",
        "vec4" => "vec4<float>",
        other => unreachable!("probe::Record has no {other} member"),
    }
}

/// The records `STRUCT` (each member at its `probe::Record` offset) and the records buffer, one
/// record per pixel, every uint32 member filled with 0xffffffff (floats 0) so that a record no
/// shader wrote reads flags 0xffffffff.
pub fn records(scene: &SceneParams) -> String {
    let mut s = format!(
        "# Records: one {RECORD_SIZE}-byte probe::Record per pixel, pixel (x, y) at record x + y * {}.\n",
        scene.width
    );
    s += &format!("STRUCT {RECORD_STRUCT} STRIDE {RECORD_SIZE}\n");
    for f in RECORD_FIELDS {
        s += &format!("  {} {} OFFSET {}\n", member_type(f.glsl_type), f.glsl_name, f.offset);
    }
    s += "END\n";
    s += &format!(
        "BUFFER {RECORDS} DATA_TYPE {RECORD_STRUCT} STD430 SIZE {} FILL 4294967295\n",
        scene.pixels()
    );
    s
}

/// The push constants as rtprobe sets them (`probe::push_constants`), as a uint32 buffer.
pub fn push_constants(spec: &ProbeSpec, scene: &SceneParams) -> String {
    let pc = probe::push_constants(scene.width, scene.height, scene.instances, spec.resource);
    let pc_words = u32_words(&pc.to_bytes(0)[..probe::PUSH_BLOCK_BYTES as usize]);
    let names: Vec<String> = probe::PUSH_FIELDS
        .iter()
        .map(|f| {
            if f.glsl_type == "uvec2" {
                format!("{}.xy", f.glsl_name)
            } else {
                f.glsl_name.to_string()
            }
        })
        .collect();
    format!(
        "# Push constants ({}).\nBUFFER pc DATA_TYPE uint32 DATA {} END\n",
        names.join(" "),
        pc_words.join(" ")
    )
}

/// The descriptor type AmberScript binds the probed array as.
pub fn kind(resource: Resource) -> &'static str {
    match resource {
        Resource::UniformBuffer => "uniform",
        _ => "storage",
    }
}

/// The probed array's buffers (one per slot; with the packed descriptor, the packed buffer too)
/// and the names bound at the array's elements, in slot order: the packed buffer at
/// `probe::PACKED_SLOT` where the spec reads it, as the worker binds it.
pub fn probed_array(spec: &ProbeSpec, instances: u32) -> (String, Vec<String>) {
    let slots = probe::slot_count(spec.resource, instances);
    let layout = if spec.resource == Resource::UniformBuffer { "STD140" } else { "STD430" };
    let mut s = format!("# The probed array: {slots} {} buffers of {} vec4, slot s element e = (s+1, kind*16+1, 1000+4s+e, 0.25+e).\n", kind(spec.resource), probe::ELEMENTS);
    for slot in 0..slots {
        if spec.packed() && slot == probe::PACKED_SLOT {
            continue;
        }
        let vals: Vec<String> = (0..probe::ELEMENTS)
            .flat_map(|e| probe::resource_value(spec.resource, slot, e))
            .map(fmt_f32)
            .collect();
        s += &format!(
            "BUFFER slot{slot} DATA_TYPE vec4<float> {layout} DATA {} END\n",
            vals.join(" ")
        );
    }
    let mut names: Vec<String> = (0..slots).map(|k| format!("slot{k}")).collect();
    if spec.packed() {
        let vals: Vec<String> = probe::packed_bytes(spec.resource, slots)
            .chunks(4)
            .map(|b| fmt_f32(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        s += &format!(
            "# index=dynamic_element: the packed buffer, bound at the spec-constant slot {} in place of that slot's own, holds every\n# slot's elements (slot s element e at v[{}*s+e]); the dynamic value selects inside it.\n",
            probe::PACKED_SLOT,
            probe::ELEMENTS
        );
        s += &format!("BUFFER packed DATA_TYPE vec4<float> {layout} DATA {} END\n", vals.join(" "));
        names[probe::PACKED_SLOT as usize] = "packed".into();
    }
    (s, names)
}

/// The `BIND` lines of the records, the probed array and the push constants.
pub fn binds(spec: &ProbeSpec, array: &[String]) -> String {
    format!(
        "  BIND BUFFER {RECORDS} AS storage DESCRIPTOR_SET 0 BINDING {RECORDS_BINDING}\n  BIND BUFFER_ARRAY {} AS {} DESCRIPTOR_SET 0 BINDING {PROBE_BINDING}\n  BIND BUFFER pc AS push_constant\n",
        array.join(" "),
        kind(spec.resource)
    )
}

/// The header's note on what the device must enable that AmberScript cannot request.
pub fn features_note(spec: &ProbeSpec) -> String {
    let mut s = String::from(
        "# The probed array is a runtime descriptor array (SPIR-V RuntimeDescriptorArray",
    );
    let nonuniform = spec.access == (crate::probe::spec::Access::Slot { nonuniform: true })
        || spec.workarounds().any(|w| w == crate::model::Workaround::Nonuniform);
    if nonuniform {
        s += ", NonUniform indexing";
    }
    s += "): the device must enable VkPhysicalDeviceDescriptorIndexingFeatures for it, which\n# AmberScript's DEVICE_FEATURE list does not name (run with an Amber whose device enables them).\n";
    let dyn_feature = match spec.resource {
        Resource::UniformBuffer => "shaderUniformBufferArrayDynamicIndexing",
        _ => "shaderStorageBufferArrayDynamicIndexing",
    };
    s + &format!("DEVICE_FEATURE {dyn_feature}\n")
}
