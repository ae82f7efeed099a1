//! Phase `compile` of a cell: its GLSL generated (with its injected fault), compiled to SPIR-V
//! (cached per source) or read from a repro bundle, patched by the spec's workarounds, written
//! out with `--dump`, and scanned for the `nonuniformEXT` the compiler dropped.
use super::built::Compiled;
use super::error::CellError;
use super::executor::Executor;
use super::{files, heap};
use crate::model::{Cell, InjectedFault, Timings, Workaround};
use crate::patches::{workaround, PatchError};
use crate::probe::spec::{ArrayAt, ProbeSpec};
use crate::shadergen::{self, CellShaders};
use std::sync::Arc;
use std::time::Instant;

/// The GLSL of every shader `cell` needs, with its injected fault (if any) appended.
pub(super) fn cell_shaders(cell: &Cell, injected: Option<&InjectedFault>) -> CellShaders {
    shadergen::generate_with(cell, injected.map(|i| i.fault))
}

impl Executor {
    /// GLSL → SPIR-V (cached per source), the cell's workarounds, `--dump`: phase `compile`.
    pub(super) fn compile_cell(
        &mut self,
        cell: &Cell,
        shaders: CellShaders,
        timings: &mut Timings,
    ) -> Result<Compiled, CellError> {
        let spec = ProbeSpec::of(cell);
        if spec.array == ArrayAt::Heap && shadergen::glslang::find().is_none() {
            return Err(CellError::NotImplemented(shadergen::glslang::missing_reason()));
        }
        let mut spirv = self.spirv(&shaders, timings)?;
        // The spec's workarounds: as-to-address for address_patched cells, then the cell's own
        // patch. A bundle's SPIR-V is patched already.
        let workarounds = spec.workarounds().filter(|_| self.opts.spirv_dir.is_none());
        for w in workarounds {
            patch_all(&mut spirv, w, timings)?;
        }
        if let Some(dir) = &self.opts.dump {
            files::dump(dir, cell, &shaders, &spirv).map_err(CellError::Io)?;
        }
        let dropped = heap::dropped_nonuniform(&spec, &spirv);
        Ok(Compiled { shaders, spirv, dropped })
    }

    /// Every shader's SPIR-V, in order: compiled from its GLSL (the time added to
    /// `timings.compile_ms`), or read from the bundle's `shaders/` with `spirv_dir`.
    fn spirv(
        &mut self,
        shaders: &CellShaders,
        timings: &mut Timings,
    ) -> Result<Vec<Arc<Vec<u32>>>, CellError> {
        let mut spirv = Vec::new();
        for s in &shaders.shaders {
            let words = match &self.opts.spirv_dir {
                Some(dir) => Arc::new(files::bundle_spirv(dir, s.role).map_err(CellError::Io)?),
                None => {
                    let (words, ms) = self.compiler.compile(s.role, &s.glsl)?;
                    timings.compile_ms += ms;
                    words
                }
            };
            spirv.push(words);
        }
        Ok(spirv)
    }
}

/// Apply workaround `w` to every module that has the access it rewrites (the time added to
/// `timings.compile_ms`); no module having it is an error, as is a failed patch.
fn patch_all(
    spirv: &mut [Arc<Vec<u32>>],
    w: Workaround,
    timings: &mut Timings,
) -> Result<(), CellError> {
    let t = Instant::now();
    let mut patched_any = false;
    for words in spirv.iter_mut() {
        match workaround::patch_module(words, w) {
            Ok(Some(p)) => {
                *words = Arc::new(p);
                patched_any = true;
            }
            Ok(None) => {}
            Err(e) => return Err(e.into()),
        }
    }
    timings.compile_ms += t.elapsed().as_secs_f64() * 1e3;
    if !patched_any {
        return Err(PatchError::NothingToPatch {
            patch: w.as_str(),
            what: "no module of the cell has the access this workaround rewrites".into(),
        }
        .into());
    }
    Ok(())
}
