//! deqp-runner's files, for CI set up around it: `--skips` and `--flakes` lists (a regular
//! expression per line, `#` comments, matched anywhere in a cell id as deqp-runner matches test
//! names), and the output folder's `results.csv` (`test,Status,duration` for every planned cell
//! and canary) and `failures.csv` (the lines CI looks at). Statuses are deqp-runner's: `Pass`,
//! `Fail` (mismatch, error), `Crash` (crash, device loss), `Timeout`, `Skip` (unsupported, not
//! implemented), `Flake` (its attempts disagree), and against a baseline `ExpectedFail`,
//! `KnownFlake`, `UnexpectedPass` and `Missing` (a fault was expected and the cell did not run).
use super::deqp::{status as deqp_status, FLAKE_ALSO};
use crate::model::{Baseline, CellCheck, CellReport, Expectation, Outcome, RunReport, Status};
use regex_automata::meta::Regex;

/// A `--skips` / `--flakes` list.
#[derive(Debug)]
pub struct Patterns {
    /// The expressions, as written.
    pub lines: Vec<String>,
    set: Option<Regex>,
}

/// A list that does not parse: the file, the line and the regex error.
#[derive(Debug, thiserror::Error)]
#[error("{file}: line {line}: {message}")]
pub struct PatternError {
    pub file: String,
    pub line: usize,
    pub message: String,
}

impl Patterns {
    /// The expressions of `text` (`file` names it in errors).
    pub fn parse(file: &str, text: &str) -> Result<Patterns, PatternError> {
        let mut lines = Vec::new();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            Regex::new(line).map_err(|e| PatternError {
                file: file.into(),
                line: n + 1,
                message: format!("{line:?} is not a regular expression: {e}"),
            })?;
            lines.push(line.to_string());
        }
        Patterns::of(lines).map_err(|message| PatternError { file: file.into(), line: 0, message })
    }

    /// The list of already checked expressions (a report's `skips`).
    pub fn of(lines: Vec<String>) -> Result<Patterns, String> {
        let set = if lines.is_empty() {
            None
        } else {
            Some(Regex::new_many(&lines).map_err(|e| e.to_string())?)
        };
        Ok(Patterns { lines, set })
    }

    /// Whether an expression matches somewhere in `id`.
    pub fn matches(&self, id: &str) -> bool {
        self.set.as_ref().is_some_and(|r| r.is_match(id))
    }
}

/// `baseline` (or an empty one) with every cell of `ids` that `flakes` matches expected as a known
/// flake: any fault or a pass is tolerated there (deqp-runner's `--flakes`).
pub fn with_flakes<'a>(
    baseline: Option<Baseline>,
    flakes: &Patterns,
    source: &str,
    ids: impl Iterator<Item = &'a str>,
) -> Baseline {
    let mut b = baseline.unwrap_or_else(|| Baseline {
        schema: crate::model::baseline::SCHEMA.into(),
        device: String::new(),
        driver_version: String::new(),
        source: source.into(),
        expected: vec![],
        worker_faults: vec![],
        performance: Default::default(),
    });
    for id in ids.filter(|id| flakes.matches(id)) {
        match b.expected.iter_mut().find(|e| e.cell == id) {
            Some(e) => e.flake = true,
            None => b.expected.push(Expectation {
                cell: id.into(),
                outcome: Outcome::Crash,
                flake: true,
                also: FLAKE_ALSO.to_vec(),
                rate: None,
                bug: None,
            }),
        }
    }
    b
}

/// deqp-runner's status of one cell of `r`.
pub fn status(r: &RunReport, c: &CellReport) -> &'static str {
    if let Some(chk) = &c.canary_check {
        return if chk.detected { "Pass" } else { "Fail" };
    }
    let against = r.baseline.as_ref().and_then(|b| b.cells.iter().find(|x| x.cell == c.id));
    match (c.outcome, against.map(|x| x.status)) {
        // Expected to fault, and it did not run here: deqp-runner's word for a test without a
        // result.
        (_, Some(Status::Missing)) => "Missing",
        (Outcome::Unsupported | Outcome::NotImplemented, _) => "Skip",
        (_, Some(Status::Improvement)) => "UnexpectedPass",
        (_, Some(Status::KnownFlake)) => "KnownFlake",
        (Outcome::Pass, _) => "Pass",
        // A finding the baseline holds (not among its surprises): expected.
        (o, None | Some(Status::Expected)) if r.baseline.is_some() && o.is_finding() => {
            "ExpectedFail"
        }
        (_, _) if c.flaky => "Flake",
        (o, _) => deqp_status(o).unwrap_or("Fail"),
    }
}

/// The planned cells and canaries of `r` (its retries are no tests of their own).
fn tests(r: &RunReport) -> impl Iterator<Item = &CellReport> {
    r.cells.iter().filter(|c| !c.is_retry(r.options.patches))
}

