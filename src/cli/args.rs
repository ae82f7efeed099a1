//! The clap definitions: every subcommand and flag, with doc comments as `--help` text.
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "rtprobe",
    version,
    about = "Find and pin down GPU driver faults in Vulkan ray tracing",
    long_about = "rtprobe runs generated shader variants in full ray tracing scenes, checks every result \
against a CPU reference, isolates device losses, crashes and hangs, and tells you which shader shape \
your driver faults on.",
    after_help = super::exit::HELP
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,

    /// Enable VK_LAYER_KHRONOS_validation when installed (also RTPROBE_VALIDATE=1);
    /// `--validate=gpu-av` (RTPROBE_VALIDATE=gpu-av): also re-run each finding of `run` under
    /// GPU-Assisted Validation, and say whether GPU-AV masks it
    #[arg(long, global = true, env = "RTPROBE_VALIDATE", num_args = 0..=1, require_equals = true, default_missing_value = "core", value_parser = parse_validate)]
    pub validate: Option<ValidateMode>,

    /// More log output on stderr (-v info, -vv debug); RUST_LOG overrides
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

/// `--validate[=MODE]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValidateMode {
    Off,
    /// The validation layer on.
    Core,
    /// The layer on, and every finding of `run` re-run under GPU-Assisted Validation.
    GpuAv,
}

fn parse_validate(s: &str) -> Result<ValidateMode, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "" | "0" | "false" | "no" | "off" => Ok(ValidateMode::Off),
        "1" | "true" | "yes" | "on" | "core" => Ok(ValidateMode::Core),
        "gpu-av" | "gpuav" => Ok(ValidateMode::GpuAv),
        other => Err(format!("{other:?} is not a validation mode (core, gpu-av, or a boolean)")),
    }
}

// One value per process, parsed once: the size of `run`'s arguments costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand, Debug)]
pub enum Command {
    /// List the Vulkan physical devices, one line each, and whether they can run RT pipelines
    Devices(DevicesArgs),
    /// Show what a device can do for ray tracing, and which matrix axis values it can run
    Caps(CapsArgs),
    /// Run the matrix of generated shader variants in full RT scenes, each checked against a CPU
    /// reference, each fault isolated; writes a JSON report
    Run(RunArgs),
    /// Apply SPIR-V workaround patches to a shader (SPIR-V binary, or GLSL with --glsl)
    Patch(PatchArgs),
    /// Narrow a run's faults down to the minimal conjunction of axis values (ddmin over the
    /// report's cells, running only what it needs), with an isolation list and verified workarounds
    Bisect(BisectArgs),
    /// Write the vendor issue for a run's fault (Markdown or JSON), from the report and a bisection
    Report(ReportArgs),
    /// Write a repro bundle for one cell: shaders (GLSL, SPIR-V, disassembly), cell.json, caps
    Repro(ReproArgs),
    /// Write the expectations (baseline) of a finished run, for `run --baseline`
    Baseline(BaselineArgs),
    /// Join the reports of shards (`run --shard I/N`) or re-runs into one report
    Merge(MergeArgs),
    /// What changed between two run reports: per cell (fixed, regressed, new, gone) and time per
    /// phase; text or Markdown (exit 1 when an outcome changed)
    Diff(DiffArgs),
    /// Numerical stability of the driver's ray/triangle traversal against an f64 watertight
    /// reference: leaks, double hits, t and barycentric error per case (exit 1 when a case fails)
    Stress(StressArgs),
    /// Run time against error, measured by running rtprobe itself: matrix time and detection of
    /// wrong values against image size, detection of flaky faults against repeats, time per phase
    /// per run configuration; writes DIR/bench.json (rtprobe.bench/1) and SVG plots
    Bench(BenchArgs),
    /// glTF scenes: what rtprobe reads from one (`info`), or write the test scene or a large one
    /// for measurements (`make`)
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Shrink a faulting user shader of a `run --shader` report with spirv-reduce (rtprobe is its
    /// interestingness test: same fault, valid, every descriptor index in bounds) and name the
    /// remaining access's shape as a `--filter` predicate; writes DIR/reduced.spv, .spvasm,
    /// access.txt and reduce.json (rtprobe.reduce/1)
    Reduce(ReduceArgs),
    /// Internal: spirv-reduce's interestingness test for `rtprobe reduce`; not for direct use
    #[command(name = "__interesting", hide = true)]
    Interesting {
        /// The job file written by `rtprobe reduce`
        job: PathBuf,
        /// The candidate module spirv-reduce appends
        candidate: PathBuf,
    },
    /// Internal: run cells for the supervisor (`rtprobe run`); not for direct use
    #[command(name = "__worker", hide = true)]
    Worker {
        /// The job file written by the supervisor
        job: PathBuf,
    },
    /// Internal: run one stress case for `rtprobe stress`; not for direct use
    #[command(name = "__stress", hide = true)]
    StressWorker {
        /// The job file written by `rtprobe stress`
        job: PathBuf,
    },
    /// Internal: run `run --shader`'s attempts of one variant; not for direct use
    #[command(name = "__shader", hide = true)]
    ShaderWorker {
        /// The job file written by `rtprobe run --shader`
        job: PathBuf,
    },
    /// Internal: run `patch --verify`'s pipelines for `rtprobe patch`; not for direct use
    #[command(name = "__verify", hide = true)]
    VerifyWorker {
        /// The job file written by `rtprobe patch`
        job: PathBuf,
    },
}

#[derive(Args, Debug, Clone)]
pub struct ReduceArgs {
    /// A `run --shader` report (rtprobe.shader-run/1) with a fault
    pub report: PathBuf,

