//! Tasks shared between the calling thread and rayon's pool, the caller working from the start.
//!
//! `par_chunks` called from a thread outside the pool (Python's thread, through the bindings)
//! injects the work into the pool and puts the caller to sleep until the pool's threads have
//! woken up, done the work and woken the caller again: two wake-ups per call. On a virtual
//! machine a wake-up can take hundreds of microseconds (measured on the 2-vCPU machine of the
//! benchmarks: 10,000 impact frequencies took 650 µs on 2 threads after the caller had slept,
//! as long as on one thread, against 400 µs back to back). [`for_each_task`] lets the caller
//! take tasks from a shared counter at once, and the pool's threads join when they wake: at worst
//! the caller does all the work itself, at the speed of one thread, and it never waits for a
//! thread that has not started a task. Each task index is handed out exactly once, so tasks that
//! write disjoint parts of the outputs ([`Disjoint`]) give the results of a serial loop.

use std::marker::PhantomData;
use std::any::Any;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The counters a call shares with the jobs it spawns; the jobs own them (a job that starts after
/// the call has returned finds no task left and touches nothing else).
struct Counters {
    next: AtomicUsize,
    done: AtomicUsize,
    /// the first panic of a task, raised again in the caller
    panic: Mutex<Option<Box<dyn Any + Send>>>,
}

/// A pointer to the call's task closure, lifetime erased. Dereferenced only by a thread that has
/// claimed a task index below the count, and the call returns only after every claimed task is
/// done, so it is never used after the closure is gone.
#[derive(Clone, Copy)]
struct TaskRef(*const (dyn Fn(usize) + Sync));

// SAFETY: the closure is Sync, and the pointer's use is bounded as described above.
unsafe impl Send for TaskRef {}

/// Run `task(i)` for every i in 0..n, each exactly once, on the calling thread and on up to
/// (pool size - 1) threads of the current rayon pool (so at most the pool's size works at once;
/// RAYON_NUM_THREADS=1 runs everything on the caller). Called from a thread of a pool, it is
/// rayon's own parallel loop. A panic in a task is raised again in the caller (with its message)
/// after every claimed task has finished.
pub fn for_each_task<F: Fn(usize) + Sync>(n: usize, task: F) {
    if n == 0 {
        return;
    }
    let helpers = rayon::current_num_threads().saturating_sub(1).min(n - 1);
    if helpers == 0 {
        (0..n).for_each(task);
        return;
    }
    if rayon::current_thread_index().is_some() {
        use rayon::prelude::*;
        (0..n).into_par_iter().for_each(&task);
        return;
    }
    CALLS.fetch_add(1, Ordering::Release);
    let counters = Arc::new(Counters { next: AtomicUsize::new(0), done: AtomicUsize::new(0), panic: Mutex::new(None) });
    let dyn_task: &(dyn Fn(usize) + Sync) = &task;
    // SAFETY (lifetime erasure): see TaskRef; the wait below outlives every dereference.
    let task_ref = TaskRef(unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), &'static (dyn Fn(usize) + Sync)>(dyn_task) });
    let work = move |c: &Counters, t: TaskRef| loop {
        let i = c.next.fetch_add(1, Ordering::Relaxed);
        if i >= n {
            break;
        }
        // SAFETY: i < n was claimed, so the call is still waiting for this task (see TaskRef).
        let f = unsafe { &*t.0 };
        if let Err(payload) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(i))) {
            c.panic.lock().unwrap_or_else(|p| p.into_inner()).get_or_insert(payload);
        }
        c.done.fetch_add(1, Ordering::Release);
    };
    for _ in 0..helpers {
        let c = Arc::clone(&counters);
        rayon::spawn(move || work(&c, task_ref));
    }
    work(&counters, task_ref);
    // every index is claimed: wait for the tasks still running on other threads (each is one
    // task long; no thread is woken for this)
    let mut spins = 0u32;
    while counters.done.load(Ordering::Acquire) < n {
        if spins < 1 << 14 {
            std::hint::spin_loop();
            spins += 1;
        } else {
            std::thread::yield_now();
        }
    }
    let first_panic = counters.panic.lock().unwrap_or_else(|p| p.into_inner()).take();
    if let Some(payload) = first_panic {
        std::panic::resume_unwind(payload);
    }
}

/// Parallel calls begun from outside the pool (see [`wake_helpers`]).
static CALLS: AtomicUsize = AtomicUsize::new(0);
/// Set while helper threads are held awake by [`wake_helpers`].
static AWAKE: AtomicBool = AtomicBool::new(false);

/// Wake the pool's threads ahead of a parallel call, so that they are running when the call's
/// tasks arrive instead of being woken by them.
///
/// A caller that has work of its own to do before its parallel call (the Python API validates
/// its inputs for ~50 µs before the core call) calls this first: each helper thread is woken now,
/// while the caller works, and spins until the next [`for_each_task`] from outside the pool begins
/// or `max_wait` has passed, then takes that call's tasks at once. Without it, the first tasks of
/// a call after an idle pause wait for the wake-up of a sleeping thread (tens to hundreds of
/// microseconds on a virtual machine), and a short call runs mostly on the caller alone.
/// At most one set of helpers is held awake at a time; nothing happens on a one-thread pool or
/// from inside a pool. The cost when no call follows is `max_wait` of CPU time per helper.
pub fn wake_helpers(max_wait: std::time::Duration) {
    let helpers = rayon::current_num_threads().saturating_sub(1);
    if helpers == 0 || rayon::current_thread_index().is_some() || AWAKE.swap(true, Ordering::AcqRel) {
        return;
    }
    let calls = CALLS.load(Ordering::Acquire);
    let waiting = Arc::new(AtomicUsize::new(helpers));
    for _ in 0..helpers {
        let waiting = Arc::clone(&waiting);
        rayon::spawn(move || {
            let start = std::time::Instant::now();
            let mut spins = 0u32;
            while CALLS.load(Ordering::Acquire) == calls {
                std::hint::spin_loop();
                spins = spins.wrapping_add(1);
                if spins % 256 == 0 && start.elapsed() >= max_wait {
                    break;
                }
            }
            if waiting.fetch_sub(1, Ordering::AcqRel) == 1 {
                AWAKE.store(false, Ordering::Release);
            }
        });
    }
}

