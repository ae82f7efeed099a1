//! How workers that compile afresh (re-runs of a cell alone, GPU-AV, bisect, repro) bypassed the
//! driver's own pipeline cache, as the report records it: per worker ([`DriverCache`], sent when
//! it is ready) — the device's `VkPhysicalDevicePipelineBinaryPropertiesKHR` as it saw them, and
//! which switch it used: `disableInternalCache` (VK_KHR_pipeline_binary) where
//! `pipelineBinaryInternalCacheControl` allows it, else the drivers' documented environment
//! switches —, whether it ran kept SPIR-V (rtprobe's own GLSL cache, which is not the driver's),
//! and for the run ([`DriverCacheSummary`]).
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One worker's driver cache.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DriverCache {
    /// `VkPhysicalDevicePipelineBinaryPropertiesKHR` by member (empty without the extension).
    #[serde(default)]
    pub properties: BTreeMap<String, bool>,
    /// The worker compiles afresh.
    #[serde(default)]
    pub fresh: bool,
    /// Its device was created with `disableInternalCache`.
    #[serde(default)]
    pub internal_cache_disabled: bool,
    /// It set `__GL_SHADER_DISK_CACHE=0` and `MESA_SHADER_CACHE_DISABLE=true` before loading
    /// the driver.
    #[serde(default)]
    pub env_switch: bool,
    /// It read kept GLSL → SPIR-V compiles (rtprobe's own cache, `shadergen::disk_cache`; not
    /// the driver's, which a fresh worker still bypasses).
    #[serde(default)]
    pub glsl_cache: bool,
}

/// The run's driver caches: the pipeline-binary properties (from the first worker that read
/// them without a switch, else any), and how many fresh workers used which switch.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DriverCacheSummary {
    pub properties: BTreeMap<String, bool>,
    pub fresh_workers: usize,
    pub internal_cache_disabled: usize,
    pub env_switch: usize,
    /// Fresh workers that ran the SPIR-V kept from an earlier compile (their GLSL not compiled
    /// again; their pipelines still compiled afresh).
    #[serde(default)]
    pub glsl_cache: usize,
}

impl DriverCacheSummary {
    /// A worker is ready with `c`.
    pub fn ready(&mut self, c: DriverCache) {
        if c.fresh {
            self.fresh_workers += 1;
            self.internal_cache_disabled += usize::from(c.internal_cache_disabled);
            self.env_switch += usize::from(c.env_switch);
            self.glsl_cache += usize::from(c.glsl_cache);
        }
        // The environment switch can hide the driver's cache, and its properties with it.
        if self.properties.is_empty() || !c.env_switch {
            self.properties = c.properties;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresh_workers_are_counted_by_switch_and_unswitched_properties_win() {
        let props =
            |on: bool| BTreeMap::from([("pipelineBinaryInternalCacheControl".to_string(), on)]);
        let mut s = DriverCacheSummary::default();
        s.ready(DriverCache { properties: props(true), ..Default::default() });
        s.ready(DriverCache {
            properties: props(false),
            fresh: true,
            env_switch: true,
            ..Default::default()
        });
        s.ready(DriverCache {
            properties: props(true),
            fresh: true,
            internal_cache_disabled: true,
            glsl_cache: true,
            ..Default::default()
        });
        assert_eq!((s.fresh_workers, s.internal_cache_disabled, s.env_switch), (2, 1, 1));
        assert_eq!(s.glsl_cache, 1, "the fresh worker that ran kept SPIR-V");
        assert_eq!(
            s.properties,
            props(true),
            "the switched worker's properties do not replace them"
        );
        let mut only_switched = DriverCacheSummary::default();
        only_switched.ready(DriverCache {
            properties: props(false),
            fresh: true,
            env_switch: true,
            ..Default::default()
        });
        assert_eq!(only_switched.properties, props(false));
    }
}
