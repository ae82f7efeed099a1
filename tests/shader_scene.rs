//! End-to-end tests of `rtprobe run --shader --scene` on lavapipe: a glTF-tutorial-style
//! closest-hit written for these tests (`tests/shaders/user/tutorial.rchit`) reads the test
//! scene (`rtprobe scene make`) through the scene description's address in a push constant, and
//! its image is held to a CPU rendering of the same shading over the same fitted scene and rays
//! (the reference's f64 intersection; ambiguous pixels excluded and counted), one BLAS per
//! primitive with the global primitive index as custom index (the tutorial's layout). Its
//! twins, built with `-D WRONG_PRIM_ZERO` and `-D WRONG_POSITIONS`, fail that comparison. With
//! `-D TEXTURED` it multiplies the base colour by the material's texture from `--fill
//! 1.2=scene.textures`, held to the CPU sampling the decoded images as the harness's sampler does
//! (nearest, clamp to edge, sRGB decoded); its twin `-D WRONG_TEX` (the next image) fails. Scene
//! fills and scene files given wrongly are one line, a non-zero exit and no report.
mod common;
use common::*;
use glam::{DMat3, DVec3};
use rtprobe::harness::MISS_MARKER;
use rtprobe::reference::intersect::{self, Culling};
use rtprobe::scene::gltf::{Loaded, Texture};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The light and ambient term of `tutorial.rchit`.
const LIGHT: [f64; 3] = [0.48, 0.64, -0.6];
const AMBIENT: f64 = 0.2;
/// `Shade`'s words per pixel (`common.glsl`): colour, distance, instance, bounces.
const WORDS: usize = 6;

fn user(f: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/shaders/user").join(f).display().to_string()
}

