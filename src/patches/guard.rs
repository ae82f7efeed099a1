//! Running a patch so that it can never leave a module half-rewritten or panic out of the
//! process: on a copy ([`on_copy`]), with panics caught and returned ([`quietly`]).
use super::PatchError;
use rspirv::dr::Module;

/// A panic [`quietly`] caught, with its message ("panic" when it had none).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct Panicked(pub(crate) String);

/// `f`, with a panic caught and returned instead of printed.
pub(crate) fn quietly<T>(f: impl FnOnce() -> T + std::panic::UnwindSafe) -> Result<T, Panicked> {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let r = std::panic::catch_unwind(f);
    std::panic::set_hook(hook);
    r.map_err(|e| {
        Panicked(
            e.downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| e.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into()),
        )
    })
}

/// Run `f` on a copy of `m`, catching panics; `m` takes the copy only when `f` succeeds, so a
/// failed patch leaves the module as it was.
pub(crate) fn on_copy<R>(
    m: &mut Module,
    f: impl FnOnce(&mut Module) -> Result<R, PatchError>,
) -> Result<R, PatchError> {
    let mut work = m.clone();
    let r = quietly(std::panic::AssertUnwindSafe(|| f(&mut work)))
        .map_err(|p| PatchError::Internal(p.0))??;
    *m = work;
    Ok(r)
}
