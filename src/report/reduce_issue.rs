//! The vendor issue of a reduced user shader (`rtprobe report DIR/reduce.json`, issue 25's
//! step 7): from `rtprobe reduce`'s file (`model::reduce`) and the reduced module's disassembly
//! and accesses beside it, the title (marked when the fault was injected), the original
//! module's hash and the finding, the reduction's numbers, the classification and its
//! `--filter` predicate, the isolation lines (the matrix's slice of that shape), the
//! workarounds verified on the original with their host contracts, and the reduced shader.
//! [`ReduceIssue`] is the data (`--format json`), [`ReduceIssue::markdown`] the text.
use crate::model::reduce::{AccessClass, ReduceReport};
use serde::Serialize;

pub const SCHEMA: &str = "rtprobe.reduce-issue/1";

/// The issue's content.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReduceIssue {
    pub schema: String,
    pub title: String,
    /// Set when the fault was injected: never file it.
    pub injected: Option<String>,
    /// The finding and the original in one paragraph.
    pub summary: String,
    pub original_hash: String,
    /// Function-body instructions, steps, runs, wall time.
    pub reduction: String,
    pub classification: Vec<String>,
    pub predicate: String,
    pub isolation: Vec<String>,
    pub workarounds: Vec<String>,
    /// The remaining accesses, GLSL-like (`access.txt`).
    pub access: String,
    /// The reduced module's disassembly (`reduced.spvasm`).
    pub disassembly: String,
}

fn outcomes(r: &ReduceReport) -> String {
    let v: Vec<&str> = r.outcomes.iter().map(|o| o.as_str()).collect();
    if v.is_empty() {
        "a fault".into()
    } else {
        v.join(" or ")
    }
}

fn isolation(r: &ReduceReport) -> Vec<String> {
    let Some(s) = &r.slice else {
        return vec![
            "the matrix's slice of this shape was not run (`reduce --slice-cells 0`)".into()
        ];
    };
    let mut out = vec![s.line.clone()];
    out.extend(s.faulted.iter().map(|c| format!("`{c}`: faults")));
    if !s.command.is_empty() {
        out.push(format!("ran: `{}`", s.command));
    }
    out
}

fn workarounds(r: &ReduceReport) -> Vec<String> {
    let mut out = Vec::new();
    for w in &r.workarounds {
        out.push(w.line.clone());
        if w.verified {
            let files = w.files.join(", ");
            let contract = w.contract_file.as_deref().unwrap_or("");
            out.push(format!("  files: {files}; host contract ({contract}): {}", w.host_contract));
        }
    }
    out.extend(r.not_applicable.iter().cloned());
    if out.is_empty() {
        out.push("no patch of `rtprobe patch` applies to the original".into());
    }
    out
}

/// The issue of `r`, with the reduced module's `access` text and `disassembly`.
pub fn build(r: &ReduceReport, access: String, disassembly: String) -> ReduceIssue {
    let injected = r.injection.as_ref().map(|i| format!("This fault was injected on purpose with `--inject-fault '{i}'`: rtprobe made the shader misbehave to prove its own detection. It is not a driver bug; do not file it."));
    let shape =
        if r.predicate.is_empty() { "no descriptor access".into() } else { r.predicate.clone() };
    let title = format!(
        "{}{} in a reduced {} ({}) on {}",
        if injected.is_some() { "[injected, not a driver bug] " } else { "" },
        outcomes(r),
        r.module,
        shape,
        r.device
    );
    let summary = format!(
        "`{}` of the `run --shader` cell `{}` ({}) ends in {} on {}. `rtprobe reduce` shrank it with {}, every candidate held to the same outcome in {} attempt{} (a fault as frequent as the finding's missed with p = {:.3}), every descriptor index provably in bounds and no validation message.",
        r.module,
        r.cell,
        r.report,
        outcomes(r),
        r.device,
        r.reducer,
        r.attempts_per_candidate,
        if r.attempts_per_candidate == 1 { "" } else { "s" },
        r.final_miss_probability
    );
    let reduction = r.reduction_text();
    let classification = r.classification.iter().map(AccessClass::sentence).collect();
    ReduceIssue {
        schema: SCHEMA.into(),
        title,
        injected,
        summary,
        original_hash: r.original_hash.clone(),
        reduction,
        classification,
        predicate: r.predicate.clone(),
        isolation: isolation(r),
        workarounds: workarounds(r),
        access,
        disassembly,
    }
}

