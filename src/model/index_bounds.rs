//! What `run --shader`'s descriptor-index check saw (`cli::shader_bounds`): the largest index
//! each descriptor array was read with on the run's data, against the descriptors its binding
//! holds. An index at or past them is the input's fault ([`RULE`]), never a driver finding.
use serde::{Deserialize, Serialize};

/// The rule an index past a runtime-sized array's binding breaks, as the report and the error
/// quote it (Vulkan 1.4.360, checked against Vulkan-Docs).
pub const RULE: &str = "Vulkan 1.4.360, Shader Interfaces, DescriptorSet and Binding Assignment: \
\"If the array is runtime-sized, then array elements greater than or equal to the size of that \
binding in the bound descriptor set must not be used\"";

/// The same for a fixed-size array: SPIR-V leaves an access chain past its array's size
/// undefined, and Vulkan binds no more descriptors than the array declares.
pub const FIXED_RULE: &str = "SPIR-V: an access chain index past its array's size is undefined \
(\"Validity and Defined Behavior\"), and the array is \"no larger than the number of descriptors \
in the binding\" (Vulkan 1.4.360, Shader Interfaces)";

/// What the check saw of a set of accesses' indices.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct IndexSeen {
    pub smallest: u32,
    pub largest: u32,
    /// Some index differed among its subgroup's active invocations; `None`: not measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nonuniform: Option<bool>,
}

/// One descriptor array the check watched (a binding as one declaration declares it).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct IndexedArray {
    pub set: u32,
    pub binding: u32,
    /// Descriptors the harness bound there.
    pub elements: u32,
    /// A runtime-sized array (sized by `--array-size` or the harness).
    pub runtime: bool,
    /// What its accesses' indices were (`None`: no access of it ran). `nonuniform`: some index
    /// differed among its subgroup's active invocations (not uniform within the subgroup,
    /// `VUID-RuntimeSpirv-subgroupSize-10149`'s words); `None` there: not measured (no subgroup
    /// vote in the device's ray tracing stages).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seen: Option<IndexSeen>,
    /// The same of its dynamic accesses without `NonUniform` alone, where one ran (what the
    /// `nonuniform` variant's explanation reads).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub undecorated: Option<IndexSeen>,
}

impl IndexedArray {
    /// The largest index an access read it with (0 when none ran).
    pub fn largest(&self) -> u32 {
        self.seen.as_ref().map_or(0, |s| s.largest)
    }

    /// Whether some access went past the binding.
    pub fn outside(&self) -> bool {
        self.seen.as_ref().is_some_and(|s| s.largest >= self.elements)
    }

    /// `set 1 binding 3: up to 126 of 127 elements`.
    pub fn line(&self) -> String {
        let kind = if self.runtime { "runtime array" } else { "array" };
        match &self.seen {
            None => format!(
                "set {} binding {}: not reached ({kind} of {})",
                self.set, self.binding, self.elements
            ),
            Some(s) => format!(
                "set {} binding {}: up to {} ({kind} of {})",
                self.set, self.binding, s.largest, self.elements
            ),
        }
    }
}

/// The check's record in a `run --shader` report.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct IndexBounds {
    /// The watched arrays as the last check saw them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub arrays: Vec<IndexedArray>,
    /// Runtime arrays the harness sized up so the run's own data stays inside: from, to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grown: Option<(u32, u32)>,
    /// Why the indices were not checked (then `arrays` is empty).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unchecked: Option<String>,
}

impl IndexBounds {
    /// Not checked, and why.
    pub fn unchecked(why: &str) -> IndexBounds {
        IndexBounds { unchecked: Some(why.into()), ..IndexBounds::default() }
    }

    /// Nothing checked and nothing to say: no module indexes a descriptor array.
    pub fn is_empty(&self) -> bool {
        *self == IndexBounds::default()
    }

    /// The report's note (`None` when [`IndexBounds::is_empty`]).
    pub fn note(&self) -> Option<String> {
        if self.is_empty() {
            return None;
        }
        if let Some(why) = &self.unchecked {
            let grown = self.grown.map_or(String::new(), |(from, to)| {
                format!(" (runtime arrays sized {to} instead of {from} before that)")
            });
            return Some(format!("descriptor indices not checked: {why}{grown}"));
        }
        let arrays: Vec<String> = self.arrays.iter().map(IndexedArray::line).collect();
        let grown = self.grown.map_or(String::new(), |(from, to)| {
            format!(
                "; runtime arrays sized {to} instead of {from}, as the harness's own data, as this \
                 device computed the indices, reaches past {from} ({RULE})"
            )
        });
        Some(format!("descriptor indices inside their bindings: {}{grown}", arrays.join(", ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_index_at_the_size_is_outside_and_notes_say_what_was_grown() {
        let a = IndexedArray {
            set: 1,
            binding: 3,
            elements: 64,
            runtime: true,
            seen: Some(IndexSeen { smallest: 3, largest: 64, nonuniform: None }),
            undecorated: None,
        };
        assert!(a.outside());
        let never = IndexedArray { seen: None, ..a.clone() };
        assert!(!never.outside());
        assert_eq!(never.line(), "set 1 binding 3: not reached (runtime array of 64)");
        let seen = Some(IndexSeen { smallest: 3, largest: 63, nonuniform: None });
        assert!(!IndexedArray { seen, ..a.clone() }.outside());
        let b = IndexBounds {
            arrays: vec![IndexedArray {
                elements: 127,
                seen: Some(IndexSeen { smallest: 3, largest: 126, nonuniform: None }),
                ..a
            }],
            grown: Some((64, 127)),
            unchecked: None,
        };
        let n = b.note().unwrap();
        assert!(n.contains("set 1 binding 3: up to 126 (runtime array of 127)"), "{n}");
        assert!(n.contains("sized 127 instead of 64") && n.contains("must not be used"), "{n}");
        let u = IndexBounds { unchecked: Some("why".into()), ..IndexBounds::default() };
        assert_eq!(u.note().as_deref(), Some("descriptor indices not checked: why"));
        assert_eq!(IndexBounds::default().note(), None);
    }
}
