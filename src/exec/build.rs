//! Building a cell at its turn: compile, bind and create its pipeline phase by phase (the
//! second half of phase `pipeline` creates the pipeline unless an identical one exists), or take
//! what a prebuild made for it; and what creating a cell's pipeline needs.
use super::built::{Bound, Compiled, PipelineInput};
use super::compile::cell_shaders;
use super::error::CellError;
use super::executor::{Executor, PhaseHook};
use super::{heap, pipeline};
use crate::model::{Cell, InjectedFault, Phase, Timings};
use crate::probe::spec::ProbeSpec;
use std::time::Instant;

impl Executor {
    /// What creating the cell's pipeline needs, apart from the device and cache.
    pub(super) fn pipeline_input<'a>(
        &self,
        cell: &Cell,
        c: &'a Compiled,
        b: &Bound,
    ) -> PipelineInput<'a> {
        let spec = ProbeSpec::of(cell);
        let binding = &self.bindings[&b.key];
        let layout = binding.heap_layout();
        let mapping =
            spec.heap.zip(layout.as_ref()).map(|(access, l)| heap::PipelineMapping::new(access, l));
        let records = pipeline::shader_records(&spec, layout.as_ref());
        PipelineInput {
            shaders: &c.shaders,
            spirv: &c.spirv,
            layout: binding.pipeline_layout,
            model: spec.model,
            mapping,
            records,
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
            let input = self.pipeline_input(cell, c, b);
            let t = Instant::now();
            let p = input.create(&self.gpu, self.cache)?;
            timings.pipeline_ms = t.elapsed().as_secs_f64() * 1e3;
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
                let c = self.compile_cell(cell, cell_shaders(cell, injected), timings)?;
                on_phase(Phase::Pipeline)?;
                let b = self.bind_cell(cell, &c, timings)?;
                self.ensure_pipeline(cell, &c, &b, timings)?;
                Ok(b)
            }
        }
    }
}
