//! The child `rtprobe run`s bench measures with: [`Bench`] starts this executable with the base
//! arguments ([`BASE_ARGS`]) and a point's own, reads its report back and deletes it; it also
//! counts the cells a filter selects (`run --list`) and the flags `run` knows (`run --help`).
use super::options::{BenchOptions, BASE_ARGS};
use crate::model::RunReport;
use std::process::{Command, Stdio};
use std::time::Instant;

/// Why a point could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("cannot start `{cmd}`: {source}")]
    Spawn { cmd: String, source: std::io::Error },
    #[error("`{cmd}` exited with code {code}: {stderr}")]
    RunFailed { cmd: String, code: i32, stderr: String },
    #[error("`{cmd}`: {why}")]
    Report { cmd: String, why: crate::model::LoadError },
    #[error("`{cmd}` ran no {what} cell: check the filter")]
    Empty { cmd: String, what: &'static str },
}

/// One child run: its command line and report.
pub(super) struct Ran {
    pub(super) command: String,
    pub(super) wall_s: f64,
    pub(super) report: RunReport,
}

/// Runs the points, each a child `rtprobe run`; the parts' methods are in their own files.
pub struct Bench<'a> {
    pub(super) opts: &'a BenchOptions,
    counter: usize,
    /// One line per point, for the terminal.
    pub progress: &'a mut dyn FnMut(&str),
}

/// A square `--size` argument.
pub(super) fn size_arg(s: u32) -> String {
    format!("{s}x{s}")
}

/// `a` as a shell word (the command line a point records).
fn shell_quote(a: &str) -> String {
    if a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,".contains(c)) {
        a.to_string()
    } else {
        format!("'{}'", a.replace('\'', "'\\''"))
    }
}

impl<'a> Bench<'a> {
    pub fn new(opts: &'a BenchOptions, progress: &'a mut dyn FnMut(&str)) -> Self {
        Bench { opts, counter: 0, progress }
    }

    /// The base arguments, the device and `--validate`.
    fn base(&self) -> Vec<String> {
        let mut a: Vec<String> = BASE_ARGS.iter().map(|s| s.to_string()).collect();
        if let Some(d) = &self.opts.device {
            a.extend(["--device".into(), d.clone()]);
        }
        if self.opts.validate {
            a.push("--validate".into());
        }
        a
    }

    /// This executable with `args` and `env` (stdin closed, stderr captured; stdout as `stdout`
    /// says).
    fn spawn(
        &self,
        args: &[String],
        cmd: &str,
        stdout: Stdio,
        env: &[(&str, std::path::PathBuf)],
    ) -> Result<std::process::Output, BenchError> {
        let mut c = Command::new(&self.opts.exe);
        c.args(args)
            .envs(env.iter().map(|(k, v)| (*k, v)))
            // Its job folder inside bench's work folder, which an interrupt removes.
            .env("TMPDIR", &self.opts.work_dir)
            .stdin(Stdio::null())
            .stdout(stdout)
            .stderr(Stdio::piped());
        let spawn_err = |source| BenchError::Spawn { cmd: cmd.to_string(), source };
        // Its own process group, dying with bench, killed by bench's interrupt handler.
        let child = crate::runner::groups::spawn_registered(&mut c).map_err(spawn_err)?;
        let pgid = child.id() as i32;
        let out = child.wait_with_output().map_err(spawn_err);
        crate::runner::groups::unregister(pgid);
        out
    }

    /// `rtprobe run ARGS` (plus the base arguments), its report read back and deleted.
    pub(super) fn run(&mut self, args: &[String]) -> Result<Ran, BenchError> {
        self.run_env(args, &[])
    }

    /// [`Bench::run`] with `env` set for the child (cache folders).
    pub(super) fn run_env(
        &mut self,
        args: &[String],
        env: &[(&str, std::path::PathBuf)],
    ) -> Result<Ran, BenchError> {
        self.counter += 1;
        let out = self.opts.work_dir.join(format!("point-{}.json", self.counter));
        let mut full = vec!["run".to_string()];
        full.extend(self.base());
        full.extend(args.iter().cloned());
        let command = std::iter::once("rtprobe".to_string())
            .chain(full.iter().map(|a| shell_quote(a)))
            .collect::<Vec<_>>()
            .join(" ");
        full.extend(["-o".to_string(), out.to_string_lossy().into_owned()]);
        let t = Instant::now();
        let o = self.spawn(&full, &command, Stdio::null(), env)?;
        let wall_s = t.elapsed().as_secs_f64();
        let code = o.status.code().unwrap_or(-1);
        // 0: all passed; 1: findings (the injected ones); 11: an injection went undetected.
        if ![0, 1, 11].contains(&code) {
            return Err(BenchError::RunFailed { cmd: command, code, stderr: last_line(&o.stderr) });
        }
        let report = RunReport::load(&out)
            .map_err(|why| BenchError::Report { cmd: command.clone(), why })?;
        let _ = std::fs::remove_file(&out);
        Ok(Ran { command, wall_s, report })
    }

    /// How many cells `run --list ARGS` would run.
    pub(super) fn to_run(&self, args: &[String]) -> Result<usize, BenchError> {
        let mut full = vec!["run".to_string(), "--list".into()];
        full.extend(self.base());
        full.extend(args.iter().cloned());
        let cmd = format!("rtprobe {}", full.join(" "));
        let o = self.spawn(&full, &cmd, Stdio::piped(), &[])?;
        if !o.status.success() {
            return Err(BenchError::RunFailed {
                cmd,
                code: o.status.code().unwrap_or(-1),
                stderr: last_line(&o.stderr),
            });
        }
        Ok(String::from_utf8_lossy(&o.stdout).lines().filter(|l| l.starts_with("run ")).count())
    }

    /// The long and short flags `rtprobe run --help` lists.
    pub(super) fn known_flags(&self) -> Result<Vec<String>, BenchError> {
        let o = self.spawn(
            &["run".into(), "--help".into()],
            "rtprobe run --help",
            Stdio::piped(),
            &[],
        )?;
        let text = String::from_utf8_lossy(&o.stdout);
        Ok(text
            .split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']' || c == '=')
            .filter(|w| w.starts_with('-') && w.len() > 1)
            .map(|w| w.to_string())
            .collect())
    }
}

/// A child's last stderr line, without its own `rtprobe: error: ` prefix.
fn last_line(stderr: &[u8]) -> String {
    let text = String::from_utf8_lossy(stderr);
    let last = text.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("").trim();
    last.strip_prefix("rtprobe: error: ").unwrap_or(last).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoting_keeps_predicates_one_word() {
        assert_eq!(shell_quote("stage=raygen|miss@value:0.1:1"), "'stage=raygen|miss@value:0.1:1'");
        assert_eq!(shell_quote("64x64"), "64x64");
    }
}
