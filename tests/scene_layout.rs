//! The `scene_layout` cells on lavapipe: both layouts on the test scene (`scene make`) and on the
//! procedural scene pass, and their records agree word for word per cell pair (the lane words
//! aside: they say which lanes ran together); the twins — a wrong value injected into the
//! per_mesh fetch is a mismatch and breaks the agreement; the two layouts fed different scenes
//! (seeds) both pass and disagree. The texture cells (`resource=sampled_image`) pass on both
//! scenes, sample several textures and fetch the geometry cells' triangles; an injected wrong
//! value is a mismatch; on a glTF scene without textures they are `not_implemented` with why.
//! The texture cells of both layouts agree word for word too (`per_mesh`'s reads its material
//! through the mesh buffers). The mutants' twins: a wrong texture or mesh buffer (`run
//! --mutants`) is killed on both scenes.
mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

const LAYOUTS: &str = "scene_layout=shared_buffers|per_mesh";
/// A wrong value injected into the per_mesh geometry cells only.
const GEOMETRY_FAULT: &str = "scene_layout=per_mesh,resource=storage_buffer@value:0.5:7";
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

fn reason(r: &Value, id: &str) -> String {
    let cells = r["cells"].as_array().unwrap();
    let c = cells.iter().find(|c| c["id"] == id).unwrap_or_else(|| panic!("{id} not run"));
    c["reason"].as_str().unwrap_or_default().into()
}

/// The texture cells of each set-based model, in both layouts.
fn texture_cells() -> Vec<String> {
    texture_pairs().into_iter().flat_map(|(s, p)| [s, p]).collect()
}

/// The (shared_buffers, per_mesh) texture cells of each set-based model.
fn texture_pairs() -> Vec<(String, String)> {
    ["descriptor_indexing", "descriptor_buffer"]
        .iter()
        .map(|m| {
            let c = format!("closest_hit.sampled_image.dynamic.nonuniform.{m}");
            (format!("{c}.shared_buffers"), format!("{c}.per_mesh"))
        })
        .collect()
}

/// The layout records' value words, as floats.
fn values(records: &[u8]) -> Vec<[f32; 4]> {
    let word = |r: &[u8], k: usize| u32::from_le_bytes(r[k..k + 4].try_into().unwrap());
    records
        .chunks(RECORD)
        .filter(|r| word(r, 0) & FLAG_LAYOUT != 0)
        .map(|r| [0, 1, 2, 3].map(|k| f32::from_bits(word(r, 48 + 4 * k))))
        .collect()
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

/// Both layouts pass and agree; the texture cells pass, sample at least `textures` texture
/// elements, and hold the geometry cells' vertex indices (their words before the value).
fn layouts_pass_and_agree(dir: &Path, scene: Option<&Path>, textures: usize) {
    let (code, r) = run_layouts(dir, scene, &[]);
    assert_eq!(code, Some(0), "{r}");
    let (shared, _) = &pairs()[0];
    for id in texture_cells() {
        assert_eq!(outcome(&r, &id), "pass", "{id}: {}", reason(&r, &id));
        let (recs, geometry) = (records(dir, &id), records(dir, shared));
        let mut elements: Vec<i64> = values(&recs).iter().map(|v| v[2] as i64).collect();
        elements.sort_unstable();
        elements.dedup();
        elements.retain(|e| *e >= 0);
        assert!(elements.len() >= textures, "{id}: sampled only texture elements {elements:?}");
        let indices = |b: &[u8]| -> Vec<Vec<u8>> {
            b.chunks(RECORD).map(|r| [&r[..4], &r[32..48]].concat()).collect()
        };
        assert_eq!(indices(&recs), indices(&geometry), "{id}: other triangles than {shared}");
    }
    for (shared, per_mesh) in pairs().into_iter().chain(texture_pairs()) {
        assert_eq!((outcome(&r, &shared), outcome(&r, &per_mesh)), ("pass".into(), "pass".into()));
        let (differ, fetched) = disagreement(&records(dir, &shared), &records(dir, &per_mesh));
        assert_eq!(differ, 0, "{shared} and {per_mesh} disagree on {differ} records");
        assert!(fetched > 100, "{shared}: only {fetched} fetching records");
    }
}

#[test]
fn both_layouts_pass_and_agree_word_for_word_on_both_scenes() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (file, procedural) = (dir.path().join("file"), dir.path().join("procedural"));
    layouts_pass_and_agree(&file, Some(&dir.path().join("scene.gltf")), 2);
    layouts_pass_and_agree(&procedural, None, 4);
}

/// The agreement check's own twin: each layout on a scene of its own (another seed) passes
/// against its reference, and the records disagree.
#[test]
fn layouts_fed_different_scenes_pass_but_disagree() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let (code_a, ra) = run_layouts(&a, None, &["--seed", "1"]);
    let (code_b, rb) = run_layouts(&b, None, &["--seed", "2"]);
    assert_eq!((code_a, code_b), (Some(0), Some(0)), "{ra}\n{rb}");
    for (shared, per_mesh) in pairs().into_iter().chain(texture_pairs()) {
        let (differ, _) = disagreement(&records(&a, &shared), &records(&b, &per_mesh));
        assert!(
            differ > 100,
            "{shared} (seed 1) and {per_mesh} (seed 2) agree: the check cannot fail"
        );
    }
}

