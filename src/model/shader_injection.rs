//! What `run --shader --inject-fault` injected, as its report records it: the predicate and the
//! kind, each module's matching accesses (and those that could not take the fault), and how many
//! faults each variant's modules held as they ran (a patch rewrites the injected module).
use serde::{Deserialize, Serialize};

/// One module's injection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InjectedModule {
    pub file: String,
    pub stage: String,
    /// Accesses that got the fault.
    pub matched: usize,
    /// Each of them in words (`closest_hit reads storage_buffer materials (dynamic index)`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sites: Vec<String>,
    /// Matching accesses that could not get it, and why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub skipped: Vec<String>,
}

/// The faults one variant's modules held.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InjectedVariant {
    pub name: String,
    pub faults: usize,
}

/// The run's injection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShaderInjection {
    /// `PREDICATE@KIND`.
    pub spec: String,
    /// `device` or `hang`.
    pub fault: String,
    pub modules: Vec<InjectedModule>,
    #[serde(default)]
    pub variants: Vec<InjectedVariant>,
}

/// How the summary and the report's notes say an injection matched nothing.
pub const MATCHED_NOTHING: &str = "the injection matched no access";

impl ShaderInjection {
    /// Accesses that got the fault, over every module.
    pub fn matched(&self) -> usize {
        self.modules.iter().map(|m| m.matched).sum()
    }

    /// One line for the summary and the notes.
    pub fn line(&self) -> String {
        let n = self.matched();
        if n == 0 {
            let skipped: usize = self.modules.iter().map(|m| m.skipped.len()).sum();
            let why = match skipped {
                0 => "no access rtprobe finds matches the predicate (it sees set/binding \
                      descriptor reads in the entry point's own functions; not heap arrays, not \
                      handles passed to a called function), so nothing was made to fault"
                    .to_string(),
                n => format!("{n} matching accesses were skipped (the report's `skipped` says why), so nothing was made to fault"),
            };
            return format!("{MATCHED_NOTHING} ({}): {why}", self.spec);
        }
        let files: Vec<String> = self
            .modules
            .iter()
            .filter(|m| m.matched > 0)
            .map(|m| format!("{} in {}", m.matched, m.file))
            .collect();
        let lost: Vec<String> = self
            .variants
            .iter()
            .filter(|v| v.faults < n)
            .map(|v| format!("{} keeps {}", v.name, v.faults))
            .collect();
        let lost = if lost.is_empty() { String::new() } else { format!("; {}", lost.join(", ")) };
        format!(
            "injected {} fault ({}) after {n} access{}: {}{lost}",
            self.fault,
            self.spec,
            if n == 1 { "" } else { "es" },
            files.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(file: &str, matched: usize) -> InjectedModule {
        InjectedModule {
            file: file.into(),
            stage: "closest_hit".into(),
            matched,
            sites: vec![],
            skipped: vec![],
        }
    }

    #[test]
    fn the_line_says_what_matched_and_what_a_patch_lost() {
        let mut i = ShaderInjection {
            spec: "resource=uniform_buffer@device".into(),
            fault: "device".into(),
            modules: vec![module("hit.rchit", 0)],
            variants: vec![],
        };
        assert!(i.line().starts_with(MATCHED_NOTHING), "{}", i.line());
        i.modules = vec![module("hit.rchit", 2), module("any.rahit", 1)];
        i.variants = vec![
            InjectedVariant { name: "unpatched".into(), faults: 3 },
            InjectedVariant { name: "nonuniform".into(), faults: 2 },
        ];
        assert_eq!(
            i.line(),
            "injected device fault (resource=uniform_buffer@device) after 3 accesses: 2 in hit.rchit, 1 in any.rahit; nonuniform keeps 2"
        );
    }
}
