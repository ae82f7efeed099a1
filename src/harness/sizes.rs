//! The sizes `run --shader` lets the user set ([`Sizes`]): the element count of every runtime
//! descriptor array (`--array-size`; by default [`super::reflect::RUNTIME_ELEMENTS`], one per
//! index the harness scene produces) and the bytes of the sink buffer every address word points
//! at (`--sink-size`, default [`SINK_SIZE`]), with their bounds.
use super::module::UserModule;
use serde::{Deserialize, Serialize};

/// The most elements `--array-size` gives a runtime array.
pub const MAX_ARRAY_SIZE: u32 = 65536;
/// The sink's default size: every 64-bit integer and pointer the harness fills holds its
/// address, so a shader reads zeros through it up to this many bytes past it.
pub const SINK_SIZE: u64 = 4 << 20;
/// The bounds of `--sink-size`: one 16-byte vector, up to 1 GiB.
pub const SINK_BOUNDS: std::ops::RangeInclusive<u64> = 16..=(1 << 30);

/// What the harness makes of a given size.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sizes {
    /// Elements of every runtime descriptor array (`None`: the reflected default).
    #[serde(default)]
    pub array: Option<u32>,
    /// Bytes of the sink buffer.
    #[serde(default = "default_sink")]
    pub sink: u64,
}

fn default_sink() -> u64 {
    SINK_SIZE
}

impl Default for Sizes {
    fn default() -> Sizes {
        Sizes { array: None, sink: SINK_SIZE }
    }
}

impl Sizes {
    /// `modules` with every runtime descriptor array given [`Sizes::array`] elements.
    pub fn apply(&self, mut modules: Vec<UserModule>) -> Vec<UserModule> {
        if let Some(n) = self.array {
            for b in modules.iter_mut().flat_map(|m| m.iface.bindings.iter_mut()) {
                if b.runtime {
                    b.count = n;
                }
            }
        }
        modules
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--array-size` reaches every runtime descriptor array and no fixed one; without it the
    /// reflected counts stay.
    #[test]
    fn the_array_size_replaces_only_runtime_counts() {
        let glsl = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            #extension GL_EXT_nonuniform_qualifier : require\n\
            layout(set = 1, binding = 0) uniform sampler2D maps[];\n\
            layout(set = 1, binding = 1) uniform sampler2D fixed4[4];\n\
            layout(set = 1, binding = 2) readonly buffer B { vec4 v[]; } bufs[];\n\
            layout(location = 0) rayPayloadInEXT vec4 c;\n\
            void main() { uint k = uint(c.w);\n\
            c = textureLod(maps[nonuniformEXT(k)], vec2(0), 0.0)\n\
            + textureLod(fixed4[k & 3u], vec2(0), 0.0) + bufs[nonuniformEXT(k)].v[0]; }\n";
        let words = crate::shadergen::compile::Compiler::new()
            .unwrap()
            .compile_glsl(shaderc::ShaderKind::Miss, "t.rmiss", glsl)
            .unwrap();
        let m = UserModule::new("t.rmiss", &words).unwrap();
        let counts = |ms: &[UserModule]| -> Vec<u32> {
            ms[0].iface.bindings.iter().map(|b| b.count).collect()
        };
        let default = super::super::reflect::RUNTIME_ELEMENTS;
        assert_eq!(counts(&Sizes::default().apply(vec![m.clone()])), [default, 4, default]);
        let sized = Sizes { array: Some(300), sink: SINK_SIZE };
        assert_eq!(counts(&sized.apply(vec![m])), [300, 4, 300]);
    }
}
