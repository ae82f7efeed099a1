//! The `rtprobe` binary: everything lives in the library; this only turns its exit code into the
//! process's.
fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(rtprobe::cli::main_entry())
}
