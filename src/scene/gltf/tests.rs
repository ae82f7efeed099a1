//! The loader against scenes `make` writes, edited into every kind of bad input.
use super::make::{make, MakeOptions};
use super::*;
use crate::model::SceneParams;
use glam::{Mat4, Quat, Vec3};

fn scene(glb: bool) -> (crate::tempdir::TempDir, std::path::PathBuf) {
    let dir = crate::tempdir::tempdir().unwrap();
    let path = make(dir.path(), MakeOptions { triangles: 0, glb }).unwrap();
    (dir, path)
}

/// The loader's error for `path` after `edit` changed its JSON.
fn edited(edit: impl Fn(&mut serde_json::Value)) -> String {
    let e = load_edited(edit).err().expect("the edit breaks the scene");
    assert!(!e.contains('\n'), "one line: {e}");
    e
}

#[test]
fn the_test_scene_loads_with_its_meshes_nodes_materials_and_camera() {
    let (_d, path) = scene(false);
    let s = Loaded::load(&path).unwrap();
    let tris: Vec<u32> = s.meshes.iter().map(|m| m.triangle_count()).collect();
    assert_eq!(tris, vec![128, 6, 2]);
    assert_eq!(s.meshes[1].primitives.len(), 2);
    assert_eq!(s.meshes[1].primitives[1].first_triangle, 2);
    assert_eq!(s.meshes[1].primitives[1].vertex_offset, 6);
    assert_eq!(s.meshes[1].triangle(2), [6, 8, 7]);
    assert_eq!(s.materials[1].emissive, [0.05, 0.0, 0.15]);
    assert_eq!(s.materials[2].base_color_texture, Some(1));
    assert_eq!(s.instances.iter().map(|i| i.mesh).collect::<Vec<_>>(), vec![0, 1, 2, 2, 2]);
    assert_eq!(s.triangles(), 128 + 6 + 3 * 2);
    assert_eq!(s.materials[2].alpha, Alpha::Mask(0.5));
    assert!(s.opaque(0, 0) && s.opaque(1, 0) && !s.opaque(1, 1) && !s.opaque(2, 0));
    assert_eq!(s.materials[0].base_color_image, Some(0));
    assert!(s.camera.is_some());
    assert_eq!(s.meshes[0].normals.len(), s.meshes[0].positions.len());
    assert_eq!(s.meshes[0].uvs.len(), s.meshes[0].positions.len());
    // The world matrix of "leaf b": world root, then "bush", then its own.
    let y = Vec3::Y;
    let root =
        Mat4::from_rotation_translation(Quat::from_axis_angle(y, 0.3), Vec3::new(0.0, -0.2, 0.0));
    let bush =
        Mat4::from_rotation_translation(Quat::from_axis_angle(y, 0.8), Vec3::new(1.2, 0.3, -0.4));
    let leaf =
        Mat4::from_rotation_translation(Quat::from_axis_angle(y, 1.2), Vec3::new(0.4, 0.6, 0.2));
    assert!(
        s.instances[3].world.abs_diff_eq(root * bush * leaf, 1e-5),
        "{:?}",
        s.instances[3].world
    );
}

#[test]
fn images_are_decoded_one_at_a_time_when_asked() {
    for glb in [false, true] {
        let (_d, path) = scene(glb);
        let s = Loaded::load(&path).unwrap();
        assert_eq!(s.images, 2);
        let checker = s.decode_image(0).unwrap();
        assert_eq!((checker.width, checker.height, checker.rgba8.len()), (16, 16, 1024));
        assert_eq!(&checker.rgba8[..4], &[230, 230, 230, 255]);
        let stripes = s.decode_image(1).unwrap();
        assert_eq!((stripes.rgba8[3], stripes.rgba8[4 * 4 + 3]), (255, 0), "alpha stripes");
        assert!(s.decode_image(2).unwrap_err().to_string().contains("images[2]"));
    }
}

#[test]
fn a_glb_holds_the_same_scene_as_the_gltf() {
    let (_a, gltf) = scene(false);
    let (_b, glb) = scene(true);
    let (a, b) = (Loaded::load(&gltf).unwrap(), Loaded::load(&glb).unwrap());
    assert_eq!(a.meshes, b.meshes);
    assert_eq!(a.instances, b.instances);
    assert_eq!(a.materials, b.materials);
}