    /// The report's cell id (optional: a `run --shader` report has one cell)
    #[arg(long, value_name = "ID")]
    pub cell: Option<String>,

    /// Output folder (refused when not empty, unless --force)
    #[arg(long, short = 'o', value_name = "DIR")]
    pub out: PathBuf,

    /// Write into a non-empty output folder
    #[arg(long)]
    pub force: bool,

    /// Device index or case-insensitive name substring (default: the first RT-capable device)
    #[arg(long, short = 'd', value_name = "INDEX|NAME")]
    pub device: Option<String>,

    /// spirv-reduce's --step-limit: the most reduction steps it tries
    #[arg(long, default_value_t = 2500, value_name = "N")]
    pub step_limit: u32,

    /// The most matrix cells of the predicate's slice to run (a shard when it generates more;
    /// 0: no slice)
    #[arg(long, default_value_t = 16, value_name = "N")]
    pub slice_cells: u32,
}

#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// Device index or case-insensitive name substring (default: the first RT-capable device)
    #[arg(long, short = 'd', value_name = "INDEX|NAME")]
    pub device: Option<String>,

    #[arg(long, value_name = "FILTER", help = crate::model::registry::filter_help_short(), long_help = crate::model::registry::filter_help())]
    pub filter: Vec<String>,

    /// Print the planned cells (unsupported ones with the reason) and the rules that kept
    /// combinations out; run nothing
    #[arg(long)]
    pub list: bool,

    /// Report file (default: reports/run-<timestamp>-<device>.json, never one that exists or
    /// that another run is writing)
    #[arg(long, short = 'o', visible_alias = "output", value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// Continue an interrupted run from its report (finished cells are kept, not re-run). The
    /// device, scene, filters, injections and options are the report's; one given here that
    /// differs from the report's is refused
    #[arg(long, value_name = "REPORT")]
    pub resume: Option<PathBuf>,

    /// Also write deqp-runner's files into DIR: results.csv (`test,Status,duration` for every
    /// planned cell), failures.csv (the lines CI looks at: Fail, Crash, Timeout, Flake,
    /// UnexpectedPass), junit.xml, and the report (DIR/report.json unless -o says otherwise)
    #[arg(long, value_name = "DIR")]
    pub output_dir: Option<PathBuf>,

    /// Known flakes, deqp-runner's form: a regular expression per line (`#` comments) matched
    /// against cell ids; a matching cell that faults is a known flake, not a failure
    #[arg(long, value_name = "FILE")]
    pub flakes: Option<PathBuf>,

    /// Cells not to run, deqp-runner's form: a regular expression per line (`#` comments)
    /// matched against cell ids; they are left out of the plan as a filter would
    #[arg(long, value_name = "FILE")]
    pub skips: Option<PathBuf>,

    /// Also write JUnit XML (findings as failures, unsupported cells as skipped)
    #[arg(long, value_name = "FILE")]
    pub junit: Option<PathBuf>,

    /// With --shader: compare each variant's outputs with another `run --shader` report of the
    /// same cell (another device or driver); differences are notes unless --tolerance is given
    #[arg(long, value_name = "REPORT")]
    pub compare: Option<PathBuf>,

    /// With --compare: outputs whose 32-bit float words differ by more than T (absolute; a
    /// NaN or an infinity never passes), or whose other words differ at all, are a `mismatch`
    #[arg(long, value_name = "T", requires = "compare")]
    pub tolerance: Option<f32>,

    /// Write each cell's generated GLSL and SPIR-V and the records it read back (records.bin)
    /// under DIR/<cell id>/, and for a cell whose records mismatch, pictures of them there:
    /// expected.png, actual.png, diff.png
    #[arg(long, value_name = "DIR")]
    pub dump: Option<PathBuf>,

    /// Worker processes running cells in parallel (default: one per CPU core, at most 8, on CPU
    /// devices such as lavapipe, whose pipeline compiles are single-threaded; 1 on GPUs, where
    /// each worker pays for a device and they contend: use --threads there)
    #[arg(long, short = 'j')]
    pub jobs: Option<usize>,

    /// Threads each worker creates pipelines on, ahead of the cells' turns (1..=64; traces still
    /// run one cell at a time). Default: the available cores, at most 16, on GPUs (pipeline
    /// creation is most of a cell's time there); 1 on CPU devices such as lavapipe, whose
    /// workers already use the cores (and which compile at the first trace). 1 builds each cell
    /// at its turn. If a worker dies or hangs while building a batch, the batch runs again with
    /// each cell building at its turn, so a fault is still exactly one cell's verdict. With
    /// --validate (any mode) always 1, so that each validation error is counted for its own cell
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,

