//! End-to-end tests of `run --shader`'s `--compare`, `--tolerance`, `--junit` and `--baseline`
//! on lavapipe, with the bindless pipeline of `tests/shaders/user/` (written for the tests):
//! a run against its own earlier report has no notes; against a hand-edited one (one output's
//! bytes changed) a note, or with `--tolerance 0` a mismatch naming the output; another cell's
//! report is refused in one line; the JUnit file has one testcase per variant; an injected
//! fault held to a baseline expecting it exits 0, and 1 where the baseline does not say so.
mod common;
use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};

const FILES: [&str; 3] = ["raygen.rgen", "miss.rmiss", "bindless.rchit"];
const FAULT: &str = "stage=closest_hit,resource=storage_buffer,index=dynamic@device";

/// `run --validate --shader FILES --repeat 2 -o DIR/NAME.json` with `extra`: the output and the
/// report, if written.
fn shader_run(dir: &Path, name: &str, extra: &[&str]) -> (std::process::Output, Option<Value>) {
    let out = dir.join(format!("{name}.json"));
    let extra = [&["--repeat", "2"][..], extra].concat();
    run_user_shaders(&FILES, &out, &extra, &[])
}

fn write(path: &Path, v: &Value) -> String {
    std::fs::write(path, serde_json::to_vec(v).unwrap()).unwrap();
    path.to_string_lossy().into_owned()
}

fn notes(r: &Value) -> Vec<String> {
    r["notes"].as_array().map_or(vec![], |n| n.iter().map(|n| n.as_str().unwrap().into()).collect())
}

