//! The command line: clap definitions ([`args`]), exit codes ([`exit`]), and dispatch. Nothing
//! below this module knows about clap.
pub mod args;
pub mod bench;
pub mod bisect;
pub mod commands;
pub mod exit;
pub mod fleet;
pub mod issue_run;
pub mod patch;
pub mod patch_inputs;
pub mod report;
pub mod repro;
pub mod run;
pub mod shared;
pub mod stress;
pub mod values;

use args::{Cli, Command};
use clap::Parser;

fn init_tracing(verbose: u8) {
    use tracing_subscriber::EnvFilter;
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .try_init();
}

/// Parse the command line, run the command, and return the process exit code. Errors are printed
/// as one line on stderr.
pub fn main_entry() -> u8 {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { exit::USAGE } else { exit::OK };
        }
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
        Command::Run(a) => run::run(&g, a),
        Command::Patch(a) => patch::patch(&g, a),
        Command::Bisect(a) => bisect::bisect(&g, a),
        Command::Report(a) => report::report(&g, a),
        Command::Repro(a) => repro::repro(&g, a),
        Command::Stress(a) => stress::stress(&g, a),
        Command::Bench(a) => bench::bench(&g, a),
        Command::Baseline(a) => fleet::baseline(a),
        Command::Merge(a) => fleet::merge_cmd(a),
        Command::Diff(a) => fleet::diff_cmd(a),
        Command::Worker { job } => return crate::runner::worker::main(job),
        Command::StressWorker { job } => return crate::stress::worker::main(job),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("rtprobe: error: {}", format!("{e:#}").replace('\n', " "));
            exit::code_for(&e)
        }
    }
}