    /// Where the VkPipelineCache is kept between runs, one file per device and driver version
    /// (default: $RTPROBE_CACHE_DIR, else $XDG_CACHE_HOME/rtprobe, else ~/.cache/rtprobe), or
    /// `off`. A file of another device or driver, or a corrupt one, is ignored with a warning.
    /// Re-runs of a cell alone (--confirm, --repeat, the repeats of workaround and pattern cells,
    /// --validate=gpu-av, bisect, --cell-spec) never load it: they start cold, so that a cached
    /// binary cannot stand in for a compile. (A workaround or pattern cell's first run goes with
    /// the run's workers and loads it.)
    #[arg(long, value_name = "DIR|off")]
    pub pipeline_cache: Option<String>,

    /// `worker`: a worker runs many cells and is replaced after a fault;
    /// `process-per-cell`: every cell in a fresh process
    #[arg(long, value_enum, default_value = "worker")]
    pub isolation: crate::model::Isolation,

    /// Deadline for one cell, in seconds (a cell past it is a `timeout`)
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS")]
    pub timeout: f64,

    /// Deadline for a worker's setup (instance, device, scene acceleration structures,
    /// resources), in seconds; a failed setup is retried once in a fresh worker
    #[arg(long, default_value_t = 120.0, value_name = "SECONDS")]
    pub setup_timeout: f64,

    /// Do not re-run faulting cells alone in a fresh worker
    #[arg(long)]
    pub no_confirm: bool,

    /// Add canary cells (invalid address read, endless loop) that prove crash, device-loss and
    /// timeout detection on this driver
    #[arg(long)]
    pub canaries: bool,

    /// The `patch` axis: `faults` retries every faulting cell with each SPIR-V workaround that
    /// applies (the report names the verified ones); `all` plans every cell with each; `none`
    #[arg(long, value_enum, default_value = "faults")]
    pub patches: crate::model::PatchMode,

    /// Where the probe records its subgroup lane evidence (docs/lane-evidence.md): `auto` where
    /// the device lists ballot in the probed stage; `force` everywhere (a diagnosis only: outside
    /// the spec where the device does not list the stage); `off` never
    #[arg(long, value_enum, default_value = "auto")]
    pub lane_evidence: crate::model::LaneMode,

    /// Scene seed
    #[arg(long, default_value_t = 1)]
    pub seed: u64,

    /// Image size WIDTHxHEIGHT (one primary ray per pixel; multiples of 8)
    #[arg(long, default_value = "64x64", value_name = "WxH")]
    pub size: String,

    /// TLAS instances (at least 16)
    #[arg(long, default_value_t = 16)]
    pub instances: u32,

    /// Quads per side of the largest mesh (meshes have detail/4, detail/2, detail)
    #[arg(long, default_value_t = 16)]
    pub mesh_detail: u32,