/// The earlier run every comparison uses, written once per test.
fn earlier(dir: &Path) -> Value {
    let (o, r) = shader_run(dir, "earlier", &[]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    r.expect("the earlier report")
}

#[test]
fn a_run_against_its_own_report_has_no_notes_and_an_edited_one_differs() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let mut r = earlier(d.path());
    let data = r["variants"][0]["data"].as_array().unwrap();
    assert!(!data.is_empty(), "the report embeds the outputs");
    let own = d.path().join("earlier.json").to_string_lossy().into_owned();
    let (o, same) = shader_run(d.path(), "same", &["--compare", &own, "--tolerance", "0"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let same = same.unwrap();
    assert_eq!(same["compare"]["differences"], 0, "{}", same["compare"]);
    assert!(notes(&same).iter().all(|n| !n.starts_with("compared: ")), "{:?}", notes(&same));
    // One output's first texel changed by hand (the colour target, written everywhere).
    let label = data[0]["label"].as_str().unwrap().to_string();
    let mut bytes = unb64(data[0]["bytes"].as_str().unwrap());
    bytes[0] ^= 0x01;
    r["variants"][0]["data"][0]["bytes"] = Value::from(b64(&bytes));
    let edited = write(&d.path().join("edited.json"), &r);
    let (o, noted) = shader_run(d.path(), "noted", &["--compare", &edited]);
    assert_eq!(o.status.code(), Some(0), "a difference is a note: {}", stdout(&o));
    let noted = noted.unwrap();
    let note = notes(&noted).into_iter().find(|n| n.starts_with("compared: unpatched: "));
    assert!(
        note.as_deref().is_some_and(|n| n.contains(&label) && n.contains("1 of 4096")),
        "{:?}",
        notes(&noted)
    );
    assert!(stdout(&o).contains("note: compared: unpatched"), "{}", stdout(&o));
    assert_eq!(noted["variants"][0]["outcome"], "pass");
    // Twin: with --tolerance 0 it is a mismatch naming the output.
    let (o, held) = shader_run(d.path(), "held", &["--compare", &edited, "--tolerance", "0"]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let v = &held.unwrap()["variants"][0];
    assert_eq!(
        (v["outcome"].as_str(), v["judgement"].as_str()),
        (Some("mismatch"), Some("compare_differs")),
        "{v}"
    );
    assert!(v["detail"].as_str().unwrap().contains(&label), "{v}");
    assert!(stdout(&o).lines().last().unwrap().starts_with("verdict: FAIL"), "{}", stdout(&o));
}

#[test]
fn another_cells_report_is_refused_in_one_line() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let mut r = earlier(d.path());
    r["cell"] = Value::from("shader:other.rchit@0123456789ab");
    let other = write(&d.path().join("other.json"), &r);
    let (o, report) = shader_run(d.path(), "refused", &["--compare", &other]);
    assert_ne!(o.status.code(), Some(0));
    let err = stderr(&o);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("another cell") && err.contains("shader:other.rchit"), "{err}");
    assert!(report.is_none(), "no report is written");
    // A --tolerance out of bounds is refused too.
    let own = d.path().join("earlier.json").to_string_lossy().into_owned();
    let (o, _) = shader_run(d.path(), "neg", &["--compare", &own, "--tolerance=-1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn junit_has_one_testcase_per_variant() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let xml = d.path().join("junit.xml");
    let (o, r) = shader_run(d.path(), "j", &["--junit", xml.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let r = r.unwrap();
    let text = std::fs::read_to_string(&xml).unwrap();
    let cases: Vec<&str> = text.matches("<testcase ").collect();
    let names = r["variants"].as_array().unwrap();
    assert_eq!(cases.len(), names.len(), "{text}");
    for v in names {
        assert!(text.contains(&format!("name=\"{}\"", v["name"].as_str().unwrap())), "{text}");
    }
    assert!(text.contains(r["cell"].as_str().unwrap()) && !text.contains("<failure"), "{text}");
    assert_well_formed(&text);
}

/// A plain check that `xml` parses: one root, every element closed in order.
fn assert_well_formed(xml: &str) {
    let body = xml.trim().strip_prefix("<?xml").and_then(|s| s.split_once("?>")).unwrap().1;
    let mut open: Vec<String> = Vec::new();
    let mut rest = body;
    while let Some(k) = rest.find('<') {
        let end = rest[k..].find('>').expect("a tag closes") + k;
        let tag = &rest[k + 1..end];
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(open.pop().as_deref(), Some(name), "{xml}");
        } else if !tag.ends_with('/') {
            open.push(tag.split_whitespace().next().unwrap().to_string());
        }
        assert!(!rest[..k].contains('>'), "a stray '>': {xml}");
        rest = &rest[end + 1..];
    }
    assert!(open.is_empty(), "{open:?}");
}

#[test]
fn a_baseline_expecting_the_injected_fault_passes_the_run() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let (o, r) = shader_run(d.path(), "faulty", &["--inject-fault", FAULT]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(r.unwrap()["outcome"], "crash");
    let base: PathBuf = d.path().join("baseline.json");
    let report = d.path().join("faulty.json");
    let o = run(&["baseline", report.to_str().unwrap(), "-o", base.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let b: Value = serde_json::from_slice(&std::fs::read(&base).unwrap()).unwrap();
    let ids: Vec<&str> =
        b["expected"].as_array().unwrap().iter().map(|e| e["cell"].as_str().unwrap()).collect();
    assert!(
        ids.iter().any(|i| i.starts_with("shader:raygen.rgen@") && i.ends_with("/unpatched")),
        "{ids:?}"
    );
    let base = base.to_str().unwrap();
    let (o, r) = shader_run(d.path(), "held", &["--inject-fault", FAULT, "--baseline", base]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let r = r.unwrap();
    assert_eq!(r["outcome"], "crash");
    assert_eq!(r["baseline"]["expected"].as_u64(), Some(ids.len() as u64), "{}", r["baseline"]);
    // Twin: without the fault the baseline's expectations are unexpected passes: exit 1.
    let (o, r) = shader_run(d.path(), "clean", &["--baseline", base]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("UnexpectedPass"), "{}", stdout(&o));
    assert_eq!(r.unwrap()["outcome"], "pass");
}
