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
//!
//! Between calls the pool's threads spin for [`spin_time`] (`ROTORID_SPIN_US`, 200 µs by
//! default) before they sleep, and join the next call from outside the pool through an offer
//! they watch, without a job queued for them: a loop of short calls with a little Python between
//! them (a loop of API calls) then pays no wake-up per call. Waking a sleeping thread costs the
//! caller itself ~38 µs on the 2-vCPU virtual machine of the benchmarks (a futex wake).

pub mod steer;

use std::marker::PhantomData;
use std::any::Any;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// The counters a call shares with the jobs it spawns; the jobs own them (a job that starts after
/// the call has returned finds no task left and touches nothing else).
struct Counters {
    /// the number of tasks
    n: usize,
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

/// Claim and run tasks of a call until none is left (the caller's loop and every helper's).
fn work(c: &Counters, t: TaskRef) {
    loop {
        let i = c.next.fetch_add(1, Ordering::Relaxed);
        if i >= c.n {
            break;
        }
        // SAFETY: i < n was claimed, so the call is still waiting for this task (see TaskRef).
        let f = unsafe { &*t.0 };
        if let Err(payload) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(i))) {
            let mut first = c.panic.lock().unwrap_or_else(|p| p.into_inner());
            if first.is_none() {
                *first = Some(payload);
            } else {
                // kept, not dropped: a payload whose drop panics would unwind the caller out of
                // its wait while helpers still run its tasks
                std::mem::forget(payload);
            }
        }
        c.done.fetch_add(1, Ordering::Release);
    }
}

/// Run `task(i)` for every i in 0..n, each exactly once, on the calling thread and on up to
/// (pool size - 1) threads of the current rayon pool (so at most the pool's size works at once;
/// RAYON_NUM_THREADS=1 runs everything on the caller). Called from a thread of a pool, it is
/// rayon's own parallel loop. A panic in a task is raised again in the caller (with its message)
/// after every claimed task has finished.
///
/// From outside a pool the call is first offered to the helpers still spinning after an earlier
/// call (see [`spin_time`]) or woken by [`wake_helpers`]: they take its tasks without a job being
/// queued for them, so no sleeping thread is woken (a wake-up costs the caller ~38 µs on the
/// 2-vCPU virtual machine of the benchmarks). Jobs are spawned only for the helpers missing.
/// After the call, the helpers spin for [`spin_time`] in case another call follows.
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
    let counters =
        Arc::new(Counters { n, next: AtomicUsize::new(0), done: AtomicUsize::new(0), panic: Mutex::new(None) });
    let dyn_task: &(dyn Fn(usize) + Sync) = &task;
    // SAFETY (lifetime erasure): see TaskRef; the wait below outlives every dereference.
    let task_ref = TaskRef(unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), &'static (dyn Fn(usize) + Sync)>(dyn_task) });
    // the offer first, then the call count that spinning helpers watch, then the reservation of
    // the helpers missing (sequentially consistent with a helper's leaving: see `spin`): a helper
    // that leaves is either counted out there, and replaced by a job, or sees the new call and
    // takes it
    *OFFER.lock().unwrap_or_else(|p| p.into_inner()) = Some((Arc::clone(&counters), task_ref));
    let call = CALLS.fetch_add(1, Ordering::SeqCst) + 1;
    let missing = reserve_spinners(helpers);
    // a woken helper is to start on another CPU than this busy one (see steer)
    steer::away_from_caller(missing);
    for _ in 0..missing {
        let c = Arc::clone(&counters);
        rayon::spawn(move || {
            steer::job_started();
            work(&c, task_ref);
            drop(c);
            spin(call);
        });
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
    // withdrawn (unless another thread's call has replaced it): a helper arriving late finds
    // nothing (had it taken the counters, it would find every task claimed and never touch the
    // closure)
    {
        let mut offer = OFFER.lock().unwrap_or_else(|p| p.into_inner());
        if offer.as_ref().is_some_and(|(c, _)| Arc::ptr_eq(c, &counters)) {
            *offer = None;
        }
    }
    // the pool's threads may use every CPU again (rayon's own loops), should a helper job not
    // have started yet (it gives the masks back as it starts)
    steer::restore();
    // the helpers wait for the next call for the spin time from now (a longer wait asked for by
    // wake_helpers ends with this call)
    DEADLINE_NS.store(now_ns().saturating_add(nanos(spin_time())), Ordering::SeqCst);
    let first_panic = counters.panic.lock().unwrap_or_else(|p| p.into_inner()).take();
    if let Some(payload) = first_panic {
        std::panic::resume_unwind(payload);
    }
}