    /// Make cells misbehave on purpose: `PREDICATE[@KIND]`, PREDICATE in --filter syntax; KIND
    /// device (default: a load through an invalid address), hang, value[:FRACTION[:SEED]] (SEED: each
    /// cell draws its own pixels), nan, flaky:P.
    /// Repeatable; RTPROBE_INJECT_FAULT takes a `;`-separated list. Proves detection on your driver.
    #[arg(
        long = "inject-fault",
        value_name = "PREDICATE[@KIND]",
        env = "RTPROBE_INJECT_FAULT",
        value_delimiter = ';'
    )]
    pub inject_fault: Vec<String>,

    /// Hold the run to these expectations (from `rtprobe baseline`, or deqp-runner `test,Status`
    /// lines): exit 1 only on regressions, on improvements (unless --allow-improvements) and on
    /// phases slower than the baseline's bounds
    #[arg(long, value_name = "FILE")]
    pub baseline: Option<PathBuf>,

    /// With --baseline: cells better than expected are reported but do not fail the run
    #[arg(long)]
    pub allow_improvements: bool,

    /// Run only shard I of N (1-based): a deterministic, balanced split of the planned cells by
    /// cell id, for a CI system's parallel jobs; join the reports with `rtprobe merge`
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,

    /// How ray tracing pipelines are made: `linked` from one pipeline library per shader group
    /// (VK_KHR_pipeline_library), each library made once and shared by the cells whose group is
    /// the same, or `whole` from all their stages; `auto` links on GPUs (faster there) and not on
    /// CPU devices (lavapipe compiles each pipeline at its first trace, and lavapipe 25's linked
    /// pipelines give wrong results). See docs/performance.md
    #[arg(long, value_enum, default_value = "auto", value_name = "MODE")]
    pub pipelines: crate::model::PipelineMode,

    /// Run exactly N probe cells, each with a pipeline of its own: the first N of the plan, or
    /// all of them and then copies (`<id>.copy-k`: the same probe with a constant of its own in
    /// the first stage, so new shaders and a new pipeline, the same records). For measuring time
    /// against the number of cells (`rtprobe bench --cells`)
    #[arg(long, value_name = "N")]
    pub cells_scale: Option<usize>,

    /// Run each faulting cell until it has N attempts (each alone in a fresh worker) and report
    /// k of N with the chance that a fault of the observed rate would have been missed
    #[arg(long, value_name = "N")]
    pub repeat: Option<u32>,

    /// Prove that every emulated driver bug is caught: after the matrix, run each cell that
    /// passed again with each mutant — a SPIR-V mutation of its probed stage that reads another
    /// descriptor, element, sampler or TLAS (always in bounds), or flips a result word's bits —
    /// where the CPU reference, run with the same mutation, predicts other records, and report
    /// the kill matrix (docs/mutants.md). Mutant attempts never change a cell's verdict
    #[arg(long)]
    pub mutants: bool,

    /// Only these mutants (comma-separated, repeatable; implies --mutants): index-zero,
    /// index-next, index-broadcast, base-dropped, element-zero, stride-double, sampler-next,
    /// tlas-other, value-bits
    #[arg(long, value_name = "NAME", value_delimiter = ',')]
    pub mutant: Vec<String>,

    /// Run only a seeded sample of N applicable (cell, mutant) pairs (implies --mutants; CI's
    /// share of the kill matrix; SEED defaults to 1)
    #[arg(long, value_name = "N[:SEED]")]
    pub mutants_sample: Option<String>,

    /// Run exactly the cell described by a repro bundle's cell.json (`rtprobe repro`): it
    /// replaces the plan, the scene and the injections
    #[arg(long, value_name = "FILE", conflicts_with_all = ["filter", "inject_fault", "resume", "canaries"])]
    pub cell_spec: Option<PathBuf>,

    /// Run your own ray tracing shaders instead of the generated matrix, one file per stage of
    /// the pipeline (repeatable): SPIR-V, or GLSL whose stage its name says (.rgen, .rchit,
    /// .rahit, .rmiss, .rint, .rcall; also NAME.rchit.glsl). Each variant — unpatched, and each
    /// workaround patch that applies — is traced --repeat times (default 3) in a child process;
    /// faults, validation messages and outputs that differ are findings. See
    /// docs/your-shader.md
    #[arg(long, value_name = "FILE", help_heading = "Your shaders")]
    pub shader: Vec<PathBuf>,

    /// With --shader: the entry point to run, in modules that have several
    #[arg(long, value_name = "NAME", requires = "shader", help_heading = "Your shaders")]
    pub entry: Option<String>,

    /// With --shader: put hit shaders in ray type K's hit groups (K = the SBT record offset its
    /// rays trace with; repeatable), where their payload does not say it (two ray types with one
    /// payload structure, an any-hit without a payload). See docs/your-shader.md#ray-types
    #[arg(
        long = "hit-group",
        value_name = "K=FILE[,FILE…]",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub hit_groups: Vec<String>,

    /// With --shader: a folder `#include "…"` searches (repeatable), as glslang's -I
    #[arg(
        short = 'I',
        long = "include-dir",
        value_name = "DIR",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub include_dirs: Vec<PathBuf>,

    /// With --shader: a preprocessor macro for GLSL inputs (repeatable), as glslang's -D
    #[arg(
        short = 'D',
        long = "define",
        value_name = "NAME[=VALUE]",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub defines: Vec<String>,

    /// With --shader: the Vulkan environment GLSL inputs are compiled for (default vulkan1.2)
    #[arg(
        long,
        value_enum,
        value_name = "ENV",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub target_env: Option<crate::shadergen::compile::TargetEnv>,

    /// With --shader: a specialization constant's value, ID=VALUE (repeatable), given to every
    /// stage declaring SpecId ID; VALUE is read as the constant's type (bool, int, uint, float)
    #[arg(
        long = "spec",
        value_name = "ID=VALUE",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub spec: Vec<String>,

    /// With --shader: how descriptors are bound. Default: descriptor_heap for modules that
    /// read a descriptor heap (VK_EXT_descriptor_heap), descriptor_indexing for the others
    #[arg(
        long,
        value_enum,
        value_name = "MODEL",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub descriptor_model: Option<crate::model::DescriptorModel>,

    /// With --shader: the engine's device features as a Vulkan Profiles JSON (what `caps
    /// --profile` writes): robustness enabled and descriptor binding flags as the engine's
    /// (docs/your-shader.md)
    #[arg(long, value_name = "FILE", requires = "shader", help_heading = "Your shaders")]
    pub profile: Option<PathBuf>,
    /// With --shader: the descriptor heap's ranges as a JSON file, for heap modules whose layout
    /// the modules alone do not determine (docs/your-shader.md)
    #[arg(long, value_name = "FILE", requires = "shader", help_heading = "Your shaders")]
    pub heap_layout: Option<PathBuf>,
    /// With --shader: data in place of the harness's, TARGET=SOURCE (repeatable): TARGET is
    /// SET.BINDING (a buffer, every element), SET.BINDING[ELEM], push.OFFSET or record.OFFSET
    /// (bytes); SOURCE is zero, random:SEED, a file's bytes or, with --scene, scene.NAME:
    /// positions, indices, normals, uvs, materials, prim_info, scene_desc, or textures (the
    /// scene's images into a texture array binding) (docs/your-shader.md)
    #[arg(
        long = "fill",
        value_name = "TARGET=SOURCE",
        requires = "shader",
        help_heading = "Your shaders"
    )]
    pub fill: Vec<String>,

    /// Trace this glTF 2.0 scene (.gltf or .glb) instead of the seeded procedural one: the
    /// generated cells on its meshes and instances (custom index = mesh index; docs/scenes.md),
    /// or with --shader the harness's, `--fill TARGET=scene.NAME` putting its data in buffers,
    /// push constants, records or (scene.textures) a texture array (docs/your-shader.md)
    #[arg(long, value_name = "FILE", help_heading = "Your shaders")]
    pub scene: Option<PathBuf>,

    /// With --shader: the elements of every runtime-sized descriptor array (`textures[]`,
    /// `buffer B {…} b[]`), 1 to 65536 (default: one per index the harness scene produces, 64)
    #[arg(long, value_name = "N", requires = "shader", help_heading = "Your shaders")]
    pub array_size: Option<u64>,

    /// With --shader: skip the descriptor-index check that runs first (each array's largest
    /// index on the run's data; runtime arrays sized up where the harness's own data goes past
    /// them). An index past its binding then runs as given: undefined, the shader's fault
    #[arg(long, requires = "shader", help_heading = "Your shaders")]
    pub no_index_check: bool,

    /// With --shader: the bytes of the zero-filled sink buffer every 64-bit integer and
    /// buffer_reference pointer points at, 16 to 1073741824 (default 4 MiB)
    #[arg(long, value_name = "BYTES", requires = "shader", help_heading = "Your shaders")]
    pub sink_size: Option<u64>,

    /// Set by `--cell-spec`: the bundle's `shaders/` folder, whose SPIR-V the worker runs instead
    /// of compiling the GLSL (not a flag).
    #[arg(skip)]
    pub spirv_dir: Option<PathBuf>,

    /// Set by `--cell-spec`: every worker compiles afresh (no pipeline cache or binaries, the
    /// driver's own cache bypassed; not a flag).
    #[arg(skip)]
    pub fresh: bool,

    /// The arguments given on the command line or through their variable, by clap id (not a
    /// flag): `--resume` takes the others from the report and refuses these where they differ.
    #[arg(skip)]
    pub explicit: Vec<String>,

    /// `--skips` patterns taken from the report `--resume` continues (not a flag).
    #[arg(skip)]
    pub skip_patterns: Option<Vec<String>>,
}