#[test]
fn the_fitted_scene_fills_the_view_keeps_facing_and_uses_mesh_indices() {
    let (_d, path) = scene(false);
    let s = Loaded::load(&path).unwrap();
    let scene = fit::to_scene(&s, &SceneParams::default());
    assert_eq!(scene.instances.len(), 5);
    assert_eq!(scene.params.instances, 5);
    assert_eq!(scene.meshes.len(), 4, "three meshes and the floor");
    assert_eq!(scene.meshes[1].geometries, vec![0..2, 2..6]);
    let customs: Vec<u32> = scene.instances.iter().map(|i| i.custom_index).collect();
    assert_eq!(customs, vec![0, 1, 2, 2, 2]);
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for i in &scene.instances {
        let t = i.transform;
        let m = Mat4::from_cols_array_2d(&[
            [t[0][0], t[1][0], t[2][0], 0.0],
            [t[0][1], t[1][1], t[2][1], 0.0],
            [t[0][2], t[1][2], t[2][2], 0.0],
            [t[0][3], t[1][3], t[2][3], 1.0],
        ]);
        assert!(m.determinant() > 0.0, "a rotation and a positive scale keep triangle facing");
        let crate::scene::Geometry::Mesh(k) = i.geometry else { panic!("meshes only") };
        for p in &scene.meshes[k].positions {
            let q = m.transform_point3(Vec3::from(*p));
            (lo, hi) = (lo.min(q), hi.max(q));
        }
    }
    let half = crate::scene::VIEW_HALF;
    assert!(lo.x >= -half && hi.x <= half && lo.y >= -half && hi.y <= half, "{lo} {hi}");
    assert!((hi.x - lo.x).max(hi.y - lo.y) > 1.7 * half, "fills the view: {lo} {hi}");
    assert!(lo.z >= -9.0 - 1e-4 && (hi.z - 5.0).abs() < 1e-4, "{lo} {hi}");
}

#[test]
fn a_large_scene_has_the_triangles_asked_for() {
    let dir = crate::tempdir::tempdir().unwrap();
    let path = make(dir.path(), MakeOptions { triangles: 20_000, glb: true }).unwrap();
    let s = Loaded::load(&path).unwrap();
    assert!(s.triangles() >= 20_000, "{}", s.triangles());
    assert_eq!(s.instances.len(), 16);
}

#[test]
fn bad_input_is_one_line_naming_the_part() {
    let e =
        Loaded::load(std::path::Path::new("/nonexistent/scene.gltf")).err().unwrap().to_string();
    assert!(e.contains("cannot read scene") && !e.contains('\n'), "{e}");
    let e = edited(|d| d["extensionsRequired"] = serde_json::json!(["KHR_draco_mesh_compression"]));
    assert!(e.contains("requires extension KHR_draco_mesh_compression"), "{e}");
    assert!(e.contains("mesh compression off"), "{e}");
    let e = edited(|d| d["meshes"][0]["primitives"][0]["mode"] = serde_json::json!(1));
    assert!(e.contains("mesh 0 (ground), primitive 0") && e.contains("not triangles"), "{e}");
    let e = edited(|d| d["buffers"][0]["byteLength"] = serde_json::json!(99_999_999));
    assert!(e.contains("buffer 0") && e.contains("truncated"), "{e}");
    let e = edited(|d| d["buffers"][0]["uri"] = serde_json::json!("missing.bin"));
    assert!(e.contains("beside the .gltf"), "{e}");
    let e = edited(|d| {
        d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = serde_json::json!(999)
    });
    assert!(e.contains("not glTF 2.0") && e.contains("invalid at"), "{e}");
    let e = edited(|d| d["nodes"][4]["children"] = serde_json::json!([3]));
    assert!(e.contains("node 3: reached twice"), "a cycle ends: {e}");
    let e = edited(|d| d["extensionsRequired"] = serde_json::json!(["KHR_texture_transform"]));
    assert!(e.contains("requires extension KHR_texture_transform"), "{e}");
    assert!(e.contains("export it without KHR_texture_transform") && !e.contains("compression"));
    let e = edited(|d| d["scenes"][0]["nodes"] = serde_json::json!([7]));
    assert!(e.contains("no triangles"), "{e}");
}

#[test]
fn broken_json_and_a_texture_file_that_is_gone_are_refused() {
    let (_d, path) = scene(false);
    let text = std::fs::read(&path).unwrap();
    std::fs::write(&path, &text[..text.len() / 2]).unwrap();
    let e = Loaded::load(&path).err().unwrap().to_string();
    assert!(e.contains("not glTF 2.0") && !e.contains('\n'), "{e}");
    let (d2, path) = scene(false);
    std::fs::remove_file(d2.path().join("checker.png")).unwrap();
    let s = Loaded::load(&path).expect("images are not read at load");
    let e = s.decode_image(0).unwrap_err().to_string();
    assert!(
        e.contains("images[0] (uri \"checker.png\"): cannot read the image file")
            && !e.contains('\n'),
        "{e}"
    );
}

