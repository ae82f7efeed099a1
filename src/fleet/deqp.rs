//! Baselines in deqp-runner's form: `test,Status` lines, `#` comments. Its statuses are coarser
//! than rtprobe's outcomes — `Fail` is a mismatch or an error, `Crash` a crash or a device loss,
//! `Flake` any failure at any rate — so rtprobe writes each entry's exact expectation in a
//! comment line before it (`# rtprobe: {…}`, ignored by deqp-runner) and reads it back: an
//! rtprobe baseline round-trips exactly through this form. A line without that comment (a
//! deqp-runner or hand-written file) stands for its whole status: `Fail` accepts a mismatch or
//! an error, `Crash` a crash or a device loss, `Flake` any failure, held at deqp-runner's own
//! flake rate (`model::baseline::DEQP_FLAKE_RATE`: one fault in two attempts).
use crate::model::baseline::SCHEMA;
use crate::model::{Baseline, Expectation, Outcome};
use std::collections::BTreeMap;

/// A line that is not a baseline entry (1-based `line`).
#[derive(Debug, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct LineError {
    pub line: usize,
    pub message: String,
}

/// The comment that carries an entry's exact expectation.
const EXACT: &str = "rtprobe:";

/// The deqp-runner status of a non-flaky expected outcome (`None`: not a failure).
pub fn status(o: Outcome) -> Option<&'static str> {
    match o {
        Outcome::Pass | Outcome::Unsupported | Outcome::NotImplemented => None,
        Outcome::Mismatch | Outcome::Error => Some("Fail"),
        Outcome::Crash | Outcome::DeviceLost => Some("Crash"),
        Outcome::Timeout => Some("Timeout"),
    }
}

fn status_of(e: &Expectation) -> &'static str {
    if e.flake {
        "Flake"
    } else {
        status(e.outcome).unwrap_or("Fail")
    }
}

/// What a deqp-runner `Flake` stands for besides a crash: any other failure (`--flakes` entries
/// too, `deqp_files::with_flakes`).
pub const FLAKE_ALSO: &[Outcome] =
    &[Outcome::Mismatch, Outcome::Error, Outcome::Timeout, Outcome::DeviceLost];

/// What a deqp-runner status stands for when no exact expectation comes with it: the outcome
/// recorded, the others it accepts, and whether it is a flake.
fn foreign(status: &str) -> Option<(Outcome, &'static [Outcome], bool)> {
    Some(match status {
        "Fail" | "ExpectedFail" => (Outcome::Mismatch, &[Outcome::Error], false),
        "Crash" => (Outcome::Crash, &[Outcome::DeviceLost], false),
        "Timeout" => (Outcome::Timeout, &[], false),
        "Flake" | "KnownFlake" => (Outcome::Crash, FLAKE_ALSO, true),
        _ => return None,
    })
}

/// Read `test,Status` lines; `# device: …` / `# driver: …` fill the header, `# rtprobe: {…}`
/// gives the next line's exact expectation (used when it names that cell with that status).
pub fn parse(file: &str, text: &str) -> Result<Baseline, LineError> {
    let mut b = Baseline {
        schema: SCHEMA.into(),
        device: String::new(),
        driver_version: String::new(),
        source: file.into(),
        expected: vec![],
        worker_faults: vec![],
        performance: BTreeMap::new(),
    };
    let mut exact: Option<Expectation> = None;
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let err = |message: String| LineError { line: n + 1, message };
        if let Some(c) = line.strip_prefix('#') {
            let c = c.trim();
            if let Some(v) = c.strip_prefix("device:") {
                b.device = v.trim().into();
            } else if let Some(v) = c.strip_prefix("driver:") {
                b.driver_version = v.trim().into();
            } else if let Some(v) = c.strip_prefix(EXACT) {
                let e: Expectation = serde_json::from_str(v.trim())
                    .map_err(|e| err(format!("not an rtprobe expectation: {e}")))?;
                exact = Some(e);
            }
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let (cell, status) =
            line.split_once(',').ok_or_else(|| err(format!("{line:?} is not `cell,Status`")))?;
        let (cell, status) = (cell.trim(), status.trim());
        let (outcome, also, flake) = foreign(status).ok_or_else(|| {
            err(format!("unknown status {status:?} (Fail, Crash, Timeout, Flake)"))
        })?;
        let e = match exact.take() {
            Some(e) if e.cell == cell && status_of(&e) == status => e,
            _ => Expectation {
                cell: cell.into(),
                outcome,
                flake,
                also: also.to_vec(),
                rate: None,
                bug: None,
            },
        };
        e.recorded().map_err(err)?;
        b.expected.push(e);
    }
    Ok(b)
}

/// deqp-runner form, each entry after its exact expectation (performance bounds and worker
/// faults do not fit it and are dropped).
pub fn write(b: &Baseline) -> String {
    let mut s = format!(
        "# rtprobe baseline (deqp-runner form; `# rtprobe:` lines keep rtprobe's exact expectation)\n# device: {}\n# driver: {}\n",
        b.device, b.driver_version
    );
    for e in &b.expected {
        let exact = serde_json::to_string(e).expect("an expectation serializes");
        s += &format!("# {EXACT} {exact}\n{},{}\n", e.cell, status_of(e));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn foreign_lines_stand_for_their_whole_status() {
        let b = parse("x.csv", "a,Fail\nb,Crash\nc,Flake\n").unwrap();
        assert_eq!(
            (b.expected[0].outcome, &b.expected[0].also[..]),
            (Outcome::Mismatch, &[Outcome::Error][..])
        );
        assert_eq!(b.expected[1].also, [Outcome::DeviceLost]);
        assert!(b.expected[2].flake && b.expected[2].rate.is_none());
    }

    #[test]
    fn an_exact_comment_keeps_error_apart_from_mismatch_and_the_flake_rate() {
        let error = Expectation {
            cell: "a".into(),
            outcome: Outcome::Error,
            flake: false,
            also: vec![],
            rate: Some("2 of 2 attempts".into()),
            bug: None,
        };
        let flake = Expectation {
            cell: "b".into(),
            outcome: Outcome::Crash,
            flake: true,
            also: vec![Outcome::Pass],
            rate: Some("1 of 8 attempts".into()),
            bug: Some("https://example.invalid/3".into()),
        };
        let b = Baseline { expected: vec![error, flake], ..parse("x", "").unwrap() };
        let text = write(&b);
        assert!(text.contains("\na,Fail\n") && text.contains("\nb,Flake\n"), "{text}");
        assert_eq!(parse("y", &text).unwrap().expected, b.expected);
        // A comment that does not match its line (edited by hand) is not applied.
        let edited = text.replace("\na,Fail\n", "\na,Crash\n");
        let e = &parse("y", &edited).unwrap().expected[0];
        assert_eq!((e.outcome, e.rate.as_deref()), (Outcome::Crash, None));
        // A malformed rate is refused with its line.
        let bad = text.replace("2 of 2 attempts", "often");
        let err = parse("z.csv", &bad).unwrap_err().to_string();
        assert!(err.starts_with("line 5: ") && err.contains("K of N attempts"), "{err}");
    }
}
