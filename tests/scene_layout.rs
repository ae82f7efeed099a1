//! The `scene_layout` cells on lavapipe: both layouts on the test scene (`scene make`) and on the
//! procedural scene pass, and their records agree word for word per cell pair (the lane words
//! aside: they say which lanes ran together); the twin — a wrong value injected into the
//! per_mesh fetch — is a mismatch and breaks the agreement.
mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

const LAYOUTS: &str = "scene_layout=shared_buffers|per_mesh";
/// Bytes of a record before its lane words (`probe::Record`).
const WORDS: usize = 64;
const RECORD: usize = 80;
const FLAG_LAYOUT: u32 = 8;

/// The (shared_buffers, per_mesh) cells of each set-based model.
fn pairs() -> Vec<(String, String)> {
    ["descriptor_indexing", "descriptor_buffer"]
        .iter()
        .map(|m| {
            (
                format!("closest_hit.storage_buffer.dynamic.{m}.shared_buffers"),
                format!("closest_hit.storage_buffer.dynamic.nonuniform.{m}.per_mesh"),
            )
        })
        .collect()
}

/// `rtprobe run` of the layout cells (on `scene`, else the procedural one) into `dir`, with
/// `--dump`; its report.
fn run_layouts(dir: &Path, scene: Option<&Path>, extra: &[&str]) -> (Option<i32>, Value) {
    let (out, dump) = (dir.join("r.json"), dir.join("dump"));
    let mut args = vec!["run", "--filter", LAYOUTS, "-o", out.to_str().unwrap()];
    args.extend(["--dump", dump.to_str().unwrap()]);
    if let Some(s) = scene {
        args.extend(["--scene", s.to_str().unwrap()]);
    }
    args.extend(extra);
    let o = run(&args);
    let report = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    (o.status.code(), report)
}

fn outcome(r: &Value, id: &str) -> String {
    let cells = r["cells"].as_array().unwrap();
    let c = cells.iter().find(|c| c["id"] == id).unwrap_or_else(|| panic!("{id} not run"));
    c["outcome"].as_str().unwrap().into()
}

fn records(dir: &Path, id: &str) -> Vec<u8> {
    std::fs::read(dir.join("dump").join(id).join("records.bin")).unwrap()
}

/// Records whose words before the lane words differ, and the layout records (`FLAG_LAYOUT`).
fn disagreement(a: &[u8], b: &[u8]) -> (usize, usize) {
    assert_eq!(a.len(), b.len());
    let (ra, rb) = (a.chunks(RECORD), b.chunks(RECORD));
    let differ = ra.clone().zip(rb).filter(|(x, y)| x[..WORDS] != y[..WORDS]).count();
    let layout = ra.filter(|r| u32::from_le_bytes(r[..4].try_into().unwrap()) & FLAG_LAYOUT != 0);
    (differ, layout.count())
}

fn layouts_pass_and_agree(dir: &Path, scene: Option<&Path>) {
    let (code, r) = run_layouts(dir, scene, &[]);
    assert_eq!(code, Some(0), "{r}");
    for (shared, per_mesh) in pairs() {
        assert_eq!((outcome(&r, &shared), outcome(&r, &per_mesh)), ("pass".into(), "pass".into()));
        let (differ, fetched) = disagreement(&records(dir, &shared), &records(dir, &per_mesh));
        assert_eq!(differ, 0, "{shared} and {per_mesh} disagree on {differ} records");
        assert!(fetched > 100, "{shared}: only {fetched} fetching records");
    }
}

#[test]
fn both_layouts_pass_and_agree_word_for_word_on_both_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (file, procedural) = (dir.path().join("file"), dir.path().join("procedural"));
    layouts_pass_and_agree(&file, Some(&dir.path().join("scene.gltf")));
    layouts_pass_and_agree(&procedural, None);
}

#[test]
fn a_wrong_fetch_is_a_mismatch_and_breaks_the_agreement() {
    let dir = tempfile::tempdir().unwrap();
    let (code, r) =
        run_layouts(dir.path(), None, &["--inject-fault", "scene_layout=per_mesh@value:0.5:7"]);
    assert_ne!(code, Some(0));
    for (shared, per_mesh) in pairs() {
        assert_eq!(
            (outcome(&r, &shared), outcome(&r, &per_mesh)),
            ("pass".into(), "mismatch".into())
        );
        let (differ, _) =
            disagreement(&records(dir.path(), &shared), &records(dir.path(), &per_mesh));
        assert!(differ > 0, "{per_mesh}: the injected fault changed no record");
    }
}
