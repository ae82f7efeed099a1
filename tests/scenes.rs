//! `rtprobe scene` end to end: the test scene written by `scene make` and read back by `scene
//! info` (as `--scene` will read it), in both containers, and a broken scene as one-line errors.
mod common;
use common::*;

#[test]
fn the_test_scene_is_written_and_read_back_in_both_containers() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    for (sub, glb, file) in [("a", false, "scene.gltf"), ("b", true, "scene.glb")] {
        let out = dir.path().join(sub);
        let mut args = vec!["scene", "make", out.to_str().unwrap()];
        if glb {
            args.push("--glb");
        }
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let path = out.join(file);
        let o = run(&["scene", "info", path.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = stdout(&o);
        assert!(
            text.contains(
                "3 meshes, 5 instances, 140 triangles traced (136 stored), 3 materials, 2 images"
            ),
            "{text}"
        );
        assert!(text.contains("material leaf: MASK below 0.5 (non-opaque geometry)"), "{text}");
        assert!(text.contains("camera at node 7"), "{text}");
    }
}

#[test]
fn a_broken_scene_is_one_line_and_exit_9() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let o = run(&["scene", "make", dir.path().to_str().unwrap()]);
    assert!(o.status.success());
    let path = dir.path().join("scene.gltf");
    let p = path.to_str().unwrap();
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    doc["extensionsRequired"] = serde_json::json!(["EXT_meshopt_compression"]);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    assert_one_line_error(
        &run(&["scene", "info", p]),
        9,
        "requires extension EXT_meshopt_compression",
    );
    doc["extensionsRequired"] = serde_json::json!([]);
    doc["meshes"][2]["primitives"][0]["mode"] = serde_json::json!(0);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    assert_one_line_error(
        &run(&["scene", "info", p]),
        9,
        "mesh 2 (leaf), primitive 0: mode Points, not triangles",
    );
    std::fs::remove_file(dir.path().join("scene.bin")).unwrap();
    assert_one_line_error(&run(&["scene", "info", p]), 9, "put the buffers beside the .gltf file");
    assert_one_line_error(&run(&["scene", "info", "/nonexistent.glb"]), 9, "cannot read scene");
}