#[derive(Args, Debug)]
pub struct BisectArgs {
    /// The run report (rtprobe.report/1) with the faults
    pub report: PathBuf,

    /// Build the isolation list and workarounds around this faulting cell (default: the first
    /// faulting cell the minimal conjunction holds for)
    #[arg(long, value_name = "ID")]
    pub cell: Option<String>,

    /// Also write the result as JSON (schema rtprobe.bisect/1; the predicate under "minimal")
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,

    /// The scope: cells bisection may use and run, in --filter syntax (repeatable; default: the
    /// report's own --filter). A wider scope lets bisection test axes the report did not vary
    #[arg(long, value_name = "FILTER")]
    pub filter: Vec<String>,

    /// Run nothing: use the report's verdicts alone (on a machine without the report's device)
    #[arg(long)]
    pub offline: bool,

    /// A pass counts only when a fault of the observed rate would have missed all its attempts
    /// with at most this probability (passes are repeated until then)
    #[arg(long, default_value_t = crate::bisect::DEFAULT_MAX_MISS, value_name = "P")]
    pub max_miss: f64,

    /// At most this many attempts per cell
    #[arg(long, default_value_t = crate::bisect::DEFAULT_MAX_ATTEMPTS, value_name = "N")]
    pub max_attempts: u32,

    /// Worker processes (default: the report's)
    #[arg(long, short = 'j')]
    pub jobs: Option<usize>,
}

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// The run report (rtprobe.report/1), or `rtprobe reduce`'s DIR/reduce.json (the issue of
    /// the reduced shader)
    pub report: PathBuf,

    /// A bisection of that report (`rtprobe bisect --json FILE`); without it, the report's own
    /// verdicts are bisected offline
    #[arg(long, value_name = "FILE")]
    pub bisect: Option<PathBuf>,

    /// Output file (default: stdout); written atomically
    #[arg(long, short = 'o', alias = "output", value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// `md` (the issue text) or `json` (the same content as data)
    #[arg(long, value_enum, default_value = "md")]
    pub format: crate::report::issue::Format,

    /// A run of the same device with `--lane-evidence force` that holds the failing cell: its
    /// lane evidence goes into the issue (its verdicts do not)
    #[arg(long, value_name = "REPORT")]
    pub lanes: Option<PathBuf>,

    /// Do not re-run the failing cell under VK_LAYER_KHRONOS_validation (by default the issue
    /// carries that run's result when the report's device is on this machine and the run did
    /// not validate)
    #[arg(long)]
    pub no_validation_run: bool,
}

#[derive(Args, Debug)]
pub struct ReproArgs {
    /// The cell id (as in the report)
    pub cell: String,

