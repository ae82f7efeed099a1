//! `--filter axis=value[|value],…`: parsed against the axis registry, matched against cells.
use super::registry;
use super::Cell;
use serde::{Deserialize, Serialize};

/// `--filter axis=value[|value],axis=value`: every term must match (values within a term are
/// alternatives). Several filters must all match.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Filter {
    pub terms: Vec<(String, Vec<String>)>,
}

/// A `--filter` that does not parse against the axis registry.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FilterError {
    #[error("filter term {term:?} is not axis=value")]
    NotAxisValue { term: String },
    /// `axes`: every axis name, for the message.
    #[error("unknown axis {axis:?} in --filter; axes: {axes}")]
    UnknownAxis { axis: String, axes: String },
    /// `values`: the axis's values, for the message.
    #[error("unknown value {value:?} for {axis} in --filter; values: {values}")]
    UnknownValue { value: String, axis: String, values: String },
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
                        values: allowed.join(", "),
                    });
                }
            }
            terms.push((axis.to_string(), values));
        }
        if terms.is_empty() {
            return Err(FilterError::Empty);
        }
        Ok(Filter { terms })
    }

    pub fn matches(&self, cell: &Cell) -> bool {
        self.terms
            .iter()
            .all(|(axis, values)| cell.axis_value(axis).is_some_and(|v| values.contains(&v)))
    }
}