/// A GLB of `json` alone (no BIN chunk).
fn glb_without_bin(json: &[u8]) -> Vec<u8> {
    let mut json = json.to_vec();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((20 + json.len() as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out
}

#[test]
fn a_glb_without_bin_reads_data_uris_and_refuses_a_buffer_that_needs_bin() {
    use base64::Engine as _;
    let (d, path) = scene(false);
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let bin = std::fs::read(d.path().join("scene.bin")).unwrap();
    let data = base64::engine::general_purpose::STANDARD.encode(bin);
    doc["buffers"][0]["uri"] =
        serde_json::json!(format!("data:application/octet-stream;base64,{data}"));
    let glb = d.path().join("embedded.glb");
    std::fs::write(&glb, glb_without_bin(&serde_json::to_vec(&doc).unwrap())).unwrap();
    let (a, b) = (Loaded::load(&path).unwrap(), Loaded::load(&glb).unwrap());
    assert_eq!(a.meshes, b.meshes);
    assert_eq!(b.decode_image(0).unwrap(), a.decode_image(0).unwrap(), "its images beside it");
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    std::fs::write(&glb, glb_without_bin(&serde_json::to_vec(&doc).unwrap())).unwrap();
    let e = Loaded::load(&glb).err().unwrap().to_string();
    assert!(
        e.contains("buffer 0: has no uri, so it is the GLB's BIN chunk, which is missing"),
        "{e}"
    );
}

#[test]
fn a_truncated_glb_and_other_versions_are_not_gltf_2() {
    let (_d, path) = scene(true);
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 8]).unwrap();
    let e = Loaded::load(&path).err().unwrap().to_string();
    assert!(e.contains("not glTF 2.0: GLB header: length") && !e.contains('\n'), "{e}");
    let e = edited(|d| d["asset"]["version"] = serde_json::json!("1.0"));
    assert!(e.contains("not glTF 2.0: invalid at asset.version: \"1.0\", not 2.x"), "{e}");
    let e = edited(|d| {
        d["asset"]["version"] = serde_json::json!("1.0");
        d["extensionsRequired"] = serde_json::json!(["KHR_materials_common"]);
    });
    assert!(e.contains("requires extension KHR_materials_common"), "extensions first: {e}");
}

/// The bytes that once panicked gltf-json 1.4.1's validation (a POSITION accessor past the end,
/// indexed unchecked), and the checks of index values and counts the reader makes itself.
#[test]
fn accessor_indices_and_values_out_of_range_are_one_line() {
    let e = edited(|d| {
        d["meshes"][1]["primitives"][1]["attributes"]["POSITION"] = serde_json::json!(4096)
    });
    assert!(
        e.contains("invalid at meshes[1].primitives[1].attributes.POSITION: accessor 4096 of"),
        "{e}"
    );
    let e = edited(|d| d["accessors"][0]["count"] = serde_json::json!(3));
    assert!(
        e.contains("mesh 0 (ground), primitive 0: index") && e.contains("past its 3 vertices"),
        "{e}"
    );
    let e = edited(|d| d["accessors"][3]["count"] = serde_json::json!(4));
    assert!(e.contains("4 indices, not a multiple of 3"), "{e}");
    let e = edited(|d| d["accessors"][0]["count"] = serde_json::json!(u32::MAX));
    assert!(e.contains("invalid at accessors[0]: 4294967295 elements"), "no allocation: {e}");
    let e = edited(|d| {
        d["meshes"][0]["primitives"][0]["attributes"].as_object_mut().unwrap().remove("POSITION");
    });
    assert!(e.contains("primitive 0: no POSITION attribute"), "{e}");
}