    /// The run report the cell comes from
    #[arg(long, value_name = "REPORT")]
    pub from: PathBuf,

    /// The bundle directory (created; an existing non-empty one needs --force)
    #[arg(long, short = 'o', alias = "output", value_name = "DIR")]
    pub out: PathBuf,

    /// Replace an existing non-empty DIR (its old files are removed, not merged)
    #[arg(long)]
    pub force: bool,
}

#[derive(Args, Debug)]
pub struct DevicesArgs {
    /// Print a JSON array instead of text
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct CapsArgs {
    /// Device index or case-insensitive name substring (default: the first RT-capable device,
    /// discrete GPUs first)
    #[arg(long, short = 'd', value_name = "INDEX|NAME")]
    pub device: Option<String>,

    /// Print one JSON object (schema rtprobe.caps/2) instead of text
    #[arg(long)]
    pub json: bool,

    /// Also write the JSON report to FILE (atomically)
    #[arg(long, short = 'o', alias = "output", value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// Also write the capabilities as a Khronos Vulkan Profiles JSON file
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,

    /// Do not create a logical device to check that the features the matrix needs can be enabled
    #[arg(long)]
    pub no_device_check: bool,
}

#[derive(Subcommand, Debug)]
pub enum SceneCommand {
    /// Load a glTF 2.0 scene (.gltf or .glb) as `--scene` would and print its meshes,
    /// triangles, instances, materials, camera, the bytes of its geometry and the time it took
    Info {
        /// The scene file
        file: PathBuf,
    },
    /// Write a glTF scene made by rtprobe: the test scene (three meshes, a node hierarchy, three
    /// materials, one alpha-masked, two PNG textures, a camera), or with --triangles a large one
    Make {
        /// The folder to write it into (created if missing)
        dir: PathBuf,
        /// Make a large scene of at least this many triangles (16 height-field meshes)
        #[arg(long, value_name = "N")]
        triangles: Option<u64>,
        /// Write one binary .glb (images in buffer views) instead of .gltf, .bin and PNGs
        #[arg(long)]
        glb: bool,
    },
}

#[derive(Args, Debug)]
pub struct StressArgs {
    /// Device index or case-insensitive name substring (default: the first RT-capable device)
    #[arg(long, short = 'd', value_name = "INDEX|NAME")]
    pub device: Option<String>,

    /// Cases to run, comma-separated (default: all): watertight, far, grazing, degenerate, tmin,
    /// transform, self
    #[arg(long, value_delimiter = ',', value_name = "CASE,...")]
    pub cases: Vec<String>,

    /// Seed of the random scenes and rays
    #[arg(long, default_value_t = 1)]
    pub seed: u64,

    /// CTS-sized scenes and ray counts (65,536-triangle square, 256×256 rays; slow on CPU drivers)
    #[arg(long)]
    pub full: bool,

    /// Write the JSON report (schema rtprobe.stress/3) to FILE, atomically
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,

    /// Write the `far` case's error-against-distance plot as SVG to FILE
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,

    /// Deadline for one submission (AS build or trace), in seconds
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS")]
    pub timeout: f64,

    /// Trace with ray queries in a compute shader instead of an RT pipeline (VK_KHR_ray_query)
    #[arg(long)]
    pub ray_query: bool,
}

#[derive(Args, Debug)]
pub struct PatchArgs {
    /// Inputs: SPIR-V binaries (`.spv`, or any file starting with the SPIR-V magic number) or
    /// GLSL sources. Several inputs are one pipeline, patched together: one push-constant
    /// address per descriptor across all of them, past every stage's own push data
    pub inputs: Vec<PathBuf>,

    #[arg(long, short = 'a', value_delimiter = ',', value_name = "PATCH,...", help = crate::patches::apply_help())]
    pub apply: Vec<String>,

    /// A patch option KEY=VALUE (repeatable); see --list for each patch's keys
    #[arg(long = "option", value_name = "KEY=VALUE")]
    pub options: Vec<String>,

    /// Output: a file (one input), a folder (several inputs), or `-` for stdout (one input).
    /// Default: beside each input, NAME.patched.spv. Written only if every patch applied and every
    /// result validates
    #[arg(long, short = 'o', alias = "output", value_name = "FILE|DIR|-")]
    pub out: Option<PathBuf>,

    /// The host contract (JSON): the push-constant bytes and stages to add, which address goes
    /// where, the spec constants. Default: beside the output, NAME.contract.json
    #[arg(long, value_name = "FILE")]
    pub contract: Option<PathBuf>,

    /// Also write the input as compiled, before any patch (a file for one input, a folder for
    /// several)
    #[arg(long, value_name = "FILE|DIR")]
    pub emit_unpatched: Option<PathBuf>,

    /// List the patches and their options
    #[arg(long)]
    pub list: bool,

    /// Read every input as GLSL (default: GLSL unless it is a `.spv` file or starts with the
    /// SPIR-V magic number)
    #[arg(long)]
    pub glsl: bool,

    /// GLSL include directory (repeatable, searched in order after the input's own directory);
    /// `#include "x"` also looks next to the including file first
    #[arg(short = 'I', long = "include-dir", value_name = "DIR")]
    pub include_dirs: Vec<PathBuf>,

