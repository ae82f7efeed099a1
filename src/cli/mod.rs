//! The command line: clap definitions ([`args`]), exit codes ([`exit`]), output that never
//! panics ([`out`]), and dispatch. Nothing below this module knows about clap.
pub mod args;
pub mod bench;
pub mod bisect;
pub mod commands;
pub mod exit;
pub mod fleet;
mod issue_out;
pub mod issue_run;
pub mod out;
pub mod output_dir;
pub mod patch;
pub mod patch_inputs;
mod patch_verify;
pub mod paths;
pub mod plan;
pub mod progress;
pub mod reduce;
mod reduce_job;
mod reduce_out;
mod reduce_patch;
mod reduce_slice;
pub mod report;
mod report_reduce;
pub mod repro;
pub mod resume;
pub mod run;
pub mod scene;
mod scene_check;
pub mod shader;
mod shader_bounds;
mod shader_compare;
mod shader_exec;
mod shader_fill;
mod shader_gpu_av;
mod shader_hit_groups;
mod shader_plan;
mod shader_profile;
mod shader_report;
mod shader_uniform;
pub mod shared;
pub mod stress;
pub mod values;

use args::{Cli, Command};
use clap::{CommandFactory, FromArgMatches};
use out::{errln, out};

fn init_tracing(verbose: u8) {
    use tracing_subscriber::filter::{LevelFilter, Targets};
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    let level = match verbose {
        0 => LevelFilter::WARN,
        1 => LevelFilter::INFO,
        _ => LevelFilter::DEBUG,
    };
    // `RUST_LOG` as `target=level,…` or a bare level (tracing-subscriber's `Targets`: the
    // env-filter's span and field directives cost a fresh build the regex engine's DFAs, issue
    // 27); unset, empty or unparsable, the `-v` level.
    let filter = std::env::var("RUST_LOG")
        .ok()
        .filter(|s| !s.trim().is_empty())
        .and_then(|s| s.parse::<Targets>().ok())
        .unwrap_or_else(|| Targets::new().with_default(level));
    let fmt = tracing_subscriber::fmt::layer().with_writer(std::io::stderr).with_target(false);
    let _ = tracing_subscriber::registry().with(fmt).with(filter).try_init();
}

/// A clap error as rtprobe's: `rtprobe: error: <what>: <its details>; <clap's tip>` on one line,
/// then a hint line naming the command's help. clap's indented detail lines (the missing
/// arguments, the possible values) join the first line; its usage block is left out.
fn usage_error(e: &clap::Error, command: &str) -> String {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::MissingSubcommand | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) && command == "rtprobe"
    {
        let names: Vec<String> = Cli::command()
            .get_subcommands()
            .filter(|c| !c.is_hide_set())
            .map(|c| c.get_name().to_string())
            .collect();
        return format!(
            "rtprobe: error: no command given: one of {}; `rtprobe --help` says what each does\n",
            names.join(", ")
        );
    }
    let text = e.render().to_string();
    let mut what = String::new();
    let mut details = Vec::new();
    let mut tips = Vec::new();
    for raw in text.lines() {
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        if let Some(first) = line.strip_prefix("error: ").filter(|_| what.is_empty()) {
            what = first.trim_end_matches(':').to_string();
        } else if let Some(tip) = line.strip_prefix("tip: ") {
            tips.push(tip.to_string());
        } else if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        } else if !what.is_empty() && raw.starts_with(' ') {
            details.push(line.to_string());
        }
    }
    if what.is_empty() {
        what = text.lines().next().unwrap_or("bad arguments").trim().to_string();
    }
    if !details.is_empty() {
        what = format!("{what}: {}", details.join(", "));
    }
    let tips = if tips.is_empty() { String::new() } else { format!(" ({})", tips.join("; ")) };
    format!("rtprobe: error: {what}{tips}; `{command} --help` lists every option\n")
}