/// The test scene written into a temporary folder.
fn test_scene() -> (rtprobe::tempdir::TempDir, PathBuf) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let o = run(&["scene", "make", &d.path().display().to_string()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let p = d.path().join("scene.gltf");
    (d, p)
}

/// `run --shader F --scene S` with `extra`: the output and the report, if written.
fn scene_run(scene: &Path, extra: &[&str]) -> (std::process::Output, Option<Value>) {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let out = d.path().join("report.json");
    let (shader, scene, out_s) =
        (user("tutorial.rchit"), scene.display().to_string(), out.display().to_string());
    let mut args = vec!["run", "--shader", &shader, "--scene", &scene, "-o", &out_s];
    args.extend_from_slice(extra);
    let o = run(&args);
    let report = std::fs::read(&out).ok().map(|b| serde_json::from_slice(&b).unwrap());
    (o, report)
}

/// Per global primitive index (the custom index the harness gives it: primitives numbered mesh
/// by mesh), its mesh and its index in the mesh.
fn primitives(l: &Loaded) -> Vec<(usize, usize)> {
    l.meshes
        .iter()
        .enumerate()
        .flat_map(|(m, mesh)| (0..mesh.primitives.len()).map(move |p| (m, p)))
        .collect()
}

/// Texel-edge margin, in texels: a UV whose `u·w` or `v·h` lies this close to an integer may
/// pick the neighbouring texel on the device (f32 interpolation) and not on the CPU (f64).
const TEXEL_MARGIN: f64 = 0.01;

/// sRGB-encoded byte `b` as the linear value an `R8G8B8A8_SRGB` sample returns.
fn srgb(b: u8) -> f64 {
    let c = b as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// `t` sampled at `uv` as the harness's sampler does (nearest, clamp to edge, LOD 0: texel
/// `clamp(floor(u·w), 0, w − 1)`), and whether `uv` lies within [`TEXEL_MARGIN`] of a texel edge.
fn sample(t: &Texture, uv: [f64; 2]) -> ([f64; 3], bool) {
    let texel = |u: f64, n: u32| {
        let x = u * n as f64;
        ((x.floor().clamp(0.0, n as f64 - 1.0)) as usize, (x - x.round()).abs() < TEXEL_MARGIN)
    };
    let ((x, ex), (y, ey)) = (texel(uv[0], t.width), texel(uv[1], t.height));
    let at = 4 * (y * t.width as usize + x);
    ([0, 1, 2].map(|k| srgb(t.rgba8[at + k])), ex || ey)
}

/// What the CPU gives one pixel: its colour and the hit's custom index (`None` for a miss),
/// whether the ray is ambiguous, whether its texture coordinate lies on a texel edge, whether it
/// sampled a texture.
struct CpuPixel {
    color: Option<([f64; 3], u32)>,
    ambiguous: bool,
    edge: bool,
    textured: bool,
}

/// The CPU's pixel (`x`, `y`): the closest hit's shading as `tutorial.rchit` computes it, in
/// f64 (with `tex`, the scene's decoded images: as `-D TEXTURED` computes it).
fn cpu_pixel(
    l: &Loaded,
    (s, cull): (&rtprobe::scene::Scene, &Culling),
    tex: Option<&[Texture]>,
    x: u32,
    y: u32,
) -> CpuPixel {
    let (o, d) = s.primary_ray(x, y);
    let r = intersect::trace((s, cull), o, d, |_| true);
    let mut px = CpuPixel { color: None, ambiguous: r.ambiguous, edge: false, textured: false };
    let Some(h) = r.hit else { return px };
    assert_eq!(h.geometry, 0, "one geometry per BLAS");
    let inst = &s.instances[h.instance_id as usize];
    let (mi, pi) = primitives(l)[h.instance as usize];
    let m = &l.meshes[mi];
    let p = &m.primitives[pi];
    let tri = m.triangle(p.first_triangle + h.primitive);
    let w = [1.0 - h.bary[0] - h.bary[1], h.bary[0], h.bary[1]];
    let lerp = |v: &[[f32; 3]]| {
        (0..3)
            .fold(DVec3::ZERO, |n, k| n + DVec3::from(v[tri[k] as usize].map(|f| f as f64)) * w[k])
    };
    let t = inst.transform;
    let obj = DMat3::from_cols_array_2d(&[0, 1, 2].map(|c| [0, 1, 2].map(|r| t[r][c] as f64)));
    let world_n = (obj.inverse().transpose() * lerp(&m.normals)).normalize();
    let world_p =
        obj * lerp(&m.positions) + DVec3::new(t[0][3] as f64, t[1][3] as f64, t[2][3] as f64);
    let place = 0.8 + 0.2 * (1.7 * world_p.x + 1.1 * world_p.y).sin();
    let lambert = world_n.dot(DVec3::from(LIGHT).normalize()).max(0.0);
    let mat = p.material.map(|k| &l.materials[k]);
    let base = mat.map_or([1.0; 4], |m| m.base_color);
    let emissive = mat.map_or([0.0; 3], |m| m.emissive);
    let textured = if mat.and_then(|m| m.base_color_texture).is_some() { 0.9 } else { 1.0 };
    let mut albedo = [0, 1, 2].map(|k| base[k] as f64);
    if let (Some(tex), Some(i)) = (tex, mat.and_then(|m| m.base_color_image)) {
        let uv = (0..3).fold([0.0; 2], |uv, k| {
            let t = m.uvs[tri[k] as usize];
            [uv[0] + t[0] as f64 * w[k], uv[1] + t[1] as f64 * w[k]]
        });
        let (texel, edge) = sample(&tex[i], uv);
        (0..3).for_each(|k| albedo[k] *= texel[k]);
        (px.edge, px.textured) = (edge, true);
    }
    let c = [0, 1, 2].map(|k| {
        albedo[k] * (AMBIENT + (1.0 - AMBIENT) * lambert) * place * textured + emissive[k] as f64
    });
    px.color = Some((c, h.instance));
    px
}

/// How the device's image compares with the CPU's: pixels within 2/255 per channel (a miss
/// where the CPU misses counts as within), pixels outside, ambiguous pixels left out.
#[derive(Debug, Default)]
struct Counts {
    within: u32,
    outside: u32,
    ambiguous: u32,
    /// Pixels left out because their texture coordinate lies on a texel edge.
    texel_edge: u32,
    /// Of the judged hits, those that sampled a texture.
    textured: u32,
    hits: u32,
    /// Of the CPU's hits, those the device's colour is within.
    hits_within: u32,
    /// Per custom index (global primitive index), the CPU's unambiguous hits on it.
    per_primitive: Vec<u32>,
}

/// The device's image in `report` against the CPU's (`textured`: shaded as `-D TEXTURED` does).
fn compare(scene: &Path, report: &Value, textured: bool) -> Counts {
    let l = Loaded::load(scene).unwrap();
    let tex: Option<Vec<Texture>> =
        textured.then(|| (0..l.images).map(|i| l.decode_image(i).unwrap()).collect());
    let size = rtprobe::harness::SIZE;
    let s = rtprobe::harness::scene::loaded(&l, size);
    let cull = Culling::of(&s);
    let v = &report["variants"][0];
    assert_eq!(v["outcome"], "pass", "{v}");
    let data = v["data"].as_array().unwrap();
    let out =
        data.iter().find(|d| d["label"].as_str().unwrap().starts_with("storage buffer")).unwrap();
    let bytes = unb64(out["bytes"].as_str().unwrap());
    assert_eq!(bytes.len(), (size * size) as usize * WORDS * 4);
    let word = |k: usize| u32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
    let mut c = Counts { per_primitive: vec![0; primitives(&l).len()], ..Counts::default() };
    for y in 0..size {
        for x in 0..size {
            let at = (y * size + x) as usize * WORDS;
            let px = cpu_pixel(&l, (&s, &cull), tex.as_deref(), x, y);
            if px.ambiguous {
                c.ambiguous += 1;
                continue;
            }
            if px.edge {
                c.texel_edge += 1;
                continue;
            }
            let cpu = px.color;
            c.textured += px.textured as u32;
            let gpu = (word(at) != MISS_MARKER)
                .then(|| [0, 1, 2].map(|k| f32::from_bits(word(at + k)) as f64));
            c.hits += cpu.is_some() as u32;
            if let Some((_, custom)) = cpu {
                c.per_primitive[custom as usize] += 1;
            }
            let same = match (cpu, gpu) {
                (None, None) => true,
                (Some((a, custom)), Some(b)) => {
                    (0..3).all(|k| (a[k] - b[k]).abs() <= 2.0 / 255.0) && word(at + 4) == custom
                }
                (None, Some(_)) | (Some(_), None) => false,
            };
            c.hits_within += (same && cpu.is_some()) as u32;
            if same {
                c.within += 1;
            } else {
                c.outside += 1;
            }
        }
    }
    c
}

/// At least 99.5% of the judged pixels within 2/255, and of the hit pixels among them (a
/// shading error on the scene's few pixels must not hide among the misses).
fn matches(c: &Counts) -> bool {
    let judged = c.within + c.outside;
    judged > 0
        && c.within as f64 >= 0.995 * judged as f64
        && c.hits_within as f64 >= 0.995 * c.hits as f64
}

/// The shader's textured build: the scene description by push constant, the scene's images as
/// the texture array at set 1 binding 2, one attempt.
const TEXTURED: [&str; 8] = [
    "--fill",
    "push.16=scene.scene_desc",
    "--fill",
    "1.2=scene.textures",
    "-D",
    "TEXTURED",
    "--repeat",
    "1",
];

/// `scene_run` under `--validate` with `fill`: its report, the run exiting 0 with every attempt
/// of every variant a pass without a validation message.
fn validated(scene: &Path, fill: &[&str]) -> Value {
    let mut args = vec!["--validate"];
    args.extend_from_slice(fill);
    let (o, r) = scene_run(scene, &args);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    for v in r["variants"].as_array().unwrap() {
        for a in v["attempts"].as_array().unwrap() {
            assert_eq!(a["outcome"], "pass", "{a}");
            assert_eq!(a["validation_messages"], 0, "{a}");
        }
    }
    r
}

/// The shader built with `fill` and `-D twin` must fail the comparison with the CPU's image
/// (`textured`: shaded as `-D TEXTURED` does).
fn twin_fails(scene: &Path, fill: &[&str], twin: &str, textured: bool) {
    let mut wrong = fill.to_vec();
    wrong.extend(["-D", twin]);
    let (o, r) = scene_run(scene, &wrong);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    let c = compare(scene, &r, textured);
    println!("{twin}: {c:?}");
    assert!(!matches(&c), "{twin} must fail the comparison: {c:?}");
}

/// The tutorial-style closest-hit on the test scene under `--validate`: no message, no fault,
/// its image the CPU's within 2/255 on at least 99.5% of the unambiguous pixels, every primitive
/// of the scene hit. The twins: the table's entry 0 whatever the custom index, and positions
/// read without the vertex offset, fail the same comparison.
#[test]
fn a_tutorial_closest_hit_renders_the_scene_as_the_cpu_does() {
    let (_d, scene) = test_scene();
    let fill = ["--fill", "push.16=scene.scene_desc", "--repeat", "1"];
    let r = validated(&scene, &fill);
    assert_eq!(r["cell_options"]["fill"], serde_json::json!(["push.16=scene.scene_desc"]));
    assert!(
        r["cell_options"]["scene"].as_str().is_some_and(|h| h.len() >= 12),
        "{}",
        r["cell_options"]
    );
    assert_eq!(r["options"]["scene"], scene.display().to_string());
    let c = compare(&scene, &r, false);
    println!("tutorial: {c:?}");
    assert!(c.hits > 100, "the scene is in view: {c:?}");
    assert!(matches(&c), "{c:?}");
    // Every primitive is hit, the second primitive of the two-primitive pyramid among them, so
    // a shader reading the wrong primitive's entry shows in the image.
    assert!(c.per_primitive.len() >= 4, "{c:?}");
    assert!(c.per_primitive.iter().all(|n| *n >= 8), "every primitive in view: {c:?}");

    // The scene description and the normals in buffer bindings: the same image.
    let binding = [
        "--fill",
        "1.0=scene.scene_desc",
        "--fill",
        "1.1=scene.normals",
        "--repeat",
        "1",
        "-D",
        "DESC_BINDING",
        "--validate",
    ];
    let (o, r) = scene_run(&scene, &binding);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let a = &r["variants"][0]["attempts"][0];
    assert_eq!(a["validation_messages"], 0, "{a}");
    let c = compare(&scene, &r, false);
    println!("bindings: {c:?}");
    assert!(matches(&c), "{c:?}");

    // An engine's `customIndex + gl_GeometryIndexEXT` reads the same entry: the same image.
    let mut engine = fill.to_vec();
    engine.extend(["-D", "ENGINE_STYLE"]);
    let (o, r) = scene_run(&scene, &engine);
    let r = r.unwrap_or_else(|| panic!("no report: {}{}", stdout(&o), stderr(&o)));
    let c = compare(&scene, &r, false);
    println!("ENGINE_STYLE: {c:?}");
    assert!(matches(&c), "{c:?}");

    // The twins: the custom index ignored (entry 0 for every hit), and positions read without
    // the primitive's vertex offset, each fail the comparison.
    for twin in ["WRONG_PRIM_ZERO", "WRONG_POSITIONS"] {
        twin_fails(&scene, &fill, twin, false);
    }
}

/// `-D TEXTURED`: the base colour texture from `--fill 1.2=scene.textures` under `--validate`:
/// no message, no fault, the image the CPU's sampling of the decoded images within 2/255 on at
/// least 99.5% of the pixels judged (ambiguous and texel-edge pixels left out and counted). The
/// twin: `-D WRONG_TEX` (the next element: the other image, or past the images) fails.
#[test]
fn scene_textures_render_as_the_cpu_samples_them() {
    let (_d, scene) = test_scene();
    let fill = TEXTURED;
    let r = validated(&scene, &fill);
    let want = serde_json::json!(["push.16=scene.scene_desc", "1.2=scene.textures"]);
    assert_eq!(r["cell_options"]["fill"], want);
    let c = compare(&scene, &r, true);
    println!("textured: {c:?}");
    assert!(c.textured > 100, "textured pixels are in view: {c:?}");
    assert!(matches(&c), "{c:?}");
    // The untextured shading is not this image: the texture changed what was compared.
    assert!(!matches(&compare(&scene, &r, false)));

    twin_fails(&scene, &fill, "WRONG_TEX", true);
}

/// `scene.textures` given wrongly: into a buffer binding, into an array smaller than the
/// scene's images, from a scene without images: one line each, exit 2, no report.
#[test]
fn scene_textures_given_wrongly_are_one_line_and_no_report() {
    let (d, scene) = test_scene();
    let tex = ["-D", "TEXTURED", "-D", "DESC_BINDING"];
    let (o, r) = scene_run(&scene, &[&tex[..], &["--fill", "1.0=scene.textures"]].concat());
    assert_one_line_error(&o, 2, "set 1 binding 0 is not an array of sampled images");
    assert!(r.is_none());
    let small = ["--fill", "1.2=scene.textures", "--array-size", "1"];
    let (o, r) = scene_run(&scene, &[&tex[..], &small].concat());
    assert_one_line_error(&o, 2, "give --array-size at least 2");
    assert!(r.is_none());
    // The test scene without its images and textures.
    let mut gltf: Value = serde_json::from_slice(&std::fs::read(&scene).unwrap()).unwrap();
    for k in ["images", "textures", "samplers"] {
        gltf.as_object_mut().unwrap().remove(k);
    }
    for m in gltf["materials"].as_array_mut().unwrap() {
        m["pbrMetallicRoughness"].as_object_mut().unwrap().remove("baseColorTexture");
    }
    let plain = d.path().join("plain.gltf");
    std::fs::write(&plain, serde_json::to_vec(&gltf).unwrap()).unwrap();
    let (o, r) = scene_run(&plain, &[&tex[..], &["--fill", "1.2=scene.textures"]].concat());
    assert_one_line_error(&o, 2, "the scene has no images");
    assert!(r.is_none());
}

/// A scene fill without `--scene`, `scene.textures` into an address, an unknown item, a fill
/// over a scene address, an address past the push block's end, a missing or broken scene file:
/// one line each, no report.
#[test]
fn scene_fills_given_wrongly_are_one_line_and_no_report() {
    let (_d, scene) = test_scene();
    // A scene fill without --scene.
    let shader = user("tutorial.rchit");
    let d = rtprobe::tempdir::tempdir().unwrap();
    let out = d.path().join("r.json").display().to_string();
    let o = run(&["run", "--shader", &shader, "--fill", "push.16=scene.scene_desc", "-o", &out]);
    assert_one_line_error(&o, 2, "needs --scene FILE");
    assert!(!Path::new(&out).exists());
    // scene.textures into a buffer address.
    let (o, r) = scene_run(&scene, &["--fill", "push.16=scene.textures"]);
    assert_one_line_error(&o, 2, "scene.textures goes to a sampled-image");
    assert!(r.is_none());
    // An unknown scene item.
    let (o, r) = scene_run(&scene, &["--fill", "push.16=scene.vertices"]);
    assert_one_line_error(&o, 2, "NAME one of positions");
    assert!(r.is_none());
    // A fill over the scene description's address slot, before any device work.
    let over = ["--fill", "push.16=scene.scene_desc", "--fill", "push.16=zero"];
    let (o, r) = scene_run(&scene, &over);
    assert_one_line_error(&o, 2, "push.16=zero: overlaps --fill push.16=scene.scene_desc");
    assert!(r.is_none());
    // An address too close to the push block's end.
    let (o, r) = scene_run(&scene, &["--fill", "push.20=scene.positions"]);
    assert_one_line_error(&o, 2, "a device address takes 8");
    assert!(r.is_none());
    // A missing scene file: the loader's line, exit 9.
    let gone = d.path().join("gone.gltf");
    let (o, r) = scene_run(&gone, &["--fill", "push.16=scene.scene_desc"]);
    assert_one_line_error(&o, 9, "gone.gltf");
    assert!(r.is_none());
    // A broken one.
    let broken = d.path().join("broken.gltf");
    std::fs::write(&broken, "{\"asset\": ").unwrap();
    let (o, r) = scene_run(&broken, &[]);
    assert_one_line_error(&o, 9, "broken.gltf");
    assert!(r.is_none());
}

/// `--fill 1.2=scene.textures` with a base-colour image that does not decode: one line naming
/// `images[0]` and its uri, exit 9 and no report, before any device work; the same scene without
/// the textures fill decodes no image and passes.
#[test]
fn a_broken_scene_image_is_one_line_only_when_scene_textures_reads_it() {
    let (d, scene) = test_scene();
    std::fs::write(d.path().join("checker.png"), b"garbage, not a PNG").unwrap();
    let textured = TEXTURED;
    let (o, r) = scene_run(&scene, &textured);
    assert_one_line_error(&o, 9, "images[0] (uri \"checker.png\"): does not decode");
    assert!(r.is_none());
    let (o, r) = scene_run(&scene, &["--fill", "push.16=scene.scene_desc", "--repeat", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(r.unwrap()["outcome"], "pass");
}

/// The scene's acceleration-structure build in the child's setup waits under `--setup-timeout`,
/// not a trace's `--timeout`: a scene of 400,000 triangles, whose build on lavapipe 25 took longer
/// than 0.1 s before (the setup failed: "acceleration structure build did not finish within
/// 100ms"), passes with `--timeout 0.1`. The twin: `--setup-timeout 0.01` is a timeout of the
/// setup, reported as such.
#[test]
fn a_large_scene_build_waits_under_the_setup_deadline() {
    let d = rtprobe::tempdir::tempdir().unwrap();
    let dir = d.path().display().to_string();
    let o = run(&["scene", "make", &dir, "--triangles", "400000", "--glb"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let scene = d.path().join("scene.glb");
    let fill = ["--fill", "push.16=scene.scene_desc", "--repeat", "1", "--timeout", "0.1"];
    let (o, r) = scene_run(&scene, &fill);
    let r = r.unwrap_or_else(|| panic!("no report: {}", stderr(&o)));
    assert_eq!(r["variants"][0]["attempts"][0]["outcome"], "pass", "{}", r["variants"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let short: Vec<&str> = fill.iter().copied().chain(["--setup-timeout", "0.01"]).collect();
    let (o, r) = scene_run(&scene, &short);
    assert_ne!(o.status.code(), Some(0), "{}", stderr(&o));
    let attempt = &r.unwrap()["variants"][0]["attempts"][0];
    assert_eq!(attempt["outcome"], "timeout", "{attempt}");
    let detail = attempt["detail"].as_str().unwrap_or_default();
    assert!(
        detail.starts_with("setup: acceleration structure build did not finish within 10ms"),
        "{attempt}"
    );
}
