//! The hit region of the harness's shader binding table ([`layout`]): which hit group each
//! record holds, and the procedural instances' SBT offset. A ray reaches record
//! `instanceShaderBindingTableRecordOffset + geometryIndex × sbtRecordStride + sbtRecordOffset`
//! (Vulkan 1.4.360, Ray Tracing, Shader Binding Table, Hit Shaders; "All data accessed must be
//! less than pHitShaderBindingTable->size bytes from the base address"). The harness's mesh
//! instances have SBT offset 0 and several geometries per BLAS (`scene::GEOMETRIES_PER_MESH`,
//! so `gl_GeometryIndexEXT` varies): a ray of type k (its offset) with stride s reaches record
//! `g·s + k` on geometry g, each of which holds type k's triangle group. The sphere instances
//! (one AABB geometry) start after the last such record, at [`HitTable::procedural`], with one
//! procedural group per ray type. Records no ray reaches hold an empty triangle group.
use super::error::HarnessError;
use super::module::UserModule;

/// Strides beyond this are refused: "Only the 4 least-significant bits of SBT Offset and SBT
/// Stride are used by this instruction - other bits are ignored" (SPIR-V 1.6, OpTraceRayKHR), so
/// a driver traces stride 17 as stride 1 and a table laid out for 17 would be the wrong one.
pub const MAX_STRIDE: u32 = 15;

/// A hit group: for geometry of this kind, of this ray type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Geometry {
    Triangles,
    Procedural,
}

/// The hit region's records in order and the procedural instances' SBT offset.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HitTable {
    /// Per record, the kind and ray type of the group it holds; `None`: no ray reaches it.
    pub records: Vec<Option<(Geometry, u32)>>,
    pub procedural: u32,
}

fn unsupported(s: String) -> HarnessError {
    HarnessError::Unsupported(s)
}

/// The table for `modules`' rays over `types` ray types on triangle BLASes of up to
/// `geometries` geometries. A non-constant stride (where geometries differ), one past
/// [`MAX_STRIDE`], or two ray types reaching one record are refused in one line.
pub fn layout(
    modules: &[&UserModule],
    types: u32,
    geometries: u32,
) -> Result<HitTable, HarnessError> {
    let mut records: Vec<Option<(Geometry, u32)>> = vec![Some((Geometry::Triangles, 0))];
    // Who reached each record first (record 0: nothing traces, the supplied raygen's group).
    let mut who: Vec<String> = vec![String::new()];
    for m in modules {
        for t in &m.iface.reflection.traces {
            let Some(k) = t.sbt_offset else { continue };
            let stride = match t.sbt_stride {
                Some(s) if s <= MAX_STRIDE => s,
                Some(s) => return Err(unsupported(format!("{} traces a ray with sbtRecordStride {s}; OpTraceRayKHR uses only its 4 low bits (SPIR-V 1.6), so strides 0 to {MAX_STRIDE} run here: give the stride your hit table really has", m.name))),
                None if geometries <= 1 => 0,
                None => return Err(unsupported(format!("{} traces a ray whose sbtRecordStride is not a constant; the harness scene's meshes have {geometries} geometries each, so the stride picks the hit group (geometryIndex × sbtRecordStride + sbtRecordOffset, Vulkan 1.4.360, Shader Binding Table, Hit Shaders): pass it as a literal, or compile with `glslangValidator -V -Os` and give the .spv so it folds", m.name))),
            };
            let said = format!("{}'s ray (sbtRecordOffset {k}, sbtRecordStride {stride})", m.name);
            for g in 0..geometries.max(1) {
                let at = (g * stride + k) as usize;
                if records.len() <= at {
                    records.resize(at + 1, None);
                    who.resize(at + 1, String::new());
                }
                match records[at] {
                    Some((_, other)) if other != k => {
                        return Err(clash(at, g, &said, other, &who[at]))
                    }
                    _ => {
                        records[at] = Some((Geometry::Triangles, k));
                        who[at] = said.clone();
                    }
                }
            }
        }
    }
    let procedural = records.len() as u32;
    records.extend((0..types).map(|k| Some((Geometry::Procedural, k))));
    Ok(HitTable { records, procedural })
}

/// Two ray types reaching record `at`.
fn clash(at: usize, g: u32, said: &str, other: u32, whose: &str) -> HarnessError {
    unsupported(format!("{said} reaches hit record {at} on geometry {g} of the harness scene's meshes, where {whose} of ray type {other} reach it too (record = geometryIndex × sbtRecordStride + sbtRecordOffset, Vulkan 1.4.360, Shader Binding Table, Hit Shaders): one record holds one ray type's group, so use sbtRecordStride 0 or at least the number of ray types"))
}

#[cfg(test)]
mod tests;