    /// GLSL macro NAME, NAME=VALUE or NAME(ARGS)=BODY, like glslang's -D (repeatable)
    #[arg(short = 'D', long = "define", value_name = "NAME[=VALUE]")]
    pub defines: Vec<String>,

    /// Vulkan environment of GLSL input: vulkan1.2 (SPIR-V 1.5), vulkan1.3 or vulkan1.4 (SPIR-V 1.6;
    /// the system shaderc, which predates 1.4, compiles it as vulkan1.3 and says so)
    #[arg(long, value_enum, default_value = "vulkan1.2", value_name = "ENV")]
    pub target_env: crate::shadergen::compile::TargetEnv,

    /// Stage of a GLSL input, overriding its file name (.rgen .rchit .rahit .rmiss .rint .rcall
    /// .comp .vert .frag, also NAME.rchit.glsl): rgen, rchit, rahit, rmiss, rint, rcall, vert,
    /// frag, comp. A SPIR-V module's stage is its entry point's
    #[arg(long, value_name = "STAGE")]
    pub stage: Option<String>,

    /// maxPushConstantsSize of the target device: a patch needing push constants past it is
    /// refused (128 bytes is what every Vulkan device has)
    #[arg(long, default_value_t = 128, value_name = "BYTES")]
    pub max_push_constants: u32,

    /// Patch without running spirv-val on the inputs and outputs (when the validator here is
    /// too old for a module)
    #[arg(long)]
    pub no_spirv_val: bool,

    /// Run the unpatched and the patched pipeline on the device (ray tracing stages: raygen
    /// and the stages it needs) with distinct data in every descriptor, fed as the host contract
    /// says, in a child process, and require identical storage images and writable storage
    /// buffers; nothing is written when they differ or the child crashes or hangs
    #[arg(long)]
    pub verify: bool,

    /// With --verify: fence deadline of one submission in seconds (the child is killed when
    /// silent for twice this plus 10 s), 1 to 3600
    #[arg(long, default_value_t = 30, value_name = "SECONDS", value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub verify_timeout: u64,

    /// With --verify: device index or case-insensitive name substring
    #[arg(long, short = 'd', value_name = "INDEX|NAME")]
    pub device: Option<String>,

    /// Print the diff of the disassembly before and after
    #[arg(long)]
    pub disassemble: bool,
}

#[derive(Args, Debug)]
pub struct BaselineArgs {
    /// A finished run report
    pub report: PathBuf,

    /// Output file
    #[arg(long, short = 'o', alias = "output", value_name = "FILE")]
    pub out: PathBuf,

    /// `json` (rtprobe's own, with flake details and performance bounds) or `deqp`
    /// (deqp-runner's `test,Status` lines)
    #[arg(long, value_enum, default_value = "json")]
    pub format: BaselineFormat,

    /// Also bound the mean time per cell of these phases (compile, pipeline, setup, trace, check)
    #[arg(long, value_delimiter = ',', value_name = "PHASE,...")]
    pub perf: Vec<String>,

    /// A bounded phase fails a later run above FACTOR × this run's mean + --perf-slack-ms
    #[arg(long, default_value_t = 2.0, value_name = "FACTOR")]
    pub perf_factor: f64,

    /// Absolute slack added to each performance bound, in milliseconds per cell
    #[arg(long, default_value_t = 1.0, value_name = "MS")]
    pub perf_slack_ms: f64,

    /// A bug link recorded with every expected failure
    #[arg(long, value_name = "URL")]
    pub bug: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BaselineFormat {
    Json,
    Deqp,
}

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Run reports (shards of one run, or re-runs of parts of it)
    #[arg(required = true, num_args = 1..)]
    pub reports: Vec<PathBuf>,

    /// Output report
    #[arg(long, short = 'o', alias = "output", value_name = "FILE")]
    pub out: PathBuf,

    /// Merge even reports of different devices, scenes, options or rtprobe versions
    #[arg(long)]
    pub force: bool,

    /// Hold the merged report to this baseline (as `run --baseline`); without it, the shards'
    /// own baseline checks are carried when they all used the same baseline
    #[arg(long, value_name = "FILE")]
    pub baseline: Option<PathBuf>,

    /// With a baseline: cells better than expected are reported but do not fail the merge
    #[arg(long)]
    pub allow_improvements: bool,
}

#[derive(Args, Debug)]
pub struct DiffArgs {
    pub old: PathBuf,
    pub new: PathBuf,

    /// `text` (a table) or `md` (Markdown for a PR comment)
    #[arg(long, value_enum, default_value = "text")]
    pub format: DiffFormat,

    /// Also write the diff to FILE (in --format)
    #[arg(long, short = 'o', alias = "output", value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// Report a phase's time per cell only when it changed by more than this factor (0.5 = ±50%)
    #[arg(long, default_value_t = 0.5)]
    pub noise: f64,

