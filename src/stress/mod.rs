//! `rtprobe stress`: numerical stability of the driver's ray/triangle traversal against the f64
//! watertight reference (`reference::watertight`). Each case (`cases`) builds small scenes and
//! rays; a [`Tracer`] (the real RT pipeline in `gpu`, or a CPU intersector in `cpu` for tests)
//! returns, per ray, the committed hit and the number of candidate hits any-hit saw; `evaluate`
//! turns them into leaks, double hits, disagreements and t / barycentric / built-in errors
//! against tolerances and ambiguity margins measured in ray space (`margin`) (`transform` adds facing and culling, `selfhit` builds the `self` case
//! from the device's own hits); `report` prints the tables and writes the JSON and the SVG of `far`.
//! `rtprobe stress` runs each case in a worker process of its own (`worker`, started and watched
//! by `supervised` through `runner::process`), so a driver crash or hang is that case's outcome.
pub mod cases;
pub mod cpu;
pub mod evaluate;
pub mod examples;
pub mod far;
pub mod gpu;
pub mod index;
pub mod layout;
pub mod margin;
pub mod mesh;
pub mod report;
pub mod result;
pub mod selfhit;
pub mod supervised;
pub mod svg;
pub mod transform;
mod types;
pub mod worker;

pub(crate) use types::one_mesh;
pub use types::{
    CaseKind, Instance, Mesh, Part, Ray, RayInfo, Scene, StressOptions, TraceError, Traced,
    TracedHit, Tracer, Work, IDENTITY,
};

/// What tracing one case gave: its parts with what the tracer returned for each, the parts and
/// the failure that stopped it, or nothing (rtprobe does not implement the case).
pub enum CaseTrace {
    Traced(Vec<Part>, Vec<Vec<Traced>>),
    Failed(Vec<Part>, TraceError),
    NotImplemented,
}

/// Build and trace every part of `kind` (the device work of a case; `self` builds its secondary
/// rays from its primary hits).
pub fn trace_case(tracer: &mut dyn Tracer, kind: CaseKind, opts: &StressOptions) -> CaseTrace {
    let parts = match cases::build(kind, opts) {
        None if kind == CaseKind::SelfHit => {
            return match selfhit::run(tracer, opts) {
                Ok((parts, traced)) => CaseTrace::Traced(parts, traced),
                Err((parts, e)) => CaseTrace::Failed(parts, e),
            }
        }
        None => return CaseTrace::NotImplemented,
        Some(parts) => parts,
    };
    let mut traced = Vec::new();
    for p in &parts {
        match tracer.trace(p) {
            Ok(t) => traced.push(t),
            Err(e) => return CaseTrace::Failed(parts, e),
        }
    }
    CaseTrace::Traced(parts, traced)
}

/// Judge a traced case against the reference (the CPU work of a case).
pub fn judge(kind: CaseKind, trace: &CaseTrace) -> evaluate::CaseResult {
    judge_counting(kind, trace, &|_| {})
}

/// [`judge`], calling `on_work` after each unit of work — a triangle placed in the reference's
/// grid, a ray judged, a ray's facing found (a worker's heartbeat counts them).
pub fn judge_counting(
    kind: CaseKind,
    trace: &CaseTrace,
    on_work: &dyn Fn(Work),
) -> evaluate::CaseResult {
    match trace {
        CaseTrace::Traced(parts, traced) => {
            evaluate::evaluate_counting(kind, parts, traced, on_work)
        }
        CaseTrace::Failed(parts, e) => evaluate::CaseResult::failed(kind, parts, e),
        CaseTrace::NotImplemented => evaluate::CaseResult::not_implemented(kind),
    }
}

/// Run `opts.cases` on `tracer` in this process: every case is built, traced and evaluated; a
/// case whose trace fails is reported with that failure, and the rest still run.
/// (`rtprobe stress` runs each case in a worker process instead: `supervised`.)
pub fn run(tracer: &mut dyn Tracer, opts: &StressOptions) -> Vec<evaluate::CaseResult> {
    opts.cases
        .iter()
        .map(|&kind| {
            let start = std::time::Instant::now();
            let mut r = judge(kind, &trace_case(tracer, kind, opts));
            r.ms = start.elapsed().as_secs_f64() * 1e3;
            r
        })
        .collect()
}