/// Seeded byte edits of the test GLB (its header, JSON and BIN; some cut short) and edits of the
/// numbers of its JSON (indices, counts, offsets, lengths, strides): each loads or is one line, never a panic. `rtprobe scene info` with the `gltf`
/// crate panicked on 7 of 1,800 such files (its mesh reader, mesh/mod.rs:396 and :430).
#[test]
fn mutated_files_load_or_fail_in_one_line() {
    let (d, path) = scene(true);
    let good = std::fs::read(&path).unwrap();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    let numbers = [0u64, 1, 3, 7, 255, 256, 65535, 1 << 31, u32::MAX as u64, 1 << 53, u64::MAX];
    let mut loaded = 0;
    for i in 0..400 {
        let mut b = good.clone();
        for _ in 0..1 + next(4) {
            let k = if next(10) < 7 { next(2000) } else { next(b.len()) };
            b[k] = next(256) as u8;
        }
        if i % 5 == 0 {
            b.truncate(next(b.len()));
        }
        let file = d.path().join("m.glb");
        std::fs::write(&file, &b).unwrap();
        match Loaded::load(&file) {
            Ok(_) => loaded += 1,
            Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
        }
    }
    assert!(loaded > 0 && loaded < 400, "some edits load, others are refused: {loaded}");
    let (t, path) = scene(false);
    let text = std::fs::read_to_string(&path).unwrap();
    loaded = 0;
    let spots: Vec<usize> = (text.match_indices(':').map(|(k, _)| k + 1))
        .filter(|&k| text.as_bytes().get(k).is_some_and(u8::is_ascii_digit))
        .collect();
    for _ in 0..200 {
        let at = spots[next(spots.len())];
        let len = text[at..].find(|c: char| !c.is_ascii_digit()).unwrap_or(0);
        let n = numbers[next(numbers.len())];
        let file = t.path().join("m.gltf");
        std::fs::write(&file, format!("{}{n}{}", &text[..at], &text[at + len..])).unwrap();
        match Loaded::load(&file) {
            Ok(_) => loaded += 1,
            Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
        }
    }
    assert!(loaded > 0 && loaded < 200, "some edits load, others are refused: {loaded}");
}

/// A sparse accessor is valid glTF 2.0 that rtprobe does not read: named as the part of the file
/// with what to do, never as a file that "is not glTF 2.0". Twin: a broken accessor (not sparse)
/// is still the parse error.
#[test]
fn a_sparse_accessor_is_named_as_a_part_not_as_a_broken_file() {
    let sparse = edited(|d| {
        let pos = d["meshes"][0]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap();
        d["accessors"][pos as usize]["sparse"] = serde_json::json!({"count": 1});
    });
    assert!(sparse.contains("attributes.POSITION: accessor"), "{sparse}");
    assert!(sparse.contains("a sparse accessor (valid glTF 2.0)"), "{sparse}");
    assert!(!sparse.contains("is not glTF 2.0"), "{sparse}");
    let broken = edited(|d| {
        let pos = d["meshes"][0]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap();
        d["accessors"][pos as usize]["type"] = serde_json::json!("VEC2");
    });
    assert!(broken.contains("is not glTF 2.0"), "{broken}");
}

/// The scene `make` writes, its JSON edited by `edit`, loaded.
fn load_edited(edit: impl Fn(&mut serde_json::Value)) -> Result<Loaded, String> {
    let (_dir, path) = scene(false);
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    edit(&mut doc);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    Loaded::load(&path).map_err(|e| e.to_string())
}

