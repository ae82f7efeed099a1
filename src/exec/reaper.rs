//! What a worker's chunk no longer needs, destroyed on a thread of its own ([`Reaper`]) while the
//! next chunk builds and runs. Destroying a chunk's pipelines and group libraries took the cell
//! thread 0.40 s on the H200 (s32's trace, `reports/nvidia-h200/perf/s32/`: 512 pipelines, from
//! the chunk's last result at 46.063 s to the next chunk's `prebuild` at 46.465 s), a serial gap
//! of a run's wall that is all rtprobe's own time. Only whole pipelines come here: linked ones and
//! their group libraries are destroyed on the cell thread (`Executor::release_pipelines`: the
//! H200 made no pipeline for 20 s when they went here, reports/nvidia-h200/perf/s33/).
//!
//! Sound (Vulkan 1.4.360, Vulkan-Docs HEAD): "All commands support being called concurrently
//! from multiple threads, but certain parameters, or components of parameters are defined to be
//! _externally synchronized_" ("Threading Behavior"); for `vkDestroyPipeline` that is only the
//! `pipeline` (`externsync="true"` in `vk.xml`), for `vkDestroyBuffer` and `vkFreeMemory` only the
//! buffer and the memory. Nothing handed over is used again by any other thread: the executor
//! forgets the handles when it hands them over, and every submission that used them has been
//! waited for (VUID-vkDestroyPipeline-pipeline-00765: "All submitted commands that refer to
//! pipeline must have completed execution"). The thread is joined before the executor destroys
//! anything else (its `Drop`), so nothing is destroyed after its device.
use std::sync::mpsc::{channel, Sender};
use std::thread::JoinHandle;

/// A thread that runs `destroy` on every item sent to it, in order, started at the first.
pub(super) struct Reaper<T: Send + 'static> {
    destroy: Option<Box<dyn FnMut(T) + Send>>,
    items: Option<Sender<T>>,
    thread: Option<JoinHandle<usize>>,
}

impl<T: Send + 'static> Reaper<T> {
    pub(super) fn new(destroy: impl FnMut(T) + Send + 'static) -> Self {
        Reaper { destroy: Some(Box::new(destroy)), items: None, thread: None }
    }

    /// Hand `item` to the thread (started now if it is not yet); returns at once.
    pub(super) fn send(&mut self, item: T) {
        if self.items.is_none() {
            let (tx, rx) = channel::<T>();
            let mut destroy = self.destroy.take().unwrap_or_else(|| Box::new(drop));
            self.thread = Some(std::thread::spawn(move || {
                let mut n = 0;
                for item in rx {
                    destroy(item);
                    n += 1;
                }
                n
            }));
            self.items = Some(tx);
        }
        if let Some(tx) = &self.items {
            // The thread holds the receiver until the sender is dropped; should it have ended
            // (a panicking `destroy`), the item is dropped here, never destroyed twice.
            let _ = tx.send(item);
        }
    }

    /// Wait until every item sent is destroyed: how many were (`None`: the thread panicked,
    /// or none was started). The reaper can be used again afterwards only with a new one.
    pub(super) fn join(&mut self) -> Option<usize> {
        self.items = None;
        self.thread.take().and_then(|t| t.join().ok())
    }
}

impl<T: Send + 'static> Drop for Reaper<T> {
    fn drop(&mut self) {
        self.join();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    #[test]
    fn items_are_destroyed_in_order_on_another_thread_and_all_before_join_returns() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let s = seen.clone();
        let caller = std::thread::current().id();
        let mut r = Reaper::new(move |k: u32| {
            assert_ne!(std::thread::current().id(), caller, "destroyed on the caller's thread");
            std::thread::sleep(std::time::Duration::from_millis(20));
            s.lock().unwrap().push(k);
        });
        let t = std::time::Instant::now();
        for k in 0..10 {
            r.send(k);
        }
        // Sending does not wait for the destruction (10 × 20 ms).
        assert!(t.elapsed() < std::time::Duration::from_millis(100), "{:?}", t.elapsed());
        assert_eq!(r.join(), Some(10));
        assert_eq!(*seen.lock().unwrap(), (0..10).collect::<Vec<_>>());
        // The twin: nothing sent, nothing started.
        assert_eq!(Reaper::new(|_: u32| {}).join(), None);
    }

    #[test]
    fn a_panicking_destroy_ends_the_thread_and_join_says_so_without_panicking() {
        let mut r = Reaper::new(|k: u32| assert!(k < 1, "item {k}"));
        r.send(0);
        r.send(1);
        r.send(2); // after the panic: dropped by the channel, not destroyed
        assert_eq!(r.join(), None);
    }
}
