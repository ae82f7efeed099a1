//! The one layout shared by the Rust side and the stress shaders: the ray buffer (two vec4 per
//! ray), the result words per ray, and the push constants. The GLSL `#define`s are generated
//! from these constants ([`glsl_header`]).
use super::{Ray, Traced, TracedHit};

/// u32 words of one result record.
pub const RESULT_WORDS: usize = 17;
pub const W_STATUS: usize = 0;
pub const W_T: usize = 1;
pub const W_U: usize = 2;
pub const W_V: usize = 3;
pub const W_PRIMITIVE: usize = 4;
pub const W_INSTANCE: usize = 5;
pub const W_CANDIDATES: usize = 6;
pub const W_PASS: usize = 7;
/// Primitive of the first and second candidate any-hit counted (which triangles a double hit
/// reported, and whether one primitive was reported twice).
pub const W_CAND0: usize = 8;
pub const W_CAND1: usize = 9;
/// gl_HitKindEXT, then gl_ObjectRayOriginEXT.xyz and gl_ObjectRayDirectionEXT.xyz (f32 bits).
pub const W_HIT_KIND: usize = 10;
pub const W_OBJ_ORIGIN: usize = 11;
pub const W_OBJ_DIR: usize = 14;
/// Status word: the closest-hit shader ran.
pub const STATUS_HIT: u32 = 1;
/// Status word: the miss shader ran (in the second, opaque trace).
pub const STATUS_MISS: u32 = 2;
/// Push constants: rays address, results address, TLAS address, ray count, launch width, ray flags.
pub const PUSH_SIZE: u32 = 36;
/// Launch width (rays are laid out row by row).
pub const LAUNCH_WIDTH: u32 = 1024;

/// `#define`s for the shaders.
pub fn glsl_header() -> String {
    format!(
        "#define RESULT_WORDS {RESULT_WORDS}\n#define W_STATUS {W_STATUS}\n#define W_T {W_T}\n#define W_U {W_U}\n#define W_V {W_V}\n\
#define W_PRIMITIVE {W_PRIMITIVE}\n#define W_INSTANCE {W_INSTANCE}\n#define W_CANDIDATES {W_CANDIDATES}\n#define W_PASS {W_PASS}\n\
#define W_CAND0 {W_CAND0}\n#define W_CAND1 {W_CAND1}\n#define W_HIT_KIND {W_HIT_KIND}\n#define W_OBJ_ORIGIN {W_OBJ_ORIGIN}\n#define W_OBJ_DIR {W_OBJ_DIR}\n\
#define STATUS_HIT {STATUS_HIT}u\n#define STATUS_MISS {STATUS_MISS}u\n"
    )
}

/// The ray buffer's bytes.
pub fn ray_bytes(rays: &[Ray]) -> Vec<u8> {
    rays.iter()
        .flat_map(|r| {
            [r.origin[0], r.origin[1], r.origin[2], r.tmin, r.dir[0], r.dir[1], r.dir[2], r.tmax]
        })
        .flat_map(f32::to_le_bytes)
        .collect()
}

/// Decode the result words of `n` rays. `None` for a record nothing wrote (neither closest hit
/// nor miss ran: the ray was lost).
pub fn decode(bytes: &[u8], n: usize) -> Vec<Option<Traced>> {
    let w = |i: usize, k: usize| {
        let o = (i * RESULT_WORDS + k) * 4;
        u32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]])
    };
    (0..n)
        .map(|i| {
            let hit = match w(i, W_STATUS) {
                STATUS_HIT => Some(TracedHit {
                    t: f32::from_bits(w(i, W_T)),
                    bary: [f32::from_bits(w(i, W_U)), f32::from_bits(w(i, W_V))],
                    primitive: w(i, W_PRIMITIVE),
                    instance: w(i, W_INSTANCE),
                    hit_kind: w(i, W_HIT_KIND),
                    object_origin: std::array::from_fn(|k| f32::from_bits(w(i, W_OBJ_ORIGIN + k))),
                    object_dir: std::array::from_fn(|k| f32::from_bits(w(i, W_OBJ_DIR + k))),
                }),
                STATUS_MISS => None,
                _ => return None,
            };
            let candidates = w(i, W_CANDIDATES);
            let first = [w(i, W_CAND0), w(i, W_CAND1)];
            Some(Traced { hit, candidates, first_candidates: first })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_reads_what_the_shaders_write() {
        let mut words = vec![0u32; 3 * RESULT_WORDS];
        words[W_STATUS] = STATUS_HIT;
        words[W_T] = 2.5f32.to_bits();
        words[W_U] = 0.25f32.to_bits();
        words[W_PRIMITIVE] = 7;
        words[W_CANDIDATES] = 2;
        words[RESULT_WORDS + W_STATUS] = STATUS_MISS;
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let d = decode(&bytes, 3);
        let h = d[0].unwrap().hit.unwrap();
        assert_eq!((h.t, h.bary[0], h.primitive, d[0].unwrap().candidates), (2.5, 0.25, 7, 2));
        assert_eq!(d[1], Some(Traced { hit: None, candidates: 0, first_candidates: [0, 0] }));
        assert_eq!(d[2], None, "an unwritten record is a lost ray");
        assert_eq!(
            ray_bytes(&[Ray {
                origin: [1.0, 2.0, 3.0],
                tmin: 0.0,
                dir: [0.0, 0.0, 1.0],
                tmax: 9.0
            }])
            .len(),
            32
        );
    }
}