/// An accessor without a `bufferView` is zeros (the `accessor.bufferView` schema: "When
/// undefined, the accessor MUST be initialized with zeros"): a NORMAL or TEXCOORD_0 so loads as
/// zeros, and is dropped, never read, where its count is not the positions' (2^40 here: no
/// allocation of it). Twins: the same edit on POSITION or on the indices is refused in one line
/// (every vertex or index zero: no triangle to trace), and the file as written has no zeros.
#[test]
fn an_accessor_without_a_buffer_view_is_zeros() {
    let attr = |d: &serde_json::Value, name: &str| {
        d["meshes"][0]["primitives"][0]["attributes"][name].as_u64().unwrap() as usize
    };
    let plain = load_edited(|_| {}).unwrap();
    assert!(plain.meshes[0].normals.iter().any(|n| *n != [0.0; 3]));
    assert!(plain.meshes[0].uvs.iter().any(|t| *t != [0.0; 2]));
    let zeros = load_edited(|d| {
        for name in ["NORMAL", "TEXCOORD_0"] {
            let k = attr(d, name);
            d["accessors"][k].as_object_mut().unwrap().remove("bufferView");
        }
    })
    .unwrap();
    let m = &zeros.meshes[0];
    assert_eq!((m.normals.len(), m.uvs.len()), (m.positions.len(), m.positions.len()));
    assert!(m.normals.iter().all(|n| *n == [0.0; 3]) && m.uvs.iter().all(|t| *t == [0.0; 2]));
    let huge = load_edited(|d| {
        let k = attr(d, "NORMAL");
        d["accessors"][k].as_object_mut().unwrap().remove("bufferView");
        d["accessors"][k]["count"] = serde_json::json!(1u64 << 40);
    })
    .unwrap();
    assert!(huge.meshes[0].normals.is_empty(), "a count unlike the positions' is dropped");
    let positions = edited(|d| {
        let k = attr(d, "POSITION");
        d["accessors"][k].as_object_mut().unwrap().remove("bufferView");
    });
    assert!(
        positions.contains("POSITION accessor") && positions.contains("no bufferView"),
        "{positions}"
    );
    let indices = edited(|d| {
        let k = d["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
        d["accessors"][k].as_object_mut().unwrap().remove("bufferView");
    });
    assert!(indices.contains("indices accessor") && indices.contains("no bufferView"), "{indices}");
}

/// A mesh no node uses is not read: one of lines loads (named unused, empty), and the file's
/// other meshes are as before. Twin: the same mesh placed by a node refuses the file.
#[test]
fn a_mesh_no_node_uses_is_not_read() {
    let add_lines = |d: &mut serde_json::Value| {
        let mut lines = d["meshes"][0].clone();
        lines["primitives"][0]["mode"] = serde_json::json!(1);
        lines["name"] = serde_json::json!("debug lines");
        d["meshes"].as_array_mut().unwrap().push(lines);
    };
    let s = load_edited(add_lines).unwrap();
    let last = s.meshes.last().unwrap();
    assert!(last.unused && last.positions.is_empty() && last.primitives.is_empty(), "{last:?}");
    assert!(s.meshes[..s.meshes.len() - 1].iter().all(|m| !m.unused && !m.indices.is_empty()));
    let placed = edited(|d| {
        add_lines(d);
        let m = d["meshes"].as_array().unwrap().len() - 1;
        d["nodes"].as_array_mut().unwrap().push(serde_json::json!({"mesh": m}));
        let n = d["nodes"].as_array().unwrap().len() - 1;
        d["scenes"][0]["nodes"].as_array_mut().unwrap().push(serde_json::json!(n));
    });
    assert!(
        placed.contains("(debug lines), primitive 0") && placed.contains("not triangles"),
        "{placed}"
    ); // Unnamed by any node, its accessors are not held to what rtprobe reads (sparse: valid glTF
       // 2.0 it does not read); the sparse test above is the twin for a mesh a node places.
    let sparse = load_edited(|d| {
        add_lines(d);
        let pos = d["meshes"][0]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap();
        let mut copy = d["accessors"][pos as usize].clone();
        copy["sparse"] = serde_json::json!({"count": 1});
        d["accessors"].as_array_mut().unwrap().push(copy);
        let k = d["accessors"].as_array().unwrap().len() - 1;
        let last = d["meshes"].as_array().unwrap().len() - 1;
        d["meshes"][last]["primitives"][0]["attributes"]["POSITION"] = serde_json::json!(k);
    });
    assert!(sparse.is_ok_and(|s| s.meshes.last().unwrap().unused));
}

/// An unused mesh before the used ones: the fitted scene has a BLAS for each mesh a node places
/// and none for it (no empty one), each instance on its own mesh's triangles and its custom
/// index still the file's mesh index; the texture table has an entry per BLAS.
#[test]
fn an_unused_mesh_first_is_no_blas_and_shifts_no_instance() {
    let s = load_edited(|d| {
        let mut lines = d["meshes"][0].clone();
        lines["primitives"][0]["mode"] = serde_json::json!(1);
        d["meshes"].as_array_mut().unwrap().insert(0, lines);
        for n in d["nodes"].as_array_mut().unwrap() {
            if let Some(m) = n["mesh"].as_u64() {
                n["mesh"] = serde_json::json!(m + 1);
            }
        }
    })
    .unwrap();
    assert!(s.meshes[0].unused);
    let scene = fit::to_scene(&s, &SceneParams::default());
    assert_eq!(scene.meshes.len(), 4, "three meshes and the floor");
    assert!(scene.meshes.iter().all(|m| !m.indices.is_empty() && !m.geometries.is_empty()));
    for (inst, node) in scene.instances.iter().zip(&s.instances) {
        let crate::scene::Geometry::Mesh(g) = inst.geometry else { panic!("a mesh instance") };
        assert_eq!(scene.meshes[g].indices.len() as u32, s.meshes[node.mesh].triangle_count());
        assert_eq!(scene.meshes[g].positions, s.meshes[node.mesh].positions);
        assert_eq!(inst.custom_index, node.mesh as u32);
    }
    let textures = crate::scene::textures::SceneTextures::of_file(s);
    assert_eq!(textures.geometry_image.len(), scene.meshes.len(), "one entry per BLAS");
}