impl ReduceIssue {
    pub fn markdown(&self) -> String {
        let mut s = format!("# {}\n\n", self.title);
        if let Some(i) = &self.injected {
            s += &format!("> **{i}**\n\n");
        }
        s += &format!("{}\n\n", self.summary);
        s += &format!("- Original module: FNV-1a 128 `{}`\n", self.original_hash);
        s += &format!("- Reduction: {}\n", self.reduction);
        if !self.predicate.is_empty() {
            s += &format!("- Shape: `--filter {}`\n", self.predicate);
        }
        s += "\n## Classification\n\n";
        for l in &self.classification {
            s += &format!("- {l}\n");
        }
        s += "\n## Isolation\n\n";
        for l in &self.isolation {
            s += &format!("- {l}\n");
        }
        s += "\n## Workaround\n\n";
        for l in &self.workarounds {
            s += &format!("- {}\n", l.trim_start());
        }
        s += "\n## The reduced shader\n\n";
        s += &format!("```glsl\n{}\n```\n\n", self.access.trim_end());
        s += "<details><summary>SPIR-V disassembly (spirv-dis)</summary>\n\n";
        s += &format!("```\n{}\n```\n\n</details>\n", self.disassembly.trim_end());
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::reduce::{Counts, ReduceWorkaround, Slice};
    use crate::model::Outcome;

    fn reduced(injection: Option<&str>) -> ReduceReport {
        ReduceReport {
            schema: crate::model::reduce::SCHEMA.into(),
            rtprobe_version: "0".into(),
            report: "run.json".into(),
            cell: "shader:abc".into(),
            device: "llvmpipe".into(),
            module: "hit.rchit".into(),
            original_hash: "0123abcd".into(),
            chosen_because: "x".into(),
            outcomes: vec![Outcome::Crash],
            injection: injection.map(String::from),
            attempts_per_candidate: 1,
            final_miss_probability: 0.0,
            steps: 5,
            interestingness_runs: 9,
            refused_statically: 2,
            wall_s: 3.0,
            instructions: Counts { before: 60, after: 15 },
            reducer: "spirv-reduce".into(),
            classification: vec![],
            predicate: "stage=closest_hit,resource=storage_buffer,index=dynamic".into(),
            workarounds: vec![ReduceWorkaround {
                patch: "ssbo-to-address".into(),
                verified: true,
                line: "ssbo-to-address: verified on the original".into(),
                attempts: 1,
                faulted: 0,
                validation_messages: 0,
                differs: None,
                compared: true,
                injected_faults: Some(0),
                host_contract: "push 8 bytes".into(),
                files: vec!["patched-ssbo-to-address.spv (hit.rchit)".into()],
                contract_file: Some("patched-ssbo-to-address.contract.json".into()),
            }],
            not_applicable: vec!["as-to-address does not apply: no AS".into()],
            slice: Some(Slice {
                faulted: vec!["closest_hit.storage_buffer.dynamic.descriptor_indexing".into()],
                line: "faults too".into(),
                ..Slice::default()
            }),
        }
    }

    #[test]
    fn the_issue_names_hash_shape_isolation_workaround_and_shader() {
        let md = build(&reduced(None), "buf[i]".into(), "OpFunctionEnd".into()).markdown();
        assert!(!md.contains("injected"), "{md}");
        for part in [
            "0123abcd",
            "--filter stage=closest_hit,resource=storage_buffer,index=dynamic",
            "60 function-body instructions to 15 (25%)",
            "`closest_hit.storage_buffer.dynamic.descriptor_indexing`: faults",
            "ssbo-to-address: verified on the original",
            "patched-ssbo-to-address.spv (hit.rchit)",
            "push 8 bytes",
            "as-to-address does not apply",
            "buf[i]",
            "OpFunctionEnd",
        ] {
            assert!(md.contains(part), "{part}: {md}");
        }
    }

    #[test]
    fn an_injected_fault_is_marked_never_to_be_filed() {
        let i = build(&reduced(Some("stage=closest_hit@device")), String::new(), String::new());
        assert!(i.title.starts_with("[injected, not a driver bug]"), "{}", i.title);
        assert!(i.markdown().contains("do not file it"));
    }
}
