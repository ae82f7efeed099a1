//! A work queue over scoped threads: items `0..n` handed out in order to `threads` threads, each
//! with its own state (a shaderc compiler, say, which is not shared between threads). Used by the
//! worker's prebuild for GLSL compiles (`shadergen::compile`) and pipeline creation
//! (`exec::prebuild`).
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// `work(&mut state, i)` for every `i` in `0..n` on at most `threads` threads, results in index
/// order. A thread whose `init` gives `None` takes no item; an item no thread took is `None`.
/// `progress(done, n)` is called after each item.
pub fn map<S, T: Send>(
    n: usize,
    threads: usize,
    init: impl Fn() -> Option<S> + Sync,
    work: impl Fn(&mut S, usize) -> T + Sync,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<Option<T>> {
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let out: Vec<Mutex<Option<T>>> = (0..n).map(|_| Mutex::new(None)).collect();
    std::thread::scope(|s| {
        for _ in 0..threads.clamp(1, n.max(1)) {
            s.spawn(|| {
                let Some(mut state) = init() else { return };
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    let r = work(&mut state, i);
                    *out[i].lock().unwrap_or_else(|p| p.into_inner()) = Some(r);
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, n);
                }
            });
        }
    });
    out.into_iter().map(|m| m.into_inner().unwrap_or_else(|p| p.into_inner())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_once_in_order_with_progress() {
        let calls = AtomicUsize::new(0);
        let r = map(
            100,
            4,
            || Some(0u32),
            |seen, i| {
                *seen += 1;
                i * 2
            },
            &|_, n| {
                assert_eq!(n, 100);
                calls.fetch_add(1, Ordering::Relaxed);
            },
        );
        assert_eq!(r, (0..100).map(|i| Some(i * 2)).collect::<Vec<_>>());
        assert_eq!(calls.into_inner(), 100);
    }

    #[test]
    fn items_no_thread_could_take_are_none() {
        let r = map(3, 2, || None::<()>, |_, i| i, &|_, _| {});
        assert_eq!(r, vec![None, None, None]);
        assert!(map(0, 8, || Some(()), |_, i| i, &|_, _| {}).is_empty());
    }
}