    /// ... and by more than this many milliseconds per cell
    #[arg(long, default_value_t = 0.5, value_name = "MS")]
    pub noise_floor_ms: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DiffFormat {
    Text,
    Md,
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Device index or case-insensitive name substring (passed to every run)
    #[arg(long, short = 'd', value_name = "INDEX|NAME")]
    pub device: Option<String>,

    /// Output directory for bench.json and the SVG plots (default: reports/bench-<timestamp>)
    #[arg(long, short = 'o', alias = "output", value_name = "DIR")]
    pub out: Option<PathBuf>,

    /// A small bench for tests and CI: sizes 8 and 16, a few cells, f 0.001 and 1, one flaky
    /// probability, no warm-up (every other flag still overrides)
    #[arg(long)]
    pub quick: bool,

    /// Square image sizes (`N` or `NxN`, N a multiple of 8, 8..=2048; default 8,16,32,64,128,256,512)
    #[arg(long, value_delimiter = ',', value_name = "N,...")]
    pub sizes: Vec<String>,

    /// Fractions f of wrong records, each in (0, 1] (default 0.001,0.01,0.1)
    #[arg(long, value_delimiter = ',', value_name = "F,...")]
    pub fractions: Vec<f64>,

    /// Seeds of the `value:f:SEED` injection; each seed is one run per size and f (default 1,2)
    #[arg(long, value_delimiter = ',', value_name = "SEED,...")]
    pub seeds: Vec<u64>,

    /// The cells injected with wrong values (--filter syntax; default
    /// descriptor_model=descriptor_indexing,resource=storage_buffer)
    #[arg(long, value_name = "FILTER")]
    pub inject_filter: Option<String>,

    /// Restrict the timed matrix (repeatable, --filter syntax; default: the default matrix)
    #[arg(long, value_name = "FILTER")]
    pub matrix_filter: Vec<String>,

    /// Flaky fault probabilities P, each in (0, 1) (default 0.1,0.3,0.5)
    #[arg(long, value_delimiter = ',', value_name = "P,...")]
    pub flaky: Vec<f64>,

    /// The cells injected with flaky faults (default
    /// descriptor_model=descriptor_indexing,resource=storage_buffer,index=literal)
    #[arg(long, value_name = "FILTER")]
    pub flaky_filter: Option<String>,

    /// Image size of the flaky rounds (default 16)
    #[arg(long, value_name = "N")]
    pub flaky_size: Option<String>,

    /// At most this many rounds (attempts per cell) per flaky probability (default 30)
    #[arg(long, value_name = "R")]
    pub max_rounds: Option<u32>,

    /// --timeout of the flaky rounds, in seconds (an injected device fault hangs on some drivers,
    /// e.g. NVIDIA; default: run's own)
    #[arg(long, value_name = "SECONDS")]
    pub flaky_timeout: Option<f64>,

    /// Skip part 2 (flaky faults). Its injected fault reads an invalid address, which hangs some
    /// GPUs (NVIDIA 580) for every later process on the machine; the part runs last for that reason
    #[arg(long, conflicts_with = "flaky")]
    pub no_flaky: bool,

    /// Run configurations to compare (each one quoted string of extra run arguments, e.g.
    /// '-j 1' '-j 2' '--isolation process-per-cell'); entries with flags this rtprobe's run does
    /// not know are skipped (default: the built-in list, bench::DEFAULT_SWEEP). Takes every
    /// following argument: put it last
    #[arg(long, num_args = 1.., allow_hyphen_values = true, value_name = "ARGS")]
    pub sweep_args: Vec<String>,

    /// Cells of the sweep (repeatable, --filter syntax; default
    /// descriptor_model=descriptor_indexing,resource=storage_buffer)
    #[arg(long, value_name = "FILTER")]
    pub sweep_filter: Vec<String>,

    /// Image sizes of part 4, detection with mutants (`run --mutants` at each; default 8,16,64;
    /// `--quick`: 16)
    #[arg(long, value_delimiter = ',', value_name = "N,...")]
    pub mutants_sizes: Vec<String>,

    /// The cells part 4 mutates (repeatable, --filter syntax; default
    /// descriptor_model=descriptor_indexing,resource=storage_buffer|acceleration_structure)
    #[arg(long, value_name = "FILTER")]
    pub mutants_filter: Vec<String>,

    /// Skip part 4 (detection with mutants)
    #[arg(long, conflicts_with = "mutants_sizes")]
    pub no_mutants: bool,

    /// Do not run each timed point once before measuring it (caches stay as they are)
    #[arg(long)]
    pub no_warmup: bool,

    /// Run every size on all its cells (default: sizes above 64×64 run a `--shard 1/k` sample,
    /// scaled up)
    #[arg(long)]
    pub no_sample: bool,

    /// Measure only time against distinct cells: one `run --cells-scale N` per N, twice in a row
    /// (first, again), with a fitted line each (e.g. 100,500,1000,2000,5000; plot
    /// time-vs-cells.svg). The other parts do not run
    #[arg(long, value_delimiter = ',', value_name = "N,...")]
    pub cells: Vec<usize>,

    /// With --cells: each point's first run in new, empty cache folders (rtprobe's, NVIDIA's and
    /// Mesa's), so every pipeline is compiled
    #[arg(long, requires = "cells")]
    pub cells_cold: bool,
}
