//! Mismatch pictures (`run --dump DIR`): a mismatching cell leaves expected / actual / diff PNGs
//! whose pixels agree with the report's counts; a passing cell leaves none.
//!
//! The mismatch is injected (`--inject-fault 'stage=closest_hit@value:0.1'`: a wrong value on
//! about 10% of the probed pixels, nothing else).
mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

const CELL: &str = "closest_hit.storage_buffer.literal.descriptor_indexing";

fn decode(p: &Path) -> (usize, usize, Vec<[u8; 3]>) {
    let d = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())),
    ));
    let mut r = d.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width as usize, info.height as usize, buf.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
}

fn run_cell(extra: &[&str], dir: &Path) -> (std::process::Output, Value) {
    let out = dir.join("r.json");
    let dump = dir.join("dump");
    let mut args = vec!["run", "--no-confirm", "--patches", "none", "--filter", "stage=closest_hit,resource=storage_buffer,index=literal,descriptor_model=descriptor_indexing",
        "--dump", dump.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = run(&args);
    let r: Value = serde_json::from_slice(&std::fs::read(&out).expect("report written")).unwrap();
    (o, r)
}

#[test]
fn a_mismatch_leaves_pictures_that_agree_with_the_report() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (o, r) = run_cell(&["--inject-fault", "stage=closest_hit@value:0.1"], dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let c =
        r["cells"].as_array().unwrap().iter().find(|c| c["id"] == CELL).expect("cell in report");
    assert_eq!(c["outcome"], "mismatch");
    let cmp = &c["attempts"][0]["result"]["comparison"];
    let pics: Vec<&str> = cmp["pictures"]
        .as_array()
        .expect("pictures listed in the report")
        .iter()
        .map(|p| p.as_str().unwrap())
        .collect();
    assert_eq!(pics.len(), 3, "{pics:?}");
    assert!(
        pics[0].ends_with(&format!("{CELL}/expected.png"))
            && pics[1].ends_with("actual.png")
            && pics[2].ends_with("diff.png"),
        "{pics:?}"
    );
    // The terminal summary points to the diff.
    assert!(stdout(&o).contains(&format!("pictures: {}", pics[2])), "{}", stdout(&o));

    let (w, h, diff) = decode(Path::new(pics[2]));
    assert_eq!(w * h, cmp["pixels"].as_u64().unwrap() as usize);
    let count = |rgb: [u8; 3]| diff.iter().filter(|p| **p == rgb).count();
    let (red, grey, green) = (count([255, 0, 0]), count([128, 128, 128]), count([0, 72, 0]));
    assert_eq!(red, cmp["mismatched_pixels"].as_u64().unwrap() as usize);
    assert_eq!(grey, cmp["ambiguous"].as_u64().unwrap() as usize);
    assert_eq!(red + green, cmp["compared"].as_u64().unwrap() as usize);
    assert!(red > 0);

    // Four panels (hit, instance, primitive, value); the value panels differ exactly where the
    // report counts a value mismatch, and the hit/instance/primitive panels agree on every
    // compared pixel (only values were made wrong).
    let (ew, eh, exp) = decode(Path::new(pics[0]));
    let (aw, _, act) = decode(Path::new(pics[1]));
    assert_eq!((ew, eh, aw), (4 * w, h, 4 * w));
    let at = |img: &Vec<[u8; 3]>, panel: usize, i: usize| img[(i / w) * 4 * w + panel * w + i % w];
    let mut value_differs = 0;
    for (i, d) in diff.iter().enumerate().take(w * h) {
        if *d == [128, 128, 128] {
            continue;
        }
        for panel in 0..3 {
            assert_eq!(at(&exp, panel, i), at(&act, panel, i), "panel {panel} pixel {i}");
        }
        let differs = at(&exp, 3, i) != at(&act, 3, i);
        assert_eq!(differs, diff[i] == [255, 0, 0], "pixel {i}: value panel vs diff");
        value_differs += differs as usize;
    }
    assert_eq!(value_differs, cmp["by_field"]["value"].as_u64().unwrap() as usize);
}

#[test]
fn a_passing_cell_leaves_no_pictures() {
    let dir = rtprobe::tempdir::tempdir().unwrap();
    let (o, r) = run_cell(&[], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}\n{:#}", stderr(&o), r["cells"][0]);
    let c = &r["cells"][0];
    assert_eq!(c["outcome"], "pass");
    assert!(c["attempts"][0]["result"]["comparison"].get("pictures").is_none());
    assert!(!dir.path().join("dump").join(CELL).join("diff.png").exists());
    assert!(dir.path().join("dump").join(CELL).join("closest_hit_triangles.rchit.glsl").exists());
}