/// `task(i)` for every i in 0..n as in [`for_each_task`], and the sum of the results.
pub fn sum_tasks<F: Fn(usize) -> usize + Sync>(n: usize, task: F) -> usize {
    let total = AtomicUsize::new(0);
    for_each_task(n, |i| {
        total.fetch_add(task(i), Ordering::Relaxed);
    });
    total.into_inner()
}

/// A mutable slice handed out in disjoint chunks to the tasks of [`for_each_task`].
pub struct Disjoint<'a, T> {
    ptr: *mut T,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

// SAFETY: chunks of distinct task indices do not overlap (the caller of `chunk` guarantees that
// each index is used by one task), so sharing the pointer is sharing `&mut` to disjoint parts.
unsafe impl<T: Send> Send for Disjoint<'_, T> {}
unsafe impl<T: Send> Sync for Disjoint<'_, T> {}

impl<'a, T> Disjoint<'a, T> {
    pub fn new(s: &'a mut [T]) -> Self {
        Disjoint { ptr: s.as_mut_ptr(), len: s.len(), _slice: PhantomData }
    }

    /// Chunk `j` of `size` elements (the last one shorter), as `chunks_mut(size).nth(j)` would
    /// give it; empty past the end.
    ///
    /// # Safety
    /// No two live chunks may overlap: call it for a given (j, size) from one task only, as
    /// [`for_each_task`] hands each index to one task.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn chunk(&self, j: usize, size: usize) -> &'a mut [T] {
        let start = j.saturating_mul(size).min(self.len);
        let end = start.saturating_add(size).min(self.len);
        // SAFETY: in bounds, and disjoint by the contract above
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(start), end - start) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_task_runs_once_from_outside_and_inside_a_pool() {
        for n in [0usize, 1, 2, 3, 17, 1000] {
            let hits: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
            for_each_task(n, |i| {
                hits[i].fetch_add(1, Ordering::Relaxed);
            });
            assert!(hits.iter().all(|h| h.load(Ordering::Relaxed) == 1), "n = {n}");
            let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
            let total = pool.install(|| sum_tasks(n, |i| i));
            assert_eq!(total, n * n.saturating_sub(1) / 2);
        }
    }

    #[test]
    fn woken_helpers_end_their_wait_at_the_next_call_or_by_themselves() {
        use std::time::{Duration, Instant};
        let until_asleep = |limit: Duration| {
            let t = Instant::now();
            while AWAKE.load(Ordering::Acquire) {
                assert!(t.elapsed() < limit, "helpers still held awake after {limit:?}");
                std::thread::sleep(Duration::from_micros(100));
            }
        };
        // a call after the wake: every task once, and the helpers let go
        wake_helpers(Duration::from_secs(5));
        let hits: Vec<AtomicUsize> = (0..500).map(|_| AtomicUsize::new(0)).collect();
        for_each_task(hits.len(), |i| {
            hits[i].fetch_add(1, Ordering::Relaxed);
        });
        assert!(hits.iter().all(|h| h.load(Ordering::Relaxed) == 1));
        until_asleep(Duration::from_secs(2));
        // no call: the wait ends by itself after max_wait
        wake_helpers(Duration::from_millis(1));
        until_asleep(Duration::from_secs(2));
        // from inside a pool it does nothing (the pool's own threads are running)
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        pool.install(|| wake_helpers(Duration::from_secs(5)));
        assert!(!AWAKE.load(Ordering::Acquire));
    }

    #[test]
    fn disjoint_chunks_are_those_of_chunks_mut() {
        let mut v: Vec<usize> = vec![0; 1003];
        let d = Disjoint::new(&mut v);
        let size = 100;
        for_each_task(11, |j| {
            // SAFETY: one task per j
            for (k, x) in unsafe { d.chunk(j, size) }.iter_mut().enumerate() {
                *x = j * size + k;
            }
        });
        assert!(v.iter().enumerate().all(|(i, &x)| x == i));
        // SAFETY: nothing else holds a chunk
        assert!(unsafe { Disjoint::new(&mut v).chunk(11, size) }.is_empty());
    }

    #[test]
    fn a_panicking_task_panics_in_the_caller_after_the_others() {
        let done = AtomicUsize::new(0);
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            for_each_task(50, |i| {
                if i == 7 {
                    panic!("task 7");
                }
                done.fetch_add(1, Ordering::Relaxed);
            })
        }));
        let payload = r.unwrap_err();
        assert_eq!(payload.downcast_ref::<&str>(), Some(&"task 7"));
        assert_eq!(done.load(Ordering::Relaxed), 49);
    }
}
