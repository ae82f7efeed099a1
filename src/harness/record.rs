//! The shader record data of the harness's SBT: every record (raygen, misses, both hit groups,
//! callables) carries, after its group handle, the same bytes, as long as the longest shader
//! record block the modules reflect (none: no data, the records are the handles). The data is
//! the harness's as in push constants — small integers in the words a block reads as 32-bit
//! integers, the sink's address in its 64-bit integers and pointers ([`super::ints`]), floats
//! elsewhere (data set [`RECORD_SET`] of `resources::word`) — with `--fill record.OFFSET`'s
//! bytes over it ([`super::fill`]).
use super::fill::Fills;
use super::ints::IntWords;
use super::module::UserModule;
use super::resources;
use super::HarnessError;

/// The data set number of the record's words (`resources::word`): past any buffer's, so its
/// floats are no buffer's.
pub const RECORD_SET: u32 = 4000;

/// The record bytes for `modules`: their longest shader record block rounded up to 4 bytes,
/// the integer words of every module's block merged, `sink` in address words, then `fills`.
pub fn data(modules: &[&UserModule], sink: u64, fills: &Fills) -> Vec<u8> {
    let end = modules.iter().map(|m| m.iface.record_end).max().unwrap_or(0).div_ceil(4) * 4;
    let mut ints = IntWords::default();
    for m in modules {
        ints.merge(&m.iface.record_ints);
    }
    let mut bytes: Vec<u8> =
        (0..end / 4).flat_map(|w| resources::word(RECORD_SET, w, ints.at(4 * w), sink)).collect();
    fills.overlay(true, &mut bytes);
    bytes
}

/// Refuse a record that with its `handle` bytes exceeds the device's `maxShaderGroupStride`.
pub fn check(record: usize, handle: u32, max_stride: u32) -> Result<(), HarnessError> {
    let need = handle as usize + record;
    if need > max_stride as usize {
        return Err(HarnessError::Unsupported(format!(
            "the shader record block needs {record} bytes after the {handle}-byte group handle, past the device's maxShaderGroupStride ({max_stride}); make the block smaller"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::fill::{self, Target};
    use crate::harness::ints::Fill;

    /// A record block of a uint, a float, a uint64_t: a small integer, a float, the sink's
    /// address; a fill over the float replaces exactly its bytes.
    #[test]
    fn record_words_hold_harness_data_and_fills() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n\
            layout(shaderRecordEXT, std430) buffer R { uint material; float gain; uint64_t addr; } rec;\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { c = vec4(float(rec.material) * rec.gain + float(rec.addr)); }\n";
        let words = crate::shadergen::compile::Compiler::new()
            .unwrap()
            .compile_glsl(shaderc::ShaderKind::ClosestHit, "t.rchit", glsl)
            .unwrap();
        let m = UserModule::new("t.rchit", &words).unwrap();
        assert_eq!(m.iface.record_end, 16);
        assert_eq!(m.iface.record_ints.at(0), Fill::SmallInt);
        let sink = 0x1234_5678_9abc_def0;
        let d = data(&[&m], sink, &Fills::default());
        assert_eq!(d.len(), 16);
        assert_eq!(&d[8..16], &sink.to_le_bytes());
        assert!(
            u32::from_le_bytes(d[0..4].try_into().unwrap()) < crate::harness::scene::INDEX_BOUND
        );
        assert_eq!(f32::from_le_bytes(d[4..8].try_into().unwrap()), 4001.0 + 1.0 / 256.0);
        let fills = Fills(vec![fill::Fill { target: Target::Record(4), bytes: vec![0xEE; 4] }]);
        let filled = data(&[&m], sink, &fills);
        assert_eq!((&filled[4..8], &filled[..4], &filled[8..]), (&[0xEE; 4][..], &d[..4], &d[8..]));
        // No record block: no data.
        assert!(check(0, 32, 4096).is_ok() && check(4065, 32, 4096).is_err());
    }
}
