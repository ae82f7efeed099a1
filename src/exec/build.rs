//! Building a cell at its turn: compile, bind and create its pipeline phase by phase (the
//! second half of phase `pipeline` creates the pipeline unless an identical one exists), or take
//! what a prebuild made for it; and what creating a cell's pipeline needs.
use super::built::{Bound, Compiled, PipelineInput, PipelineParts};
use super::error::CellError;
use super::executor::{Executor, PhaseHook};
use super::{heap, pipeline};
use crate::model::{Cell, InjectedFault, Phase, Timings};
use crate::probe::spec::ProbeSpec;
use std::time::Instant;

impl Executor {
    /// What creating the cell's pipeline needs, apart from the device, cache and shaders.
    pub(super) fn pipeline_parts(&self, cell: &Cell, b: &Bound) -> PipelineParts {
        let spec = ProbeSpec::of(cell);
        let binding = &self.bindings[&b.key];
        let layout = binding.heap_layout();
        let mapping =
            spec.heap.zip(layout.as_ref()).map(|(access, l)| heap::PipelineMapping::new(access, l));
        let records = pipeline::shader_records(&spec, layout.as_ref());
        PipelineParts {
            layout: binding.pipeline_layout,
            model: spec.model,
            mapping,
            records,
            specialization: pipeline::Specialization::probe(),
            layout_digest: binding.digest,
        }
    }

    /// The cell's pipeline, created unless an identical one exists: the second half of `pipeline`.
    fn ensure_pipeline(
        &mut self,
        cell: &Cell,
        c: &Compiled,
        b: &Bound,
        timings: &mut Timings,
    ) -> Result<(), CellError> {
        if !self.pipelines.contains_key(&b.pkey) {
            let parts = self.pipeline_parts(cell, b);
            let input = PipelineInput { shaders: &c.shaders, spirv: &c.spirv, parts: &parts };
            let t = Instant::now();
            let p = input.create(&self.gpu, &self.creation())?;
            timings.pipeline_ms = t.elapsed().as_secs_f64() * 1e3;
            // Made on the cell thread, at its turn: all of it is the cell thread's wait.
            timings.pipeline_wait_ms = timings.pipeline_ms;
            self.pipelines.insert(b.pkey, p);
        }
        Ok(())
    }

    /// Compile, bind and create the pipeline of `cell` (sequentially, phase by phase), or take
    /// what [`Executor::prebuild`] made for it.
    pub(super) fn build(
        &mut self,
        cell: &Cell,
        injected: Option<&InjectedFault>,
        timings: &mut Timings,
        on_phase: PhaseHook,
    ) -> Result<Bound, CellError> {
        on_phase(Phase::Compile)?;
        match self.prebuilt.remove(&cell.id()) {
            Some(p) => {
                *timings = p.timings;
                if p.phase == Phase::Pipeline {
                    on_phase(Phase::Pipeline)?;
                }
                p.result
            }
            None => {
                let c = self.compile_cell(cell, self.cell_shaders(cell, injected), timings)?;
                on_phase(Phase::Pipeline)?;
                let b = self.bind_cell(cell, &c, timings)?;
                self.ensure_pipeline(cell, &c, &b, timings)?;
                Ok(b)
            }
        }
    }
}
