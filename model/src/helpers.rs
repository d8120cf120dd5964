//! Helper threads kept for the life of the process, which run one borrowed closure beside the
//! calling thread: a launch traced on every core starts no thread and tears none down (on a launch of
//! a few thousand rays, spawning and joining threads cost as much as tracing a tenth of them).
//!
//! One call uses the helpers at a time; a call made while they are busy (another thread's launch)
//! starts threads of its own for that call instead, so concurrent callers never wait for each other.

use std::any::Any;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard, OnceLock};

/// A closure lent to the helpers, its lifetime erased: [`run_beside`] does not return while a helper
/// may still call it.
#[derive(Clone, Copy)]
struct Lent(*const (dyn Fn() + Sync + 'static));

// SAFETY: the pointee is `Sync`, and the pointer is dereferenced only while the lender waits.
unsafe impl Send for Lent {}

#[derive(Default)]
struct State {
    /// The closure of the current call, None between calls and once the caller has finished its share.
    job: Option<Lent>,
    /// Counts calls, so a helper takes each call's closure at most once.
    call: u64,
    /// Helpers the current call still wants to start.
    wanted: usize,
    /// Helpers running the current closure.
    running: usize,
    /// The first panic of a helper during the current call.
    panic: Option<Box<dyn Any + Send>>,
    /// Helper threads started so far.
    threads: usize,
}

struct Helpers {
    state: Mutex<State>,
    /// Signalled when a call lends a closure.
    lent: Condvar,
    /// Signalled when the last running helper finishes.
    finished: Condvar,
    /// Held for the whole of a call: one call at a time uses the helpers.
    busy: Mutex<()>,
    /// The number of the last call that lent a closure (`State::call`), read without the lock by a
    /// helper that waits for the next call awake.
    posted: AtomicU64,
    /// Helpers running the current closure (`State::running`), read without the lock by a caller
    /// that waits for them awake.
    active: AtomicUsize,
}

/// How long a helper stays awake for the next call before sleeping: waking a sleeping thread costs
/// tens of microseconds on a virtual machine (about as long as tracing fifty rays), and the calls of
/// one launch follow each other within microseconds.
const AWAKE: std::time::Duration = std::time::Duration::from_micros(50);

/// How long a caller whose own share is done waits awake for its helpers (their last pieces of
/// work), before sleeping.
const JOIN_AWAKE: std::time::Duration = std::time::Duration::from_micros(1000);

/// Spins until `done` holds or `awake` has passed; whether `done` held.
fn spin_until(awake: std::time::Duration, done: impl Fn() -> bool) -> bool {
    let start = std::time::Instant::now();
    loop {
        for _ in 0..64 {
            if done() {
                return true;
            }
            std::hint::spin_loop();
        }
        if start.elapsed() > awake {
            return done();
        }
    }
}

fn helpers() -> &'static Helpers {
    static HELPERS: OnceLock<Helpers> = OnceLock::new();
    HELPERS.get_or_init(|| Helpers {
        state: Mutex::new(State::default()),
        lent: Condvar::new(),
        finished: Condvar::new(),
        busy: Mutex::new(()),
        posted: AtomicU64::new(0),
        active: AtomicUsize::new(0),
    })
}

/// A lock that a panic elsewhere does not poison for good (the state stays consistent: every update
/// is made whole under the lock).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn helper_loop(h: &'static Helpers) {
    let mut last_call = 0u64;
    loop {
        spin_until(AWAKE, || h.posted.load(Ordering::Acquire) != last_call);
        let job = {
            let mut s = lock(&h.state);
            loop {
                match s.job {
                    Some(job) if s.call != last_call && s.wanted > 0 => {
                        s.wanted -= 1;
                        s.running += 1;
                        h.active.store(s.running, Ordering::Release);
                        last_call = s.call;
                        break job;
                    }
                    _ => s = h.lent.wait(s).unwrap_or_else(|e| e.into_inner()),
                }
            }
        };
        // SAFETY: the caller lent this closure and waits until `running` falls to 0 before its
        // borrow ends (see `run_beside`).
        let outcome = catch_unwind(AssertUnwindSafe(|| unsafe { (*job.0)() }));
        let mut s = lock(&h.state);
        if let Err(p) = outcome {
            s.panic.get_or_insert(p);
        }
        s.running -= 1;
        h.active.store(s.running, Ordering::Release);
        if s.running == 0 {
            h.finished.notify_all();
        }
    }
}

