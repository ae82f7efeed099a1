//! `--filter axis=value[|value],…`: parsed against the axis registry, matched against cells.
use super::registry;
use super::Cell;
use serde::{Deserialize, Serialize};

/// `--filter axis=value[|value],axis=value`: every term must match (values within a term are
/// alternatives). Several filters must all match. An axis named twice in one filter is refused
/// (`stage=closest_hit,stage=raygen` would match nothing): its values go in one term,
/// `stage=closest_hit|raygen`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Filter {
    pub terms: Vec<(String, Vec<String>)>,
}

/// A `--filter` that does not parse against the axis registry.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FilterError {
    #[error("filter term {term:?} is not axis=value")]
    NotAxisValue { term: String },
    /// `axes`: every axis name, for the message; `hint`: ` (did you mean …?)` or nothing.
    #[error("unknown axis {axis:?} in --filter{hint}; axes: {axes}")]
    UnknownAxis { axis: String, hint: String, axes: String },
    /// `values`: the axis's values, for the message; `hint` as above.
    #[error("unknown value {value:?} for {axis} in --filter{hint}; values: {values}")]
    UnknownValue { value: String, axis: String, hint: String, values: String },
    /// One filter names an axis twice: its terms must all match, so it could match no cell.
    #[error("{axis} appears twice in the --filter {filter:?}: every term of a filter must match, so no cell could; list the values in one term, {axis}={values}")]
    RepeatedAxis { axis: String, filter: String, values: String },
    #[error("empty --filter")]
    Empty,
}

impl Filter {
    pub fn parse(s: &str) -> Result<Filter, FilterError> {
        let mut terms = Vec::new();
        for term in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let (axis, values) = term
                .split_once('=')
                .ok_or_else(|| FilterError::NotAxisValue { term: term.into() })?;
            let axis = axis.trim();
            let Some(def) = registry::axis(axis) else {
                return Err(FilterError::UnknownAxis {
                    axis: axis.into(),
                    hint: did_you_mean(axis, registry::names()),
                    axes: registry::names().collect::<Vec<_>>().join(", "),
                });
            };
            let allowed: Vec<&str> = def.filter_values().collect();
            let values: Vec<String> = values.split('|').map(|v| v.trim().to_string()).collect();
            for v in &values {
                if !allowed.contains(&v.as_str()) {
                    return Err(FilterError::UnknownValue {
                        value: v.clone(),
                        axis: axis.into(),
                        hint: did_you_mean(v, allowed.iter().copied()),
                        values: allowed.join(", "),
                    });
                }
            }
            if let Some((_, before)) =
                terms.iter().find(|(a, _): &&(String, Vec<String>)| a == axis)
            {
                let mut all: Vec<String> = before.clone();
                all.extend(values.iter().filter(|v| !before.contains(v)).cloned());
                return Err(FilterError::RepeatedAxis {
                    axis: axis.into(),
                    filter: s.trim().into(),
                    values: all.join("|"),
                });
            }
            terms.push((axis.to_string(), values));
        }
        if terms.is_empty() {
            return Err(FilterError::Empty);
        }
        Ok(Filter { terms })
    }

    /// One filter per term (what [`Filter::matches`] requires, term by term).
    pub fn split_terms(&self) -> Vec<Filter> {
        self.terms.iter().map(|t| Filter { terms: vec![t.clone()] }).collect()
    }

    /// The filter as `--filter` takes it.
    pub fn text(&self) -> String {
        self.terms.iter().map(|(a, v)| format!("{a}={}", v.join("|"))).collect::<Vec<_>>().join(",")
    }

    pub fn matches(&self, cell: &Cell) -> bool {
        self.terms
            .iter()
            .all(|(axis, values)| cell.axis_value(axis).is_some_and(|v| values.contains(&v)))
    }
}

/// ` (did you mean X?)` when a known word is near `word`, else nothing.
fn did_you_mean<'a>(word: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    super::text::nearest(word, known).map(|w| format!(" (did you mean {w}?)")).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_repeated_axis_is_refused_with_the_term_to_write() {
        let e = Filter::parse("stage=closest_hit,stage=raygen").unwrap_err();
        assert!(matches!(e, FilterError::RepeatedAxis { .. }), "{e}");
        assert!(e.to_string().contains("stage=closest_hit|raygen"), "{e}");
        // Alternatives in one term are what it means to say.
        let f = Filter::parse("stage=closest_hit|raygen,resource=storage_buffer").unwrap();
        assert_eq!(f.text(), "stage=closest_hit|raygen,resource=storage_buffer");
        assert_eq!(f.split_terms().len(), 2);
    }

    #[test]
    fn typos_get_the_nearest_axis_or_value() {
        let e = Filter::parse("stage=closesthit").unwrap_err().to_string();
        assert!(e.contains("(did you mean closest_hit?)") && e.contains("values: raygen"), "{e}");
        let e = Filter::parse("stagee=raygen").unwrap_err().to_string();
        assert!(e.contains("(did you mean stage?)"), "{e}");
        let e = Filter::parse("colour=red").unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
    }
}