/// The texture cells on a glTF scene whose materials have no texture: not run, with why and
/// what to do; the geometry cells still pass.
#[test]
fn a_scene_without_textures_leaves_the_texture_cells_not_implemented() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut g: Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("scene.gltf")).unwrap()).unwrap();
    for m in g["materials"].as_array_mut().unwrap() {
        m["pbrMetallicRoughness"].as_object_mut().unwrap().remove("baseColorTexture");
    }
    for k in ["textures", "images", "samplers"] {
        g.as_object_mut().unwrap().remove(k);
    }
    let bare = dir.path().join("bare.gltf");
    std::fs::write(&bare, serde_json::to_vec(&g).unwrap()).unwrap();
    let (code, r) = run_layouts(&dir.path().join("out"), Some(&bare), &[]);
    assert_eq!(code, Some(0), "{r}");
    for id in texture_cells() {
        assert_eq!(outcome(&r, &id), "not_implemented");
        let why = reason(&r, &id);
        assert!(why.contains("no base-colour texture") && why.contains("--filter"), "{why}");
    }
    for (shared, per_mesh) in pairs() {
        assert_eq!((outcome(&r, &shared), outcome(&r, &per_mesh)), ("pass".into(), "pass".into()));
    }
}

#[test]
fn a_wrong_fetch_is_a_mismatch_and_breaks_the_agreement() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (code, r) = run_layouts(dir.path(), None, &["--inject-fault", GEOMETRY_FAULT]);
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
    for id in texture_cells() {
        assert_eq!(outcome(&r, &id), "pass", "{id}: the per_mesh fault leaked");
    }
    let (code, r) = run_layouts(
        &dir.path().join("tex"),
        None,
        &["--inject-fault", "resource=sampled_image@value:0.5:7"],
    );
    assert_ne!(code, Some(0));
    for id in texture_cells() {
        assert_eq!(outcome(&r, &id), "mismatch", "{id}: a wrong texel passed");
    }
}

/// GPU twins of the layout cells: `run --mutants` rewrites the texture cells' texture element
/// and the `per_mesh` cells' mesh slot (index-zero, index-next, stride-double: the wrong
/// texture or the wrong mesh buffer, read in bounds), the reference predicts what each reads,
/// and lavapipe's mismatch kills each, on the procedural scene and on `scene make`'s; a survivor
/// (or a pair left unrun) fails here. `index-broadcast` (lane 0's index for all lanes) is killed
/// where the device lists subgroup ballot in closest-hit, else not run with that reason (lavapipe
/// 25's `subgroupSupportedStages` lacks closest-hit). Every other pair is listed with why.
#[test]
fn the_layout_cells_kill_their_wrong_descriptor_mutants() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = dir.path().join("scene.gltf");
    for (name, extra) in [("proc", vec![]), ("file", vec!["--scene", scene.to_str().unwrap()])] {
        let out = dir.path().join(format!("{name}.json"));
        let mut args = vec!["run", "--mutants", "--filter", LAYOUTS, "-o", out.to_str().unwrap()];
        args.extend(extra);
        let o = run(&args);
        assert_eq!(o.status.code(), Some(0), "{name}: {}\n{}", stdout(&o), stderr(&o));
        let r: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
        let entries = r["mutants"]["entries"].as_array().unwrap();
        let cells = texture_cells().into_iter().chain(pairs().into_iter().map(|(_, p)| p));
        for cell in cells {
            for m in ["index-zero", "index-next", "stride-double", "index-broadcast"] {
                let e = entries
                    .iter()
                    .find(|e| e["cell"] == cell.as_str() && e["mutant"] == m)
                    .unwrap_or_else(|| panic!("{name} {cell} {m}: no entry"));
                let why = e["why"].as_str().unwrap_or_default();
                if m == "index-broadcast" && e["status"] == "not_run" {
                    assert!(why.contains("no subgroup ballot in closest_hit"), "{e}");
                    continue;
                }
                assert_eq!(e["status"], "killed", "{name} {cell} {m}: {e}");
                assert!(e["outcome"] == "mismatch" && e["prediction"]["caught"].as_u64() > Some(0));
            }
        }
        for e in
            entries.iter().filter(|e| e["status"] != "killed" && e["mutant"] != "index-broadcast")
        {
            assert!(e["status"] == "no_target" && !e["why"].as_str().unwrap().is_empty(), "{e}");
        }
        // The shared_buffers geometry cells index no descriptor: nothing to rewrite, said so.
        for (shared, _) in pairs() {
            let e = entries
                .iter()
                .find(|e| e["cell"] == shared.as_str() && e["mutant"] == "index-next")
                .unwrap();
            assert!(
                e["status"] == "no_target"
                    && e["why"].as_str().unwrap().contains("reads no descriptor"),
                "{e}"
            );
        }
    }
}