/// The cores this process may use (at least 1), asked once: the standard library reads the
/// cgroup's quota files at each call.
pub(crate) fn cores() -> usize {
    static CORES: OnceLock<usize> = OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// Runs `work` on the calling thread and on `extra` more threads at once, and returns when every one
/// of those runs has returned (a panic in any is resumed here). `work` shares its work out itself
/// (each run takes what is left): a helper that starts late may find nothing to do.
pub(crate) fn run_beside(extra: usize, work: &(dyn Fn() + Sync)) {
    if extra == 0 {
        return work();
    }
    let h = helpers();
    // A call that panicked left the lock poisoned and the helpers idle: they serve again.
    let busy = match h.busy.try_lock() {
        Ok(guard) => Some(guard),
        Err(std::sync::TryLockError::Poisoned(e)) => Some(e.into_inner()),
        Err(std::sync::TryLockError::WouldBlock) => None,
    };
    let Some(_busy) = busy else {
        // Another call has the helpers: threads of this call's own.
        return std::thread::scope(|scope| {
            let spawned: Vec<_> = (0..extra).map(|_| scope.spawn(work)).collect();
            let mut panic = catch_unwind(AssertUnwindSafe(work)).err();
            for t in spawned {
                if let Err(p) = t.join() {
                    panic.get_or_insert(p);
                }
            }
            if let Some(p) = panic {
                resume_unwind(p);
            }
        });
    };
    // SAFETY: only the lifetime is erased; the closure is called by helpers only until `running`
    // falls to 0 with `job` cleared, which this function waits for before it returns (or unwinds).
    let lent = Lent(unsafe {
        std::mem::transmute::<*const (dyn Fn() + Sync + '_), *const (dyn Fn() + Sync + 'static)>(
            work as *const (dyn Fn() + Sync),
        )
    });
    {
        let mut s = lock(&h.state);
        while s.threads < extra {
            s.threads += 1;
            std::thread::Builder::new()
                .name("rtconf-helper".into())
                .spawn(move || helper_loop(h))
                .expect("a helper thread starts");
        }
        s.job = Some(lent);
        s.call = s.call.wrapping_add(1);
        s.wanted = extra;
        s.panic = None;
        h.posted.store(s.call, Ordering::Release);
        h.lent.notify_all();
    }
    let own = catch_unwind(AssertUnwindSafe(work));
    let helper_panic = {
        let mut s = lock(&h.state);
        // Helpers not started by now are not needed: `work` found nothing left for them.
        s.job = None;
        s.wanted = 0;
        if s.running > 0 {
            drop(s);
            spin_until(JOIN_AWAKE, || h.active.load(Ordering::Acquire) == 0);
            s = lock(&h.state);
        }
        while s.running > 0 {
            s = h.finished.wait(s).unwrap_or_else(|e| e.into_inner());
        }
        s.panic.take()
    };
    if let Err(p) = own {
        resume_unwind(p);
    }
    if let Some(p) = helper_panic {
        resume_unwind(p);
    }
}

#[cfg(test)]
mod tests {
    use super::run_beside;
    use std::panic::AssertUnwindSafe;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;

    /// Every item is taken once, whoever takes it, and the call returns only after all are done.
    #[test]
    fn the_work_is_shared_and_finished_before_the_call_returns() {
        for extra in [0, 1, 3] {
            for _ in 0..50 {
                let next = AtomicUsize::new(0);
                let done: Vec<AtomicUsize> = (0..200).map(|_| AtomicUsize::new(0)).collect();
                run_beside(extra, &|| loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= done.len() {
                        break;
                    }
                    done[i].fetch_add(1, Ordering::Relaxed);
                });
                assert!(done.iter().all(|d| d.load(Ordering::Relaxed) == 1));
            }
        }
    }

    /// Two callers at once both finish (the second runs on threads of its own), with every item done.
    #[test]
    fn concurrent_callers_do_not_wait_for_each_other() {
        let totals = Mutex::new(Vec::new());
        std::thread::scope(|scope| {
            for _ in 0..4 {
                scope.spawn(|| {
                    let count = AtomicUsize::new(0);
                    let next = AtomicUsize::new(0);
                    run_beside(1, &|| {
                        while next.fetch_add(1, Ordering::Relaxed) < 1000 {
                            count.fetch_add(1, Ordering::Relaxed);
                        }
                    });
                    totals.lock().unwrap().push(count.into_inner());
                });
            }
        });
        assert_eq!(totals.into_inner().unwrap(), vec![1000; 4]);
    }

    /// A helper's panic reaches the caller, and the helpers serve the next call.
    #[test]
    fn a_panic_in_a_helper_is_resumed_in_the_caller() {
        use std::sync::atomic::AtomicBool;
        let caller = std::thread::current().id();
        let helper_ran = AtomicBool::new(false);
        let r = std::panic::catch_unwind(AssertUnwindSafe(|| {
            run_beside(1, &|| {
                if std::thread::current().id() != caller {
                    helper_ran.store(true, Ordering::SeqCst);
                    panic!("planted");
                }
                // The caller's share lasts until the helper has run (or long past any start).
                let start = std::time::Instant::now();
                while !helper_ran.load(Ordering::SeqCst) && start.elapsed().as_secs() < 10 {
                    std::thread::yield_now();
                }
            })
        }));
        assert!(helper_ran.load(Ordering::SeqCst), "the helper never ran");
        let p = r.expect_err("the helper's panic is resumed in the caller");
        assert_eq!(p.downcast_ref::<&str>(), Some(&"planted"));
        let n = AtomicUsize::new(0);
        run_beside(1, &|| {
            n.fetch_add(1, Ordering::Relaxed);
        });
        assert!(n.load(Ordering::Relaxed) >= 1);
    }
}
