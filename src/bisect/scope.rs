//! What bisection takes from a run report: the options its runs must repeat (device, scene,
//! `--inject-fault`, timeouts) and the scope of cells when no device is at hand.
use crate::model::Isolation;
use crate::model::PatchMode;
use crate::model::RunReport;
use crate::model::{Cell, Filter, FilterError};
use crate::model::{InjectError, Injection};

/// What the report's options or the scope's filters fail with.
#[derive(Debug, thiserror::Error)]
pub enum ScopeError {
    /// The report's recorded `--inject-fault` does not parse (any more).
    #[error("the report's --inject-fault: {0}")]
    Injection(InjectError),
    #[error(transparent)]
    Filter(FilterError),
}

/// The report's options that bisection's runs repeat.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    pub filters: Vec<String>,
    pub patches: PatchMode,
    pub inject: Vec<Injection>,
    pub jobs: Option<usize>,
    pub isolation: Isolation,
    pub timeout_s: f64,
    /// The run's worker setup deadline, when the report records it.
    pub setup_timeout_s: Option<f64>,
    pub validate: bool,
}

impl ReportOptions {
    pub fn of(r: &RunReport) -> Result<Self, ScopeError> {
        let o = &r.options;
        let inject = o
            .inject
            .iter()
            .map(|s| Injection::parse(s))
            .collect::<Result<Vec<_>, _>>()
            .map_err(ScopeError::Injection)?;
        Ok(ReportOptions {
            filters: o.filters.clone(),
            patches: o.patches,
            inject,
            jobs: o.jobs,
            isolation: o.isolation,
            timeout_s: o.timeout_s,
            setup_timeout_s: o.setup_timeout_s,
            validate: o.validate,
        })
    }

    /// The scope filters: `given`, or else the report's own `--filter`s.
    pub fn scope_filters(&self, given: &[String]) -> Result<Vec<Filter>, ScopeError> {
        let src = if given.is_empty() { &self.filters } else { given };
        src.iter().map(|f| Filter::parse(f)).collect::<Result<_, _>>().map_err(ScopeError::Filter)
    }
}

/// The scope without a device: the report's probe cells that ran and match `filters` (patched
/// variants only when the report planned them all: in `faults` mode they exist only for
/// faulting cells and are workaround retries, not a sample of the patch axis).
pub fn report_scope(r: &RunReport, filters: &[Filter], patches: PatchMode) -> Vec<Cell> {
    r.cells
        .iter()
        .filter(|c| c.cell.canary.is_none() && !c.attempts.is_empty())
        .filter(|c| c.cell.patch.is_none() || patches == PatchMode::All)
        .filter(|c| filters.iter().all(|f| f.matches(&c.cell)))
        .map(|c| c.cell)
        .collect()
}

/// The cell with this id: any cell of the full matrix, its workaround variants, or a canary.
pub fn cell_by_id(id: &str) -> Option<Cell> {
    use crate::model::Canary;
    let (all, _) = crate::matrix::plan::all_cells();
    all.into_iter()
        .flat_map(|c| {
            std::iter::once(c).chain(
                c.applicable_patches().into_iter().map(move |p| Cell { patch: Some(p), ..c }),
            )
        })
        .chain(Canary::ALL.iter().map(|k| Cell::canary(*k)))
        .find(|c| c.id() == id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_id_finds_its_cell() {
        for id in [
            "closest_hit.storage_buffer.dynamic.descriptor_indexing.patch-pin-index",
            "raygen.acceleration_structure.literal.address_patched.descriptor_buffer",
            "canary.infinite_loop",
        ] {
            assert_eq!(cell_by_id(id).unwrap().id(), id);
        }
        assert!(cell_by_id("raygen.nope").is_none());
    }
}
