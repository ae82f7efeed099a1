//! Pipeline binaries (VK_KHR_pipeline_binary) as the report records them: where a worker kept
//! them, under which global pipeline key, the driver's pipeline-binary properties
//! ([`BinaryStatus`], sent when the worker is ready), what it did with them ([`BinaryStats`], sent
//! after its last cell), and the run's sum of both ([`PipelineBinarySummary`]).
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A worker's pipeline binaries at setup.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BinaryStatus {
    /// The folder of this device's, driver's and global key's binaries (`None`: binaries not
    /// used: a re-run that compiles afresh, or `--pipeline-cache off`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dir: Option<PathBuf>,
    /// `vkGetPipelineKeyKHR` with no create info, hex (empty when not read).
    #[serde(default)]
    pub global_key: String,
    /// `VkPhysicalDevicePipelineBinaryPropertiesKHR`, by member name.
    #[serde(default)]
    pub properties: BTreeMap<String, bool>,
    /// The worker compiles afresh: no binaries, no pipeline cache, and the driver's own cache
    /// bypassed (`disableInternalCache`, recorded here when the driver allowed it).
    #[serde(default)]
    pub fresh: bool,
    #[serde(default)]
    pub internal_cache_disabled: bool,
}

/// What a worker did with pipeline binaries.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BinaryStats {
    /// Pipelines made from stored binaries.
    pub loaded: usize,
    /// Pipelines compiled with capture whose binaries were stored.
    pub captured: usize,
    /// Stored binaries not used (failed rtprobe's checks, or the driver refused them): the
    /// pipeline was compiled again and its binaries stored anew.
    pub refused: usize,
    pub bytes_read: u64,
    pub bytes_written: u64,
    /// Distinct reasons for refusals and failed captures or saves (the first few).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<String>,
}

/// Reasons kept per worker and per run.
const MAX_ERRORS: usize = 8;

impl BinaryStats {
    /// Keep `why` unless it is known or [`MAX_ERRORS`] are kept.
    pub fn note(&mut self, why: String) {
        if self.errors.len() < MAX_ERRORS && !self.errors.contains(&why) {
            self.errors.push(why);
        }
    }

    /// Add another worker's counts and reasons.
    pub fn add(&mut self, o: &BinaryStats) {
        self.loaded += o.loaded;
        self.captured += o.captured;
        self.refused += o.refused;
        self.bytes_read += o.bytes_read;
        self.bytes_written += o.bytes_written;
        for e in &o.errors {
            self.note(e.clone());
        }
    }
}

/// The run's pipeline binaries: the last worker's status (every worker of a run shares device,
/// driver and folder; fresh re-run workers are counted apart) and every worker's counts.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PipelineBinarySummary {
    pub status: BinaryStatus,
    /// Workers that used binaries, and workers that compiled afresh.
    pub workers: usize,
    #[serde(default)]
    pub fresh_workers: usize,
    #[serde(default)]
    pub fresh_with_internal_cache_disabled: usize,
    pub totals: BinaryStats,
}

impl PipelineBinarySummary {
    /// A worker is ready with `s`.
    pub fn ready(&mut self, s: BinaryStatus) {
        if s.fresh {
            self.fresh_workers += 1;
            self.fresh_with_internal_cache_disabled += usize::from(s.internal_cache_disabled);
            if self.status.properties.is_empty() {
                self.status.properties = s.properties;
            }
        } else {
            self.workers += 1;
            self.status = s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_add_up_and_keep_distinct_reasons() {
        let mut a = BinaryStats { loaded: 2, captured: 1, bytes_read: 10, ..Default::default() };
        a.note("x".into());
        a.note("x".into());
        let mut b = BinaryStats { refused: 1, bytes_written: 5, ..Default::default() };
        b.note("y".into());
        a.add(&b);
        assert_eq!(
            (a.loaded, a.captured, a.refused, a.bytes_read, a.bytes_written),
            (2, 1, 1, 10, 5)
        );
        assert_eq!(a.errors, ["x", "y"]);
        for i in 0..20 {
            a.note(format!("e{i}"));
        }
        assert_eq!(a.errors.len(), MAX_ERRORS);
    }

    #[test]
    fn fresh_workers_are_counted_apart_and_keep_the_status() {
        let mut s = PipelineBinarySummary::default();
        let used =
            BinaryStatus { dir: Some("d".into()), global_key: "ab".into(), ..Default::default() };
        s.ready(used.clone());
        s.ready(BinaryStatus { fresh: true, internal_cache_disabled: true, ..Default::default() });
        s.ready(BinaryStatus { fresh: true, ..Default::default() });
        assert_eq!((s.workers, s.fresh_workers, s.fresh_with_internal_cache_disabled), (1, 2, 1));
        assert_eq!(s.status, used);
    }
}