/// `rtprobe NAME` when the first argument names one of rtprobe's commands, else `rtprobe`.
fn command_of(argv: &[std::ffi::OsString]) -> String {
    let known = |a: &str| Cli::command().get_subcommands().any(|c| c.get_name() == a);
    argv.get(1)
        .and_then(|a| a.to_str())
        .filter(|a| known(a))
        .map(|a| format!("rtprobe {a}"))
        .unwrap_or_else(|| "rtprobe".into())
}

/// The ids of the arguments `m` got from the command line or from their variable.
fn explicit_ids(m: &clap::ArgMatches) -> Vec<String> {
    use clap::parser::ValueSource;
    m.ids()
        .filter(|id| {
            matches!(
                m.value_source(id.as_str()),
                Some(ValueSource::CommandLine | ValueSource::EnvVariable)
            )
        })
        .map(|id| id.as_str().to_string())
        .collect()
}

/// Parse the command line (clap errors in rtprobe's form: [`usage_error`]); for `run`, which of
/// its arguments were given.
fn parse() -> Result<Cli, u8> {
    let fail = |e: clap::Error, command: &str| {
        if e.use_stderr() {
            out::stderr(&usage_error(&e, command));
            exit::USAGE
        } else {
            // --help and --version: their text, on stdout.
            out!("{}", e.render().ansi());
            exit::OK
        }
    };
    let argv: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let command = command_of(&argv);
    let color =
        if out::plain_stdout() { clap::ColorChoice::Never } else { clap::ColorChoice::Auto };
    let matches =
        Cli::command().color(color).try_get_matches_from(&argv).map_err(|e| fail(e, &command))?;
    let mut cli = Cli::from_arg_matches(&matches).map_err(|e| fail(e, &command))?;
    if let (Command::Run(a), Some(("run", sub))) = (&mut cli.command, matches.subcommand()) {
        a.explicit = explicit_ids(sub);
        a.explicit.extend(explicit_ids(&matches));
    }
    Ok(cli)
}

/// Parse the command line, run the command, and return the process exit code. Errors are printed
/// as one line on stderr.
pub fn main_entry() -> u8 {
    let cli = match parse() {
        Ok(c) => c,
        Err(code) => return code,
    };
    init_tracing(cli.verbose);
    let mode = cli.validate.unwrap_or(args::ValidateMode::Off);
    let g = commands::Globals {
        validate: mode != args::ValidateMode::Off,
        gpu_av: mode == args::ValidateMode::GpuAv,
    };
    let result = match &cli.command {
        Command::Devices(a) => commands::devices(&g, a),
        Command::Caps(a) => commands::caps_cmd(&g, a),
        Command::Run(a) if !a.shader.is_empty() => shader::run_shaders(&g, a),
        Command::Run(a) => run::run(&g, a),
        Command::Patch(a) => patch::patch(&g, a),
        Command::Bisect(a) => bisect::bisect(&g, a),
        Command::Report(a) => report::report(&g, a),
        Command::Repro(a) => repro::repro(&g, a),
        Command::Stress(a) => stress::stress(&g, a),
        Command::Bench(a) => bench::bench(&g, a),
        Command::Scene(c) => scene::scene(c),
        Command::Baseline(a) => fleet::baseline(a),
        Command::Merge(a) => fleet::merge_cmd(a),
        Command::Diff(a) => fleet::diff_cmd(a),
        Command::Reduce(a) => reduce::reduce(&g, a),
        Command::Interesting { job, candidate } => return reduce_job::main(job, candidate),
        Command::Worker { job } => return crate::runner::worker::main(job),
        Command::StressWorker { job } => return crate::stress::worker::main(job),
        Command::VerifyWorker { job } => return crate::harness::child::main(job),
        Command::ShaderWorker { job } => return crate::harness::run::main(job),
    };
    tracing::debug!("command done: its objects dropped");
    match result {
        Ok(code) => code,
        Err(e) => {
            errln!("rtprobe: error: {}", exit::one_line(&e));
            exit::code_for(&e)
        }
    }
}
