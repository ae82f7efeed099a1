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

impl Filter {
    pub fn parse(s: &str) -> Result<Filter, String> {
        let mut terms = Vec::new();
        for term in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            let (axis, values) = term.split_once('=').ok_or_else(|| format!("filter term {term:?} is not axis=value"))?;
            let axis = axis.trim();
            let Some(def) = registry::axis(axis) else {
                return Err(format!("unknown axis {axis:?} in --filter; axes: {}", registry::names().collect::<Vec<_>>().join(", ")));
            };
            let allowed: Vec<&str> = def.filter_values().collect();
            let values: Vec<String> = values.split('|').map(|v| v.trim().to_string()).collect();
            for v in &values {
                if !allowed.contains(&v.as_str()) {
                    return Err(format!("unknown value {v:?} for {axis} in --filter; values: {}", allowed.join(", ")));
                }
            }
            terms.push((axis.to_string(), values));
        }
        if terms.is_empty() {
            return Err("empty --filter".into());
        }
        Ok(Filter { terms })
    }

    pub fn matches(&self, cell: &Cell) -> bool {
        self.terms.iter().all(|(axis, values)| cell.axis_value(axis).is_some_and(|v| values.contains(&v)))
    }
}
