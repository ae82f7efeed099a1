//! `run --scene` on lavapipe: the test scene written by `scene make`, a filtered matrix run on it
//! and on the procedural scene; every cell gets the same verdict on both, the scene is recorded
//! (path and content hash), the cells the scene cannot discriminate are named with why, and a
//! broken scene is the loader's one line before any device work.
mod common;
use common::*;
use serde_json::Value;
use std::collections::BTreeMap;

/// CI's share: raygen, closest-hit and intersection cells on storage buffers, set-based.
const FILTER: &str =
    "stage=raygen|closest_hit|intersection,descriptor_model=descriptor_indexing,resource=storage_buffer";

fn outcomes(r: &Value) -> BTreeMap<String, String> {
    r["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["id"].as_str().unwrap().into(), c["outcome"].as_str().unwrap().into()))
        .collect()
}

#[test]
fn the_test_scene_gives_the_procedural_verdicts_and_names_its_limits() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = dir.path().join("scene.gltf");
    let (s, p) = (dir.path().join("s.json"), dir.path().join("p.json"));
    let o = run(&[
        "run",
        "--scene",
        scene.to_str().unwrap(),
        "--filter",
        FILTER,
        "-o",
        s.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("undiscriminating: "), "{}", stdout(&o));
    let o_scene = o;
    let o = run(&["run", "--filter", FILTER, "-o", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let read = |p: &std::path::Path| -> Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let (rs, rp) = (read(&s), read(&p));
    let (a, b) = (outcomes(&rs), outcomes(&rp));
    assert!(!a.is_empty());
    assert_eq!(a, b, "every cell: the procedural verdict");
    let file = &rs["scene"]["params"]["file"];
    assert_eq!(file["hash"].as_str().unwrap().len(), 32);
    assert_eq!(rs["scene"]["instances"], 5);
    assert!(rp["scene"]["params"]["file"].is_null() && rp["scene"]["limits"].is_null());
    let limits = rs["scene"]["limits"].as_array().unwrap();
    let named = |needle: &str| -> Vec<String> {
        limits
            .iter()
            .filter(|l| l["why"].as_str().unwrap().contains(needle))
            .flat_map(|l| {
                l["cells"].as_array().unwrap().iter().map(|c| c.as_str().unwrap().to_string())
            })
            .collect()
    };
    let intersection: Vec<&String> = a.keys().filter(|k| k.starts_with("intersection.")).collect();
    assert!(!intersection.is_empty());
    assert_eq!(named("no procedural").len(), intersection.len());
    assert!(named("custom index").iter().all(|c| c.starts_with("closest_hit.")));
    assert!(!named("custom index").is_empty());
    assert!(cost_is_measured(&rs["scene"]["cost"]));
    assert!(as_build_is_timed(&rs["timing"]), "{}", rs["timing"]);
    assert!(stdout(&o_scene).contains("AS build "), "{}", stdout(&o_scene));
}

/// Every worker built the scene's AS, timed apart from (and within) its device setup.
fn as_build_is_timed(t: &Value) -> bool {
    let (mean, max) =
        (t["as_build_ms_mean"].as_f64().unwrap(), t["as_build_ms_max"].as_f64().unwrap());
    t["as_builds"] == t["workers_started"]
        && t["as_builds"].as_u64().is_some_and(|n| n > 0)
        && mean > 0.0
        && max >= mean
        && mean <= t["device_ms_mean"].as_f64().unwrap()
}

/// The AS build's twin: a worker whose cells never trace the scene builds no AS, and the report
/// says so instead of a made-up time.
#[test]
fn a_run_that_traces_no_scene_times_no_as_build() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let r = dir.path().join("c.json");
    let filter =
        "stage=compute,descriptor_model=descriptor_indexing,resource=storage_buffer,index=literal";
    let o = run(&["run", "--filter", filter, "-o", r.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let rep: Value = serde_json::from_slice(&std::fs::read(&r).unwrap()).unwrap();
    let t = &rep["timing"];
    assert!(t["workers_started"].as_u64().is_some_and(|n| n > 0), "{t}");
    assert_eq!(t["as_builds"], 0, "{t}");
    assert!(!as_build_is_timed(t));
    assert!(!stdout(&o).contains("AS build"), "{}", stdout(&o));
}

fn cost_is_measured(c: &Value) -> bool {
    c["load_ms"].as_f64().is_some_and(|x| x >= 0.0)
        && c["reference_ms"].as_f64().is_some_and(|x| x > 0.0)
}

#[test]
fn a_broken_scene_is_one_line_before_the_device() {
    let o = run(&["run", "--scene", "/nonexistent.glb", "--filter", FILTER]);
    assert_one_line_error(&o, 9, "cannot read scene");
}

/// The test scene written into `dir`, its glTF JSON read back.
fn made_scene(dir: &std::path::Path) -> (std::path::PathBuf, Value) {
    let o = run(&["scene", "make", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let path = dir.join("scene.gltf");
    let doc = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    (path, doc)
}

/// The texture cells and the geometry cells of the `shared_buffers` layout.
const TEXTURE_CELLS: &str = "scene_layout=shared_buffers,resource=sampled_image";
const GEOMETRY_CELLS: &str = "scene_layout=shared_buffers|per_mesh,resource=storage_buffer";

/// Every `scene_layout` cell (both layouts, geometry and texture) run on the scene at `path`,
/// which must exit 0: its output and its report's cells (the report beside the scene).
fn layout_run(path: &std::path::Path) -> (std::process::Output, Vec<Value>) {
    let report = path.with_file_name("r.json");
    let (p, r) = (path.to_str().unwrap(), report.to_str().unwrap());
    let o =
        run(&["run", "--scene", p, "--filter", "scene_layout=shared_buffers|per_mesh", "-o", r]);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    let rep: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    (o, rep["cells"].as_array().unwrap().clone())
}

/// A base-colour image that is gone, garbage, or not PNG/JPEG by its uri or mimeType is one line
/// naming `images[N]` and its uri, exit 9 and no report, before any device work, when a texture
/// cell is planned; a run filtered to geometry cells on a scene with both images broken decodes
/// none and passes.
#[test]
fn a_broken_base_colour_image_is_one_line_only_when_a_texture_cell_needs_it() {
    type Break = fn(&std::path::Path, &mut Value);
    let breaks: [(&str, Break, &str); 4] = [
        (
            "gone",
            |d, _| std::fs::remove_file(d.join("checker.png")).unwrap(),
            "images[0] (uri \"checker.png\"): cannot read the image file",
        ),
        (
            "garbage",
            |d, _| std::fs::write(d.join("stripes.png"), b"not a png at all").unwrap(),
            "images[1] (uri \"stripes.png\"): does not decode",
        ),
        (
            "gif",
            |d, doc| {
                std::fs::copy(d.join("checker.png"), d.join("checker.gif")).unwrap();
                doc["images"][0]["uri"] = "checker.gif".into();
            },
            "images[0] (uri \"checker.gif\"): unsupported image encoding",
        ),
        (
            "ktx2",
            |_, doc| doc["images"][1]["mimeType"] = "image/ktx2".into(),
            "images[1] (uri \"stripes.png\"): unsupported image encoding",
        ),
    ];
    for (name, edit, needle) in breaks {
        let dir = rtprobe::tempdir::tempdir().unwrap();
        let (path, mut doc) = made_scene(dir.path());
        edit(dir.path(), &mut doc);
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let report = dir.path().join("r.json");
        let (p, r) = (path.to_str().unwrap(), report.to_str().unwrap());
        let o = run(&["run", "--scene", p, "--filter", TEXTURE_CELLS, "-o", r]);
        assert_one_line_error(&o, 9, needle);
        assert!(!report.exists(), "{name}: a report was written");
    }
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (path, _) = made_scene(dir.path());
    std::fs::remove_file(dir.path().join("checker.png")).unwrap();
    std::fs::write(dir.path().join("stripes.png"), b"garbage").unwrap();
    let report = dir.path().join("r.json");
    let (p, r) = (path.to_str().unwrap(), report.to_str().unwrap());
    let o = run(&["run", "--scene", p, "--filter", GEOMETRY_CELLS, "-o", r]);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", stdout(&o), stderr(&o));
    let rep: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let got = outcomes(&rep);
    assert_eq!(got.len(), 4, "{got:?}");
    assert!(got.values().all(|v| v == "pass"), "{got:?}");
    assert!(stderr(&o).contains("textures none"), "{}", stderr(&o));
}

/// An image one texel wider than lavapipe's queried `maxImageDimension2D` makes the four texture
/// cells (two layouts, two descriptor models) `unsupported` naming the image, its size and the limit, counted with the plan's
/// unsupported cells; the geometry cells still run. The scene's device memory is printed.
#[test]
fn an_image_past_max_image_dimension_makes_the_texture_cells_unsupported() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (path, _) = made_scene(dir.path());
    let o = run(&["caps", "--json", "--no-device-check"]);
    let caps: Value = serde_json::from_slice(&o.stdout).expect("caps --json");
    let max = find_u64(&caps, "maxImageDimension2D").expect("the queried limit") as u32;
    let file = std::fs::File::create(dir.path().join("checker.png")).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), max + 1, 1);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let texels = vec![200u8; 4 * (max as usize + 1)];
    enc.write_header().unwrap().write_image_data(&texels).unwrap();
    let (o, cells) = layout_run(&path);
    let textures: Vec<&Value> =
        cells.iter().filter(|c| c["id"].as_str().unwrap().contains("sampled_image")).collect();
    assert_eq!(textures.len(), 4);
    let want = format!("images[0] (uri \"checker.png\") is {}×1 texels, more than the device's maxImageDimension2D ({max})", max + 1);
    for c in &textures {
        assert_eq!(c["outcome"], "unsupported", "{c}");
        assert!(c["reason"].as_str().unwrap().contains(&want), "{c}");
    }
    let ran = cells.iter().filter(|c| c["outcome"] == "pass").count();
    assert_eq!(ran, 4, "{}", stdout(&o));
    assert!(stdout(&o).contains("4 to run, 4 unsupported"), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("scene: needs ") && stderr(&o).contains("textures none"),
        "{}",
        stderr(&o)
    );
}

/// The first number under key `key` anywhere in `v`.
fn find_u64(v: &Value, key: &str) -> Option<u64> {
    match v {
        Value::Object(m) => {
            m.get(key).and_then(Value::as_u64).or_else(|| m.values().find_map(|x| find_u64(x, key)))
        }
        Value::Array(a) => a.iter().find_map(|x| find_u64(x, key)),
        _ => None,
    }
}

/// A scene whose materials have no base-colour texture: the texture cells are counted in the plan
/// as not run, with the reason, and the verdict says how many did not run (before, the worker
/// found it and the verdict said every planned cell ran); the geometry cells pass.
#[test]
fn a_scene_without_textures_counts_its_texture_cells_as_not_run_with_why() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (path, mut doc) = made_scene(dir.path());
    for m in doc["materials"].as_array_mut().unwrap() {
        m["pbrMetallicRoughness"].as_object_mut().unwrap().remove("baseColorTexture");
    }
    for k in ["textures", "images", "samplers"] {
        doc.as_object_mut().unwrap().remove(k);
    }
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let (o, cells) = layout_run(&path);
    let out = stdout(&o);
    assert!(out.contains("(4 to run, 0 unsupported, 4 not implemented in rtprobe)"), "{out}");
    assert!(out.contains("4 planned cells did not run"), "{out}");
    let textures: Vec<&Value> =
        cells.iter().filter(|c| c["id"].as_str().unwrap().contains("sampled_image")).collect();
    assert_eq!(textures.len(), 4);
    for c in &textures {
        assert_eq!(c["outcome"], "not_implemented", "{c}");
        assert!(c["reason"].as_str().unwrap().contains("no base-colour texture"), "{c}");
    }
    assert_eq!(cells.iter().filter(|c| c["outcome"] == "pass").count(), 4, "{out}");
}

/// An image whose header claims 40000 × 40000 texels (its body one texel): its size comes from
/// the header alone, so the texture cells are `unsupported` by the device's limit and nothing
/// allocates its 6.4 GB of texels (before, the check decoded first and a run under a memory
/// limit aborted with a backtrace).
#[test]
fn an_oversized_header_is_unsupported_without_decoding_the_image() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (path, _) = made_scene(dir.path());
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, 1, 1);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header().unwrap().write_image_data(&[1, 2, 3, 4]).unwrap();
    bytes[16..20].copy_from_slice(&40000u32.to_be_bytes());
    bytes[20..24].copy_from_slice(&40000u32.to_be_bytes());
    let mut c = !0u32;
    for &b in &bytes[12..29] {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    bytes[29..33].copy_from_slice(&(!c).to_be_bytes());
    std::fs::write(dir.path().join("checker.png"), &bytes).unwrap();
    let (o, cells) = layout_run(&path);
    let (textures, geometry): (Vec<&Value>, Vec<&Value>) =
        cells.iter().partition(|c| c["id"].as_str().unwrap().contains("sampled_image"));
    assert_eq!(textures.len(), 4);
    for c in &textures {
        assert_eq!(c["outcome"], "unsupported", "{c}");
        assert!(c["reason"].as_str().unwrap().contains("40000×40000"), "{c}");
    }
    assert!(geometry.iter().all(|c| c["outcome"] == "pass"), "{}", stdout(&o));
}

/// A large scene's acceleration-structure cells are judged under a short `--timeout`: the CPU
/// reference's AS probe rays are traced in the worker's setup (under `--setup-timeout`), not in
/// the first AS cell's check, where on a 2M-triangle scene they took ~0.6 s and every AS cell
/// timed out in its check in turn (6 false `timeout` findings before the fix).
#[test]
fn a_large_scenes_as_cells_are_not_timed_out_by_the_reference() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let scene = dir.path().join("big");
    let made = run(&["scene", "make", "--triangles", "2000000", "--glb", scene.to_str().unwrap()]);
    assert_eq!(made.status.code(), Some(0), "{}", stderr(&made));
    let r = dir.path().join("as.json");
    let filter = "stage=raygen|miss,resource=acceleration_structure|storage_buffer,index=literal,descriptor_model=descriptor_indexing";
    let glb = scene.join("scene.glb");
    let args = ["run", "--scene", glb.to_str().unwrap(), "--filter", filter, "--patches", "none"];
    let o = run(&[&args[..], &["-j", "1", "--timeout", "0.4", "-o", r.to_str().unwrap()]].concat());
    let rep: Value = serde_json::from_slice(&std::fs::read(&r).unwrap()).unwrap();
    let got = outcomes(&rep);
    assert!(got.keys().any(|id| id.contains("acceleration_structure")), "{got:?}");
    assert!(got.values().all(|o| o == "pass"), "{got:?}\n{}", stdout(&o));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// A `--scene` file with one instance: the probed arrays still hold the constant slots
/// (`SPEC_SLOT` 5, `PUSH_SLOT` 7), and a dynamic index keeps the shader's mask. Before, one
/// instance gave arrays of 4 slots, the
/// spec-constant and push-constant cells read past them, and lavapipe crashed on 236 cells of a
/// public sample scene — false findings of rtprobe's own making.
#[test]
fn a_one_instance_scene_keeps_the_constant_slots_inside_the_arrays() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (path, mut doc) = made_scene(dir.path());
    // A node whose mesh index (the custom index) has bit 2 set: the hit stages' mask must stay
    // the push block's (0 for one instance), not one derived from the widened slot count.
    // (copies of the first mesh up to index 4)
    let meshes = doc["meshes"].as_array_mut().unwrap();
    while meshes.len() < 5 {
        meshes.push(meshes[0].clone());
    }
    let mesh = 4;
    let nodes = doc["nodes"].as_array().unwrap();
    let node = nodes.iter().position(|n| n.get("mesh").is_some()).expect("a node with a mesh");
    doc["nodes"][node]["mesh"] = serde_json::json!(mesh);
    doc["scenes"][0]["nodes"] = serde_json::json!([node]);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let info = run(&["scene", "info", path.to_str().unwrap()]);
    assert!(stdout(&info).contains(" 1 instances"), "{}", stdout(&info));
    let out = dir.path().join("r.json");
    let filter = "stage=raygen|closest_hit,resource=storage_buffer|acceleration_structure,\
                  index=spec_constant|push_constant|dynamic,descriptor_model=descriptor_indexing";
    let o = run(&[
        "run",
        "--scene",
        path.to_str().unwrap(),
        "--filter",
        filter,
        "--no-confirm",
        "--patches",
        "none",
        "-o",
        out.to_str().unwrap(),
    ]);
    let r: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    let ran: Vec<&Value> =
        r["cells"].as_array().unwrap().iter().filter(|c| c["outcome"] != "unsupported").collect();
    assert!(ran.len() >= 8, "{}", stdout(&o));
    for c in &ran {
        assert_eq!(c["outcome"], "pass", "{c}");
    }
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
}