/// Parallel calls begun from outside the pool.
static CALLS: AtomicUsize = AtomicUsize::new(0);
/// The tasks of the call in progress from outside the pool, for spinning helpers to join.
#[allow(clippy::type_complexity)]
static OFFER: Mutex<Option<(Arc<Counters>, TaskRef)>> = Mutex::new(None);
/// Helper jobs spinning (or about to), ready to join the next call from outside the pool.
static SPINNING: AtomicUsize = AtomicUsize::new(0);
/// Nanoseconds after [`EPOCH`] at which spinning helpers return to the pool (and sleep).
static DEADLINE_NS: AtomicU64 = AtomicU64::new(0);
static EPOCH: OnceLock<Instant> = OnceLock::new();

fn now_ns() -> u64 {
    EPOCH.get_or_init(Instant::now).elapsed().as_nanos() as u64
}

/// `d` in nanoseconds, saturated.
fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// Reserve places for the helper jobs missing to make `helpers` spinning (or about to), in one
/// step (sequentially consistent with a helper's leaving: see [`spin`]), so that calls and wakes
/// from several threads at once never hold more than `helpers` between them; returns how many
/// jobs the caller is to spawn.
fn reserve_spinners(helpers: usize) -> usize {
    let mut spinning = SPINNING.load(Ordering::SeqCst);
    loop {
        let want = helpers.saturating_sub(spinning);
        if want == 0 {
            return 0;
        }
        match SPINNING.compare_exchange(spinning, spinning + want, Ordering::SeqCst, Ordering::SeqCst) {
            Ok(_) => return want,
            Err(now) => spinning = now,
        }
    }
}

/// A helper's wait for the next call from outside the pool: it joins every call made while it
/// spins, and returns to the pool once [`DEADLINE_NS`] has passed with no call.
/// `seen`: the last call it has taken part in (or knew of when it began).
fn spin(mut seen: usize) {
    let spin_ns = nanos(spin_time());
    let born = now_ns();
    // the spin time after the helper's own last task, whatever the deadline it finds: the caller
    // publishes the new deadline only after its wait, which a helper finishing first would miss
    let mut floor = born.saturating_add(spin_ns);
    let mut spins = 0u32;
    loop {
        let call = CALLS.load(Ordering::SeqCst);
        if call != seen {
            seen = call;
            join_offer();
            floor = now_ns().saturating_add(spin_ns);
            continue;
        }
        std::hint::spin_loop();
        spins = spins.wrapping_add(1);
        if !spins.is_multiple_of(256) {
            continue;
        }
        let now = now_ns();
        if (now >= floor && now >= DEADLINE_NS.load(Ordering::SeqCst)) || now.saturating_sub(born) >= MAX_SPIN_NS {
            SPINNING.fetch_sub(1, Ordering::SeqCst);
            // a call that counted this helper just before it left: take part after all (if the
            // call saw it leave, a job of its own covers the helper as well: harmless)
            if CALLS.load(Ordering::SeqCst) != seen {
                join_offer();
            }
            return;
        }
    }
}

/// The longest a helper job spins, calls or not (the next call spawns a fresh one): a helper
/// spinning for calls made from one thread never keeps the pool's thread from other work
/// (rayon's own loops, started from another thread) for longer than this. Also the longest
/// spin time and wait that [`spin_time_from_env`] and the bindings accept.
pub const MAX_SPIN: Duration = Duration::from_millis(50);
const MAX_SPIN_NS: u64 = MAX_SPIN.as_nanos() as u64;

