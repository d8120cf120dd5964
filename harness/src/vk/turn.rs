//! One thread at a time in Vulkan per process. Vulkan lets two threads work on two devices at once,
//! but the Khronos validation layer of Debian 12 (1.3.239) does not always survive it: a test binary
//! whose two tests ran an executor each on their own thread crashed inside the layer's
//! `vkGetDeviceQueue` on one thread while the other was in `vkCreateDevice` (once in about sixty runs
//! with a third process loading the cores). The likeliest cause is the layer's one map from each
//! instance's and device's dispatch key to its state, written by the creates and destroys and read by
//! every call without a lock (KhronosGroup/Vulkan-ValidationLayers issue 4391, `GetLayerDataPtr`).
//! So everything in the harness that calls into Vulkan holds the process's turn, which the thread
//! holding it may take again. A worker process runs one executor on one thread: its turn is never
//! contended.

use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::ThreadId;

/// Which thread holds the turn and how many times it took it.
struct Holder {
    thread: Option<ThreadId>,
    depth: usize,
}

static HOLDER: Mutex<Holder> = Mutex::new(Holder {
    thread: None,
    depth: 0,
});
static RELEASED: Condvar = Condvar::new();

/// The turn, held until dropped on the thread that took it.
#[must_use = "the turn is given back when this is dropped"]
pub(crate) struct Turn {
    /// Not `Send`: the turn is the taking thread's.
    _thread_bound: std::marker::PhantomData<*const ()>,
}

fn holder() -> MutexGuard<'static, Holder> {
    // The holder's fields stay consistent through a panic elsewhere: a poisoned lock is still right.
    HOLDER.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Waits until no other thread holds the turn, then holds it (again, if this thread already does).
pub(crate) fn take() -> Turn {
    let me = std::thread::current().id();
    let mut h = holder();
    while h.thread.is_some_and(|t| t != me) {
        h = RELEASED.wait(h).unwrap_or_else(PoisonError::into_inner);
    }
    h.thread = Some(me);
    h.depth += 1;
    Turn {
        _thread_bound: std::marker::PhantomData,
    }
}

impl Drop for Turn {
    fn drop(&mut self) {
        let mut h = holder();
        h.depth -= 1;
        if h.depth == 0 {
            h.thread = None;
            drop(h);
            RELEASED.notify_one();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::take;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Barrier;

    /// Threads taking the turn, some twice over, are never inside it together, and each gets it.
    #[test]
    fn one_thread_holds_the_turn_at_a_time_and_may_take_it_again() {
        let inside = AtomicUsize::new(0);
        let most = AtomicUsize::new(0);
        let entered = AtomicUsize::new(0);
        let start = Barrier::new(4);
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| {
                    start.wait();
                    for round in 0..200 {
                        let _outer = take();
                        let _inner = (round % 2 == 0).then(take);
                        let now = inside.fetch_add(1, Ordering::SeqCst) + 1;
                        most.fetch_max(now, Ordering::SeqCst);
                        for _ in 0..64 {
                            std::hint::spin_loop();
                        }
                        std::thread::yield_now();
                        inside.fetch_sub(1, Ordering::SeqCst);
                        entered.fetch_add(1, Ordering::SeqCst);
                    }
                });
            }
        });
        assert_eq!(
            most.load(Ordering::SeqCst),
            1,
            "two threads held the turn at once"
        );
        assert_eq!(entered.load(Ordering::SeqCst), 800);
        // Given back whole: this thread takes it at once.
        let _again = take();
    }
}
