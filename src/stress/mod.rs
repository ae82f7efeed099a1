//! `rtprobe stress`: numerical stability of the driver's ray/triangle traversal against the f64
//! watertight reference (`reference::watertight`). Each case (`cases`) builds small scenes and
//! rays; a [`Tracer`] (the real RT pipeline in `gpu`, or a CPU intersector in `cpu` for tests)
//! returns, per ray, the committed hit and the number of candidate hits any-hit saw; `evaluate`
//! turns them into leaks, double hits, disagreements and t / barycentric / built-in errors
//! against tolerances and ambiguity margins measured in ray space (`margin`) (`transform` adds facing and culling, `selfhit` builds the `self` case
//! from the device's own hits); `report` prints the tables and writes the JSON and the SVG of `far`.
pub mod cases;
pub mod cpu;
pub mod evaluate;
pub mod gpu;
pub mod index;
pub mod layout;
pub mod margin;
pub mod mesh;
pub mod report;
pub mod result;
pub mod selfhit;
pub mod svg;
pub mod transform;
mod types;

pub(crate) use types::one_mesh;
pub use types::{
    CaseKind, Instance, Mesh, Part, Ray, RayInfo, Scene, StressOptions, TraceError, Traced,
    TracedHit, Tracer, IDENTITY,
};

/// Run `opts.cases` on `tracer`: every case is built, traced and evaluated; a case whose trace
/// fails is reported with that failure, and the rest still run.
pub fn run(tracer: &mut dyn Tracer, opts: &StressOptions) -> Vec<evaluate::CaseResult> {
    opts.cases
        .iter()
        .map(|&kind| {
            let start = std::time::Instant::now();
            let parts = cases::build(kind, opts);
            let mut r = match parts {
                None if kind == CaseKind::SelfHit => match selfhit::run(tracer, opts) {
                    Ok((parts, traced)) => evaluate::evaluate(kind, &parts, &traced),
                    Err((parts, e)) => evaluate::CaseResult::failed(kind, &parts, &e),
                },
                None => evaluate::CaseResult::not_implemented(kind),
                Some(parts) => {
                    let mut traced = Vec::new();
                    let mut failure = None;
                    for p in &parts {
                        match tracer.trace(p) {
                            Ok(t) => traced.push(t),
                            Err(e) => {
                                failure = Some(e);
                                break;
                            }
                        }
                    }
                    match failure {
                        None => evaluate::evaluate(kind, &parts, &traced),
                        Some(e) => evaluate::CaseResult::failed(kind, &parts, &e),
                    }
                }
            };
            r.ms = start.elapsed().as_secs_f64() * 1e3;
            r
        })
        .collect()
}
