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

    /// Enable VK_LAYER_KHRONOS_validation when installed (also RTPROBE_VALIDATE=1)
    #[arg(long, global = true, env = "RTPROBE_VALIDATE", action = clap::ArgAction::SetTrue, value_parser = clap::builder::BoolishValueParser::new())]
    pub validate: bool,

    /// More log output on stderr (-v info, -vv debug); RUST_LOG overrides
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// List the Vulkan physical devices, one line each, and whether they can run RT pipelines
    Devices(DevicesArgs),
    /// Show what a device can do for ray tracing, and which matrix axis values it can run
    Caps(CapsArgs),
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

    /// Print one JSON object (schema rtprobe.caps/1) instead of text
    #[arg(long)]
    pub json: bool,

    /// Also write the JSON report to FILE (atomically)
    #[arg(long, short = 'o', value_name = "FILE")]
    pub out: Option<PathBuf>,

    /// Also write the capabilities as a Khronos Vulkan Profiles JSON file
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,

    /// Do not create a logical device to check that the features the matrix needs can be enabled
    #[arg(long)]
    pub no_device_check: bool,
}
