//! An Amber script (google/amber, `docs/amber_script.md`) for a repro bundle, the reproducer that
//! needs no rtprobe build: the cell's SPIR-V as `SPIRV-HEX` (the exact binaries the worker runs,
//! patched where the cell says), the GLSL as comments, rtprobe's buffers and push constants, and
//! the expected records as `EXPECT`s from the CPU reference. Written for descriptor-indexing
//! compute cells (`compute`) and ray tracing cells (`rt`: rtprobe's scene as BLAS/TLAS with its
//! custom indices and SBT offsets, the shader groups and binding tables, the trace) reading
//! storage or uniform buffers; [`fits`] refuses the rest with the reason, what AmberScript lacks
//! (descriptor buffers and heaps, shader record data, device addresses in push constants,
//! specialization of ray tracing shaders, arrays of acceleration structures) or what rtprobe does
//! not write yet (images, graphics). [`check`] reads a script's `EXPECT`s as Amber's verifier does,
//! against a records buffer: the test suite holds every script to rtprobe's own records.
mod check;
mod compute;
mod expect;
mod fit;
mod parts;
mod rt;

pub use check::{check, CheckError};
pub use fit::{fits, Unfit};
pub use parts::{PROBE_BINDING, RECORDS, RECORDS_BINDING};

use crate::model::{Cell, Injection, SceneParams, Stage};

/// What a cell without an Amber script has instead, and why rtprobe writes no standalone
/// program for it (docs/bisect-report-repro.md#no-standalone-program).
pub const NO_STANDALONE: &str = "no standalone program either: it would re-implement rtprobe's executor for the cell's binding model in C (docs/bisect-report-repro.md#no-standalone-program); the values such a program needs are in the issue, and `rtprobe run --cell-spec` runs the bundle's SPIR-V";
use crate::report::shaders::Shader;

/// The script for `cell`, or why none is written (a sentence for the README); `lanes`: the probe
/// records lane evidence (`report::shaders::lanes_in`).
pub fn script(
    cell: &Cell,
    shaders: &[Shader],
    scene: &SceneParams,
    inject: Option<&Injection>,
    lanes: bool,
    origin: &str,
) -> Result<String, Unfit> {
    fits(cell, inject)?;
    if scene.file.is_some() {
        return Err(Unfit::SceneFile);
    }
    let body = match cell.stage {
        Stage::Compute => {
            let [shader] = shaders else {
                return Err(Unfit::ShaderCount(shaders.len()));
            };
            compute::body(cell, shader, scene, lanes)
        }
        Stage::Raygen
        | Stage::ClosestHit
        | Stage::AnyHit
        | Stage::Miss
        | Stage::Intersection
        | Stage::Callable => rt::body(cell, shaders, scene, lanes),
        Stage::Fragment => return Err(Unfit::Graphics),
    };
    Ok(header(cell) + &format!("# {origin}\n") + &body)
}

/// The script's first lines: what it is, how to run it, what it cannot request.
fn header(cell: &Cell) -> String {
    let spec = crate::probe::spec::ProbeSpec::of(cell);
    let mut s = String::from("#!amber\n");
    s += &format!(
        "# rtprobe repro: {}\n# {}\n",
        cell.id(),
        crate::bisect::isolation::describe(cell)
    );
    s += "# Run: amber -d -v 1.2 cell.amber (Amber from github.com/google/amber: docs/bisect-report-repro.md#amber-the-reproducer-without-rtprobe;\n# -v 1.2: ray tracing needs Vulkan 1.2's vkGetBufferDeviceAddress; -d: without validation layers).\n";
    s += "# A pass means every EXPECT held: the driver wrote the records rtprobe's f64 reference expects.\n";
    s += &parts::features_note(&spec);
    s + "\n"
}

#[cfg(test)]
mod tests;
