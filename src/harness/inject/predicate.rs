//! `run --shader --inject-fault`'s predicate: the `--filter` syntax (`axis=value[|value…]`
//! terms joined by `,`, every term must match) over the three axes that mean something for one
//! descriptor access of a user's module — `stage`, `resource`, `index` — with the axis
//! registry's values (`model::axes`). It matches an [`Access`] (what a site is, on those axes)
//! and nothing else: it shares no code with any classifier of results, so a fault it triggers
//! cannot depend on how a run is later judged.
//!
//! `resource=acceleration_structure` matches the load of an acceleration structure descriptor
//! (index `literal` for one that is no array, as for any descriptor). An acceleration structure
//! made from a 64-bit address (`OpConvertUToAccelerationStructureKHR`: `as-to-address`'s
//! output, or a shader's own) is no descriptor read and no access here: nothing matches it, so
//! the injection re-applied to `as-to-address`'s output puts no fault in (`rtprobe reduce`'s
//! workaround check), while the reduce classifier (`shape`) still lists it, `through` an
//! address.
use crate::model::{Filter, IndexSource, Resource, Stage};

/// The axes a `--shader` predicate takes.
pub const AXES: &[&str] = &["stage", "resource", "index"];

/// One descriptor access of a user's module, on the predicate's axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Access {
    pub stage: Stage,
    pub resource: Resource,
    pub index: IndexSource,
}

/// A parsed predicate: for each axis, the values allowed (empty: any).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Predicate {
    pub stages: Vec<Stage>,
    pub resources: Vec<Resource>,
    pub index: Vec<IndexSource>,
}

/// A predicate `--shader` cannot take.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PredicateError {
    #[error("{axis:?} is not an axis of a user's access; --shader's predicate takes {}", AXES.join(", "))]
    Axis { axis: String },
    #[error("{0}")]
    Syntax(String),
    /// A registry value that no access of a user's ray tracing module can have, and why.
    #[error("{axis}={value}: {why}")]
    Value { axis: &'static str, value: String, why: &'static str },
}

impl Predicate {
    pub fn parse(s: &str) -> Result<Predicate, PredicateError> {
        for term in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let axis = term.split_once('=').map_or(term, |(a, _)| a).trim();
            if term.contains('=') && !AXES.contains(&axis) {
                return Err(PredicateError::Axis { axis: axis.into() });
            }
        }
        let f = Filter::parse(s).map_err(|e| {
            PredicateError::Syntax(
                e.to_string().replace("--filter", "predicate").replace("the the ", "the "),
            )
        })?;
        let mut p = Predicate::default();
        for (axis, values) in &f.terms {
            for v in values {
                p.add(axis, v)?;
            }
        }
        Ok(p)
    }

    /// Add one value the registry accepted for `axis`.
    fn add(&mut self, axis: &str, v: &str) -> Result<(), PredicateError> {
        let refuse = |axis, why| Err(PredicateError::Value { axis, value: v.into(), why });
        match axis {
            "stage" => match Stage::parse(v) {
                Some(s) if s.is_ray_tracing() => self.stages.push(s),
                _ => return refuse("stage", "--shader runs ray tracing stages only"),
            },
            "resource" => match Resource::parse(v) {
                Some(r) => self.resources.push(r),
                None => return refuse("resource", "not a resource of the registry's"),
            },
            _ => match IndexSource::parse(v) {
                Some(IndexSource::DynamicElement) | None => {
                    return refuse("index", "it names the matrix's packed pattern; a user's access is told by its descriptor index: literal, spec_constant, push_constant or dynamic")
                }
                Some(i) => self.index.push(i),
            },
        }
        Ok(())
    }

    pub fn matches(&self, a: &Access) -> bool {
        any(&self.stages, a.stage) && any(&self.resources, a.resource) && any(&self.index, a.index)
    }
}

/// An empty list allows every value.
fn any<T: PartialEq>(list: &[T], v: T) -> bool {
    list.is_empty() || list.contains(&v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn access(stage: Stage, resource: Resource, index: IndexSource) -> Access {
        Access { stage, resource, index }
    }

    #[test]
    fn terms_must_all_match_and_values_are_alternatives() {
        let p = Predicate::parse("stage=closest_hit|any_hit,index=dynamic").unwrap();
        let hit = access(Stage::ClosestHit, Resource::StorageBuffer, IndexSource::Dynamic);
        assert!(p.matches(&hit));
        assert!(p.matches(&Access { stage: Stage::AnyHit, ..hit }));
        // Twins: another stage, another index source.
        assert!(!p.matches(&Access { stage: Stage::Raygen, ..hit }));
        assert!(!p.matches(&Access { index: IndexSource::Literal, ..hit }));
        let r = Predicate::parse("resource=uniform_buffer").unwrap();
        assert!(!r.matches(&hit));
        assert!(r.matches(&Access { resource: Resource::UniformBuffer, ..hit }));
    }

    #[test]
    fn other_axes_and_values_no_access_has_are_one_line() {
        let msg = |s: &str| Predicate::parse(s).unwrap_err().to_string();
        let e = msg("stage=raygen,descriptor_model=descriptor_heap");
        assert_eq!(
            e,
            "\"descriptor_model\" is not an axis of a user's access; --shader's predicate takes stage, resource, index"
        );
        assert!(msg("colour=red").contains("takes stage, resource, index"));
        assert!(
            msg("stage=closesthit").contains("did you mean closest_hit?"),
            "{}",
            msg("stage=closesthit")
        );
        assert!(msg("stage").contains("is not axis=value"), "{}", msg("stage"));
        assert!(msg("stage=fragment").starts_with("stage=fragment: --shader runs ray tracing"));
        assert!(Predicate::parse("resource=acceleration_structure").is_ok());
        assert!(msg("index=dynamic_element").contains("literal, spec_constant"));
        for e in [msg("colour=red"), msg("stage=fragment"), msg("index=dynamic_element")] {
            assert!(!e.contains('\n'), "{e}");
        }
    }
}