/// Take part in the call on offer, if there is one.
fn join_offer() {
    let offer = OFFER.lock().unwrap_or_else(|p| p.into_inner()).clone();
    if let Some((c, t)) = offer {
        work(&c, t);
    }
}

/// How long the pool's helper threads keep spinning after a parallel call, ready for the next:
/// `ROTORID_SPIN_US` microseconds ([`spin_time_from_env`]), 200 µs by default. A short call
/// followed by another (a loop of API calls, each with ~50 µs of Python between them) then finds
/// its helpers running instead of asleep. The cost is that much CPU time of each helper after a
/// call that no other call follows; 0 turns it off (helpers then sleep right after a call). A
/// rayon loop started from outside the pool meanwhile (modal analysis, the studies) finds the
/// spinning helpers busy until their deadline and starts on the pool's other threads. Read
/// once; a value [`spin_time_from_env`] refuses falls back to the default here (the Python
/// bindings refuse it when they load).
pub fn spin_time() -> Duration {
    *SPIN_TIME.get_or_init(|| spin_time_from_env().ok().flatten().unwrap_or(DEFAULT_SPIN))
}

static SPIN_TIME: OnceLock<Duration> = OnceLock::new();
/// The default of [`spin_time`].
pub const DEFAULT_SPIN: Duration = Duration::from_micros(200);

/// The spin time `ROTORID_SPIN_US` asks for: None when unset or empty, an error for anything but
/// a number of microseconds within 0 and 50,000 ([`MAX_SPIN`]).
pub fn spin_time_from_env() -> Result<Option<Duration>, crate::error::CoreError> {
    match std::env::var("ROTORID_SPIN_US") {
        Err(_) => Ok(None),
        Ok(v) if v.trim().is_empty() => Ok(None),
        Ok(v) => match v.trim().parse::<f64>() {
            Ok(us) if (0.0..=MAX_SPIN.as_secs_f64() * 1e6).contains(&us) => Ok(Some(Duration::from_secs_f64(us * 1e-6))),
            _ => Err(crate::error::CoreError::value(
                "ROTORID_SPIN_US",
                format!("must be a number of microseconds within 0 and 50000 (or unset), got {v:?}"),
            )),
        },
    }
}

/// Wake the pool's threads ahead of a parallel call, so that they are running when the call's
/// tasks arrive instead of being woken by them.
///
/// A caller that has work of its own to do before its parallel call (the Python API validates
/// its inputs for ~50 µs before the core call) calls this first: each helper thread not already
/// spinning is woken now, while the caller works, and spins until `max_wait` has passed (at most
/// 50 ms; a call made meanwhile ends the wait [`spin_time`] after it), taking part in every
/// [`for_each_task`] from outside the pool made meanwhile. Without it, the first tasks of a call
/// after an idle pause wait for the wake-up of a sleeping thread (tens to hundreds of
/// microseconds on a virtual machine), and a short call runs mostly on the caller alone. Nothing
/// happens on a one-thread pool or from inside a pool. The cost when no call follows is `max_wait` of CPU time per
/// helper.
pub fn wake_helpers(max_wait: Duration) {
    let helpers = rayon::current_num_threads().saturating_sub(1);
    if helpers == 0 || rayon::current_thread_index().is_some() {
        return;
    }
    DEADLINE_NS.fetch_max(now_ns().saturating_add(nanos(max_wait)), Ordering::SeqCst);
    let seen = CALLS.load(Ordering::SeqCst);
    // top up to one spinning job per helper thread, started on another CPU than this one (see
    // steer; the last job to start gives the threads their masks back)
    let missing = reserve_spinners(helpers);
    steer::away_from_caller(missing);
    for _ in 0..missing {
        rayon::spawn(move || {
            steer::job_started();
            spin(seen)
        });
    }
}

/// Helper jobs spinning now (or spawned to), ready for the next call from outside the pool: 0
/// once they have all gone back to sleep.
pub fn spinning_helpers() -> usize {
    SPINNING.load(Ordering::SeqCst)
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
