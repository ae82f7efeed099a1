//! The GLSL of an injected fault ([`crate::model::inject`]), appended to the probe body right
//! after `probeValue` is read, so the fault happens at the probed read in the probed stage and
//! nowhere else. Every kind keeps its effect observable (the compiler cannot fold it away): the
//! endless loop and the invalid load are guarded by push constants the worker sets at run time.
use super::probe_code::ProbeCode;
use crate::model::FaultKind;

/// A small integer hash of the pixel and the push-constant salt (lowbias32), the same on every
/// driver; salt 0 (`value:F` without a seed) gives the hash of the pixel alone.
const HASH: &str = "uint injectHash(uvec2 p) {\n    uint h = p.x * 0x8da6b343u ^ p.y * 0xd8163841u ^ 0x9e3779b9u ^ pc.injectSalt * 0x27d4eb2du;\n    \
h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15; h *= 0x846ca68bu; h ^= h >> 16;\n    return h;\n}\n";

/// Append `fault` to `probe` (its body must define `probeValue` and see `px`).
pub fn apply(probe: &mut ProbeCode, fault: FaultKind) {
    match fault {
        FaultKind::Device | FaultKind::Flaky { .. } => {
            probe.extensions.extend([
                "GL_EXT_buffer_reference",
                "GL_EXT_shader_explicit_arithmetic_types_int64",
            ]);
            probe.decls +=
                "layout(buffer_reference, std430) readonly buffer InjectBad { vec4 v[]; };\n";
            probe.body += "    if (any(notEqual(pc.badAddress, uvec2(0u))))\n        \
probeValue += InjectBad(packUint2x32(pc.badAddress)).v[(px.x + px.y * pc.width) * 4096u];\n";
        }
        FaultKind::Hang => {
            probe.body += "    {\n        uint injectN = 0u;\n        while (pc.loopForever != 0u) {\n            injectN += 1u;\n            \
records[px.x + px.y * pc.width].pad = injectN;\n        }\n        probeValue.w += float(injectN);\n    }\n";
        }
        FaultKind::Value { fraction, .. } => {
            // +0.5 makes the first component a non-integer: never any element's value.
            if fraction >= 1.0 {
                probe.body += "    probeValue.x += 0.5;\n";
            } else {
                let threshold = (fraction * 4294967296.0).round().clamp(1.0, 4294967295.0) as u32;
                probe.decls += HASH;
                probe.body +=
                    &format!("    if (injectHash(px) < {threshold}u) probeValue.x += 0.5;\n");
            }
        }
        FaultKind::Nan => probe.body += "    probeValue.x = uintBitsToFloat(0x7fc00000u);\n",
    }
}