/// `test,Status,duration` rows: the planned cells and canaries, then the baseline's missing
/// entries that `r` did not plan at all (no duration).
fn rows(r: &RunReport) -> Vec<(&str, &'static str, f64)> {
    let mut rows: Vec<(&str, &'static str, f64)> = tests(r)
        .map(|c| (c.id.as_str(), status(r, c), c.attempts.iter().map(|a| a.wall_ms).sum::<f64>()))
        .collect();
    let unplanned = |x: &&CellCheck| !r.cells.iter().any(|c| c.id == x.cell);
    for x in r.baseline.iter().flat_map(|b| b.missing()).filter(unplanned) {
        rows.push((x.cell.as_str(), "Missing", 0.0));
    }
    rows
}

fn line((id, status, ms): &(&str, &str, f64)) -> String {
    format!("{id},{status},{:.3}\n", ms / 1e3)
}

/// `results.csv`: every planned cell and canary, `test,Status,duration` (seconds, all attempts),
/// and the baseline's missing cells.
pub fn results_csv(r: &RunReport) -> String {
    rows(r).iter().map(line).collect()
}

/// `failures.csv`: the results CI looks at (`Fail`, `Crash`, `Timeout`, `Flake`,
/// `UnexpectedPass`, `Missing`): neither the passes and skips nor what the baseline expects.
pub fn failures_csv(r: &RunReport) -> String {
    let failing = ["Fail", "Crash", "Timeout", "Flake", "UnexpectedPass", "Missing"];
    rows(r).iter().filter(|(_, s, _)| failing.contains(s)).map(line).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{
        Attempt, BaselineCheck, CellCheck, DescriptorModel, IndexSource, Resource, Stage,
    };

    fn cell(index: IndexSource, outcomes: &[Outcome]) -> CellReport {
        let c = crate::model::Cell::new(
            Stage::Miss,
            Resource::StorageBuffer,
            index,
            DescriptorModel::DescriptorIndexing,
        );
        let mut r = CellReport::new(&c, Attempt::for_tests(outcomes[0], false));
        for o in &outcomes[1..] {
            r.attempts.push(Attempt::for_tests(*o, true));
        }
        r.refresh();
        r
    }

    #[test]
    fn lists_are_regular_expressions_and_a_bad_line_is_named() {
        let p = Patterns::parse(
            "skips.txt",
            "# comment\n\nmiss\\..*\\.dynamic\\.\nraygen\\.uniform_buffer\n",
        )
        .unwrap();
        assert!(p.matches("miss.storage_buffer.dynamic.descriptor_indexing"));
        assert!(p.matches("raygen.uniform_buffer.literal.descriptor_buffer"));
        assert!(!p.matches("miss.storage_buffer.literal.descriptor_indexing"));
        assert_eq!(p.lines.len(), 2);
        let e = Patterns::parse("f.txt", "ok\n(unclosed\n").unwrap_err().to_string();
        assert!(e.starts_with("f.txt: line 2: \"(unclosed\" is not a regular expression"), "{e}");
        assert!(!Patterns::parse("e", "").unwrap().matches("anything"));
    }

    #[test]
    fn statuses_are_deqp_runners() {
        let mut r = RunReport::for_tests(vec![
            cell(IndexSource::Literal, &[Outcome::Pass]),
            cell(IndexSource::Dynamic, &[Outcome::Crash, Outcome::Crash]),
            cell(IndexSource::SpecConstant, &[Outcome::Mismatch, Outcome::Pass]),
            cell(IndexSource::PushConstant, &[Outcome::Timeout]),
        ]);
        let got: Vec<&str> = r.cells.iter().map(|c| status(&r, c)).collect();
        assert_eq!(got, ["Pass", "Crash", "Flake", "Timeout"]);
        assert_eq!(failures_csv(&r).lines().count(), 3);
        assert!(
            results_csv(&r)
                .starts_with("miss.storage_buffer.literal.descriptor_indexing,Pass,0.001\n"),
            "{}",
            results_csv(&r)
        );
        // Against a baseline that expects the crash and had expected the pass to fail.
        r.baseline = Some(BaselineCheck {
            cells: vec![CellCheck {
                cell: r.cells[0].id.clone(),
                status: Status::Improvement,
                expected: Outcome::Crash,
                actual: Outcome::Pass,
                why: None,
            }],
            ..Default::default()
        });
        let got: Vec<&str> = r.cells.iter().map(|c| status(&r, c)).collect();
        assert_eq!(got, ["UnexpectedPass", "ExpectedFail", "ExpectedFail", "ExpectedFail"]);
        assert_eq!(failures_csv(&r), format!("{},UnexpectedPass,0.001\n", r.cells[0].id));
    }

    /// A baseline's missing cell (a fault expected, and the cell did not run: unsupported here,
    /// or planned nowhere) is deqp-runner's `Missing`, among the failures.
    #[test]
    fn missing_cells_are_failures_planned_or_not() {
        let mut r = RunReport::for_tests(vec![
            cell(IndexSource::Literal, &[Outcome::Unsupported]),
            cell(IndexSource::Dynamic, &[Outcome::Unsupported]),
        ]);
        // Its twin first: without a baseline an unsupported cell is a skip, no failure.
        assert_eq!(status(&r, &r.cells[0]), "Skip");
        assert_eq!(failures_csv(&r), "");
        let missing = |cell: &str| CellCheck {
            cell: cell.into(),
            status: Status::Missing,
            expected: Outcome::Crash,
            actual: Outcome::Unsupported,
            why: None,
        };
        r.baseline = Some(BaselineCheck {
            cells: vec![missing(&r.cells[0].id), missing("raygen.renamed.cell")],
            ..Default::default()
        });
        assert_eq!(status(&r, &r.cells[0]), "Missing");
        assert_eq!(status(&r, &r.cells[1]), "Skip");
        assert_eq!(
            failures_csv(&r),
            format!("{},Missing,0.001\nraygen.renamed.cell,Missing,0.000\n", r.cells[0].id)
        );
        assert_eq!(results_csv(&r).lines().count(), 3);
    }

    #[test]
    fn flakes_become_known_flake_expectations() {
        let p = Patterns::parse("flakes.txt", "dynamic").unwrap();
        let ids = ["a.dynamic.b", "a.literal.b"];
        let b = with_flakes(None, &p, "flakes.txt", ids.iter().copied());
        assert_eq!(b.expected.len(), 1);
        assert!(b.expected[0].flake && b.expected[0].cell == "a.dynamic.b");
    }
}
