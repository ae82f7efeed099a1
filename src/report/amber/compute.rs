//! The Amber script of a descriptor-indexing compute cell: its one shader, the records, push
//! constants and the probed array, `SPECIALIZE 0` where the GLSL declares the spec constant, one
//! dispatch of 8×8 groups over the image, and the expected records.
use super::parts;
use crate::model::{Cell, SceneParams};
use crate::probe::{self, spec::ProbeSpec};
use crate::report::shaders::Shader;

/// The compute probe's workgroup (`local_size_x/y`).
pub const GROUP: u32 = 8;

/// The script's body after its header.
pub fn body(cell: &Cell, shader: &Shader, scene: &SceneParams, lanes: bool) -> String {
    let spec = ProbeSpec::of(cell);
    let mut s = parts::shader("compute", "probe", shader);
    s += &parts::records(scene);
    s += &parts::push_constants(&spec, scene);
    let (buffers, array) = parts::probed_array(&spec, scene.instances);
    s += &buffers;
    s += "\nPIPELINE compute probe_pipeline\n  ATTACH probe";
    if spec.spec_constant() {
        s += &format!(" SPECIALIZE 0 AS uint32 {}", probe::SPEC_SLOT);
    }
    s += "\n";
    s += &parts::binds(&spec, &array);
    s += "END\n\n";
    s += &format!(
        "RUN probe_pipeline {} {} 1\n\n",
        scene.width.div_ceil(GROUP),
        scene.height.div_ceil(GROUP)
    );
    s + &super::expect::expectations(cell, scene, lanes)
}
