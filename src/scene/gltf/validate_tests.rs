//! Each check against the test scene's JSON edited to break it (the twin that makes it fail),
//! and the unedited scene passing.
use super::*;
use serde_json::{json, Value};

/// The test scene's JSON (`make`).
fn scene() -> Value {
    let dir = crate::tempdir::tempdir().unwrap();
    let o = crate::scene::gltf::make::MakeOptions { triangles: 0, glb: false };
    let path = crate::scene::gltf::make::make(dir.path(), o).unwrap();
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// `check`'s error after `edit`.
fn broken(base: &Value, edit: impl Fn(&mut Value)) -> String {
    let mut doc = base.clone();
    edit(&mut doc);
    let root: Root = serde_json::from_value(doc).unwrap();
    let e = check(&root).expect_err("the edit breaks the scene");
    assert!(!e.contains('\n') && e.starts_with("invalid at "), "{e}");
    e
}

#[test]
fn the_test_scene_passes() {
    let root: Root = serde_json::from_value(scene()).unwrap();
    check(&root).unwrap();
    let head: crate::scene::gltf::doc::Head = serde_json::from_value(scene()).unwrap();
    version(head.asset.as_ref()).unwrap();
}

#[test]
fn versions_other_than_2_x_are_refused() {
    let v = |ver: &str, min: Option<&str>| {
        version(Some(&Asset { version: ver.into(), min_version: min.map(String::from) }))
    };
    assert!(v("2.0", None).is_ok() && v("2.1", Some("2.0")).is_ok());
    assert!(v("1.0", None).unwrap_err().contains("asset.version: \"1.0\", not 2.x"));
    assert!(v("3.0", None).is_err() && v("2", None).is_err() && v("2.x", None).is_err());
    assert!(v("2.1", Some("2.1")).unwrap_err().contains("asset.minVersion"));
    assert!(version(None).unwrap_err().contains("asset: missing"));
}

/// An edit of the scene's JSON.
type Edit = fn(&mut Value);

#[test]
fn indices_past_their_arrays_name_the_property() {
    let s = scene();
    let cases: [(&str, Edit); 9] = [
        ("meshes[0].primitives[1].indices: accessor 99 of", |d| {
            d["meshes"][0]["primitives"]
                .as_array_mut()
                .unwrap()
                .push(json!({"attributes": {"POSITION": 0}, "indices": 99}))
        }),
        ("meshes[0].primitives[0].attributes.POSITION: accessor 999 of", |d| {
            d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(999)
        }),
        ("meshes[0].primitives[0].material: material 9 of 3", |d| {
            d["meshes"][0]["primitives"][0]["material"] = json!(9)
        }),
        ("nodes[1].mesh: mesh 7 of 3", |d| d["nodes"][1]["mesh"] = json!(7)),
        ("nodes[0].children[0]: node 40 of", |d| d["nodes"][0]["children"][0] = json!(40)),
        ("scenes[0].nodes[0]: node 40 of", |d| d["scenes"][0]["nodes"][0] = json!(40)),
        ("scene: scene 3 of 1", |d| d["scene"] = json!(3)),
        ("textures[0].source: image 5 of 2", |d| d["textures"][0]["source"] = json!(5)),
        ("bufferViews[0].buffer: buffer 2 of 1", |d| d["bufferViews"][0]["buffer"] = json!(2)),
    ];
    for (want, edit) in cases {
        let e = broken(&s, edit);
        assert!(e.contains(want), "{want}: {e}");
    }
    let e = broken(&s, |d| {
        d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = json!(4)
    });
    assert!(e.contains("baseColorTexture.index: texture 4 of 2"), "{e}");
    let e = broken(&s, |d| d["nodes"][7]["camera"] = json!(1));
    assert!(e.contains("nodes[7].camera: camera 1 of 1"), "{e}");
    let e = broken(&s, |d| d["textures"][0]["sampler"] = json!(1));
    assert!(e.contains("textures[0].sampler: sampler 1 of 1"), "{e}");
}

#[test]
fn ranges_and_strides_past_their_limits_are_refused() {
    let s = scene();
    let e = broken(&s, |d| d["bufferViews"][0]["byteLength"] = json!(u64::MAX));
    assert!(e.contains("bufferViews[0]: bytes 0 + 18446744073709551615 past buffer 0"), "{e}");
    let e = broken(&s, |d| d["accessors"][0]["count"] = json!(100_000));
    assert!(
        e.contains("accessors[0]: 100000 elements of 12 bytes") && e.contains("past bufferView 0"),
        "{e}"
    );
    let e = broken(&s, |d| d["accessors"][0]["byteOffset"] = json!(4));
    assert!(e.contains("from byte 4: past bufferView 0"), "the last element one float over: {e}");
    let e = broken(&s, |d| d["accessors"][0]["count"] = json!(u64::MAX));
    assert!(e.contains("accessors[0]:"), "an overflowing count: {e}");
    let e = broken(&s, |d| d["accessors"][0]["count"] = json!(0));
    assert!(e.contains("accessors[0].count: 0"), "{e}");
    for (stride, want) in [
        (2, "not 4 to 252"),
        (256, "not 4 to 252"),
        (14, "not 4 to 252"),
        (8, "less than accessor 0's 12-byte"),
    ] {
        let e = broken(&s, |d| d["bufferViews"][0]["byteStride"] = json!(stride));
        assert!(e.contains(want), "{stride}: {e}");
    }
    let idx = s["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
    let view = s["accessors"][idx]["bufferView"].as_u64().unwrap() as usize;
    let e = broken(&s, |d| d["bufferViews"][view]["byteStride"] = json!(4));
    assert!(e.contains("primitives[0].indices: bufferView") && e.contains("tightly packed"), "{e}");
}

#[test]
fn accessor_types_must_suit_their_semantics() {
    let s = scene();
    let at = |field: &str| {
        s["meshes"][0]["primitives"][0]["attributes"][field].as_u64().unwrap() as usize
    };
    let (pos, nor, uv) = (at("POSITION"), at("NORMAL"), at("TEXCOORD_0"));
    let idx = s["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
    let set = |a: usize, key: &'static str, v: Value| {
        move |d: &mut Value| d["accessors"][a][key] = v.clone()
    };
    let cases = [
        (broken(&s, set(pos, "componentType", json!(5123))), "attributes.POSITION: accessor"),
        (broken(&s, set(nor, "type", json!("VEC2"))), "attributes.NORMAL: accessor 1: VEC2"),
        (broken(&s, set(uv, "componentType", json!(5121))), "TEXCOORD_0: accessor"),
        (broken(&s, set(idx, "componentType", json!(5126))), "indices: accessor"),
        (broken(&s, set(idx, "componentType", json!(5124))), "accessors[3].componentType: 5124"),
        (broken(&s, set(idx, "type", json!("VEC7"))), "type: \"VEC7\""),
        (
            broken(&s, set(pos, "sparse", json!({"count": 1}))),
            "sparse, which rtprobe does not read",
        ),
        (broken(&s, set(pos, "min", Value::Null)), "lacks a 3-component min and max"),
    ];
    for (e, want) in cases {
        assert!(e.contains(want), "{want}: {e}");
    }
    assert!(idx == 3, "the case above names accessors[3]");
    // Without a bufferView an accessor is zeros (valid glTF 2.0: the loader decides what zeros
    // mean for it), but its count is still held to at least 1.
    let mut viewless = s.clone();
    viewless["accessors"][idx].as_object_mut().unwrap().remove("bufferView");
    check(&serde_json::from_value(viewless.clone()).unwrap()).unwrap();
    let e = broken(&viewless, set(idx, "count", json!(0)));
    assert!(e.contains("accessors[3].count: 0"), "{e}");
    // A mesh of no primitive (the schema's minimum is 1) would be a BLAS of no geometry.
    let e = broken(&s, |d| d["meshes"][0]["primitives"] = json!([]));
    assert!(e.contains("meshes[0].primitives: empty (at least 1)"), "{e}");
}

#[test]
fn enumerations_cameras_and_images_are_checked() {
    let s = scene();
    let e = broken(&s, |d| d["meshes"][0]["primitives"][0]["mode"] = json!(7));
    assert!(e.contains("mode: 7, not 0 to 6"), "{e}");
    let e = broken(&s, |d| d["materials"][0]["alphaMode"] = json!("CLIP"));
    assert!(e.contains("materials[0].alphaMode: \"CLIP\""), "{e}");
    let e = broken(&s, |d| d["cameras"][0]["type"] = json!("fisheye"));
    assert!(e.contains("cameras[0].type: \"fisheye\""), "{e}");
    let e = broken(&s, |d| d["cameras"][0]["type"] = json!("orthographic"));
    assert!(e.contains("without its orthographic object"), "{e}");
    let e = broken(&s, |d| d["images"][0] = json!({"bufferView": 0}));
    assert!(e.contains("images[0].mimeType: missing"), "{e}");
    let e = broken(&s, |d| d["images"][0] = json!({}));
    assert!(e.contains("neither uri nor bufferView"), "{e}");
    let e = broken(&s, |d| d["images"][0]["bufferView"] = json!(0));
    assert!(e.contains("both uri and bufferView"), "{e}");
}
