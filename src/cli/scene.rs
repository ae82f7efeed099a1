//! `rtprobe scene`: `info` loads a glTF scene as `--scene` will and says what rtprobe read
//! (and how long loading took, with the peak memory of the process); `make` writes the test scene
//! or a large one (`scene::gltf::make`).
use super::args::SceneCommand;
use super::exit::{self, coded};
use super::out::outln;
use crate::scene::gltf::{make, Alpha, Loaded};
use anyhow::Result;
use std::time::Instant;

/// The largest scene `scene make --triangles` writes (about 0.9 GB of buffers).
const MAX_TRIANGLES: u64 = 32_000_000;

pub fn scene(c: &SceneCommand) -> Result<u8> {
    match c {
        SceneCommand::Info { file } => info(file),
        SceneCommand::Make { dir, triangles, glb } => {
            if let Some(t) = triangles.filter(|t| !(1..=MAX_TRIANGLES).contains(t)) {
                return Err(coded(exit::USAGE, format!("--triangles {t}: give 1 to {MAX_TRIANGLES} (leave it out for the test scene)")));
            }
            if dir.exists() && !dir.is_dir() {
                return Err(coded(
                    exit::USAGE,
                    format!(
                        "{}: is not a folder; give the folder to write the scene into",
                        dir.display()
                    ),
                ));
            }
            let path = make::make(
                dir,
                make::MakeOptions { triangles: triangles.unwrap_or(0), glb: *glb },
            )?;
            outln!("wrote {}", path.display());
            Ok(0)
        }
    }
}

fn info(file: &std::path::Path) -> Result<u8> {
    let t = Instant::now();
    let s = Loaded::load(file)?;
    let load = t.elapsed();
    outln!("scene {}", file.display());
    outln!(
        "  {} meshes, {} instances, {} triangles traced ({} stored), {} materials, {} images",
        s.meshes.len(),
        s.instances.len(),
        s.triangles(),
        s.meshes.iter().map(|m| m.indices.len()).sum::<usize>(),
        s.materials.len(),
        s.images
    );
    for m in &s.meshes {
        if m.unused {
            outln!("  {}: no node uses it (not read)", m.name);
            continue;
        }
        let tris: Vec<String> = m.primitives.iter().map(|p| p.triangles.to_string()).collect();
        outln!(
            "  {}: {} vertices, primitives of {} triangles",
            m.name,
            m.positions.len(),
            tris.join(", ")
        );
    }
    for m in &s.materials {
        let alpha = match m.alpha {
            Alpha::Opaque => "opaque".to_string(),
            Alpha::Mask(c) => format!("MASK below {c} (non-opaque geometry)"),
            Alpha::Blend => "BLEND (non-opaque geometry)".to_string(),
        };
        let tex =
            m.base_color_image.map_or("no texture".into(), |i| format!("base colour image {i}"));
        outln!("  material {}: {alpha}, {tex}", m.name);
    }
    match &s.camera {
        Some(c) => outln!(
            "  camera at node {} (its orientation is the view; rtprobe's rays are orthographic)",
            c.node
        ),
        None => outln!("  no camera: the view is fitted to the bounds from the front"),
    }
    outln!(
        "  geometry {} bytes; loaded in {:.1} ms; peak memory {} MiB",
        s.geometry_bytes(),
        load.as_secs_f64() * 1e3,
        peak_mib()
    );
    Ok(0)
}

/// The process's peak resident memory (`VmHWM`), MiB; 0 where /proc does not say.
fn peak_mib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find_map(|l| {
                l.strip_prefix("VmHWM:")
                    .and_then(|v| v.trim().trim_end_matches(" kB").trim().parse::<u64>().ok())
            })
        })
        .map_or(0, |kb| kb / 1024)
}
