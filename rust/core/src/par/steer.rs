//! Keeping a woken helper off its caller's CPU (Linux).
//!
//! When a thread that is running wakes a sleeping one, Linux places the wakee on the waker's CPU
//! unless it finds an idle CPU it may use. On the 2-vCPU virtual machine of the benchmarks it
//! found none though the other vCPU was idle (likely because a guest counts a halted vCPU as
//! preempted, not idle: `available_idle_cpu` asks `vcpu_is_preempted`): the woken helper was
//! queued behind its caller, busy with the call's tasks. Measured there (`perf sched timehist -w
//! -M`, 100,000-speed identifications 30 ms apart): the helper was migrated onto the caller's CPU
//! and waited 3.9 ms, so the call took 5.8-6.2 ms on one CPU instead of 3.2 ms on two, in 8 of
//! 12 calls.
//!
//! [`away_from_caller`] narrows the CPU masks of the pool's threads to their CPUs other than the
//! caller's before a call (or a wake) spawns helper jobs, so a woken helper can only start
//! elsewhere; the last of those jobs to start gives the masks back at once ([`job_started`]), as
//! they matter only where a woken thread is placed (rayon's own loops, started from outside the
//! pool, need every CPU), and the call's end does it too should a job not have started
//! ([`restore`]). Both are hints: an error (a cpuset that changed, a thread gone) leaves the
//! masks as they are, and the results never depend on where a task runs. Masks are never
//! narrowed to nothing (a process allowed one CPU is left alone), never touched in a forked
//! child (whose pool threads are not those recorded), not touched for pools of more than
//! [`MAX_STEERED_THREADS`] threads (one system call per thread each way), and not at all with
//! `ROTORID_STEER=0`.

#[cfg(target_os = "linux")]
use std::sync::Mutex;
use std::sync::OnceLock;

/// A thread of the global pool: its kernel thread id and the CPU mask to give back (its own,
/// read when it registered and again before each narrowing from whole masks).
#[cfg(target_os = "linux")]
struct PoolThread {
    tid: libc::pid_t,
    mask: libc::cpu_set_t,
}

#[cfg(target_os = "linux")]
struct Pool {
    threads: Vec<PoolThread>,
    /// the CPU the masks exclude now, if any
    excluded: Option<usize>,
    /// the CPU the last narrowing excluded (kept after the restore; for tests)
    last: Option<usize>,
}

/// Helper jobs spawned after the last narrowing that have not started yet: the last to start
/// gives the masks back ([`job_started`]).
#[cfg(target_os = "linux")]
static PENDING: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// The largest pool steered: each narrowing and restore is one system call per pool thread
/// (~1 µs), and the queueing it avoids was measured on 2 vCPUs.
pub const MAX_STEERED_THREADS: usize = 8;

/// The process that recorded the threads (a forked child has none of them; it never takes the
/// lock, which a parent's thread may have held when it forked) and the threads.
#[cfg(target_os = "linux")]
static POOL: OnceLock<Option<(libc::pid_t, Mutex<Pool>)>> = OnceLock::new();

/// [`POOL`]'s threads, in the process that recorded them (else None: not set, steering off, or
/// a forked child).
#[cfg(target_os = "linux")]
fn ours() -> Option<&'static Mutex<Pool>> {
    let (pid, pool) = POOL.get()?.as_ref()?;
    // SAFETY: getpid has no preconditions
    (*pid == unsafe { libc::getpid() }).then_some(pool)
}

/// Whether helpers are steered away from their caller's CPU: on Linux with `ROTORID_STEER` unset,
/// empty or 1 (the default), not with 0 ([`steer_from_env`]; a value it refuses falls back to the default
/// here, the Python bindings refuse it when they load).
pub fn steering() -> bool {
    *STEERING.get_or_init(|| cfg!(target_os = "linux") && steer_from_env().ok().flatten().unwrap_or(true))
}

static STEERING: OnceLock<bool> = OnceLock::new();

/// The steering `ROTORID_STEER` asks for: None when unset or empty, an error for anything but 0
/// or 1.
pub fn steer_from_env() -> Result<Option<bool>, crate::error::CoreError> {
    match std::env::var("ROTORID_STEER") {
        Err(_) => Ok(None),
        Ok(v) if v.trim().is_empty() => Ok(None),
        Ok(v) => match v.trim() {
            "0" => Ok(Some(false)),
            "1" => Ok(Some(true)),
            _ => Err(crate::error::CoreError::value("ROTORID_STEER", format!("must be 0 or 1 (or unset), got {v:?}"))),
        },
    }
}

/// The global pool's threads, recorded by each thread as it runs a job broadcast (without waiting
/// for it) the first time a call from outside the pool asks for steering: that call and those
/// made before the threads have run it are not steered. Nothing waits on the pool here, so a
/// forked child, whose global pool has no threads, neither hangs nor steers (its process id is
/// not the one recorded). None where steering is off.
#[cfg(target_os = "linux")]
fn pool() -> Option<&'static Mutex<Pool>> {
    POOL.get_or_init(|| {
        // SAFETY: getpid has no preconditions
        (steering() && rayon::current_num_threads() <= MAX_STEERED_THREADS)
            .then(|| (unsafe { libc::getpid() }, Mutex::new(Pool { threads: Vec::new(), excluded: None, last: None })))
    });
    let pool = ours()?;
    // after POOL is set, which the threads' registrations look up
    BROADCAST.call_once(|| rayon::spawn_broadcast(register));
    Some(pool)
}

#[cfg(target_os = "linux")]
static BROADCAST: std::sync::Once = std::sync::Once::new();

/// Record the calling pool thread (its id and CPU mask) in [`POOL`].
#[cfg(target_os = "linux")]
fn register(_: rayon::BroadcastContext<'_>) {
    // SAFETY: plain system calls on this thread, into a zeroed cpu_set_t of its own; the
    // system call, not glibc's gettid (2.30): the wheel links against glibc 2.17
    let me = unsafe {
        let mut mask: libc::cpu_set_t = std::mem::zeroed();
        let ok = libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut mask) == 0;
        ok.then(|| PoolThread { tid: libc::syscall(libc::SYS_gettid) as libc::pid_t, mask })
    };
    if let (Some(me), Some(pool)) = (me, ours()) {
        pool.lock().unwrap_or_else(|e| e.into_inner()).threads.push(me);
    }
}

/// Narrow the pool threads' CPU masks to exclude the calling thread's CPU before `jobs` helper
/// jobs are spawned (see the module documentation); each job calls [`job_started`] first, and
/// the last of them gives the masks back: they matter only where a woken thread is placed. A
/// no-op from inside a pool, for `jobs` = 0, or where a thread would be left no CPU; the masks
/// are narrowed from the threads' current ones (a `taskset` since is kept).
pub fn away_from_caller(jobs: usize) {
    #[cfg(target_os = "linux")]
    {
        if jobs == 0 || rayon::current_thread_index().is_some() {
            return;
        }
        let Some(pool) = pool() else { return };
        // SAFETY: sched_getcpu has no preconditions
        let cpu = unsafe { libc::sched_getcpu() };
        let Ok(cpu) = usize::try_from(cpu) else { return };
        if cpu >= libc::CPU_SETSIZE as usize {
            return;
        }
        let mut p = pool.lock().unwrap_or_else(|e| e.into_inner());
        if p.excluded == Some(cpu) {
            PENDING.fetch_add(jobs, std::sync::atomic::Ordering::SeqCst);
            return;
        }
        let size = std::mem::size_of::<libc::cpu_set_t>();
        let mut narrowed = false;
        let refresh = p.excluded.is_none();
        for t in p.threads.iter_mut() {
            // SAFETY: zeroed cpu_set_t values filled by the system call; cpu < CPU_SETSIZE
            unsafe {
                if refresh {
                    // the thread's mask now, to give back later
                    let mut now: libc::cpu_set_t = std::mem::zeroed();
                    if libc::sched_getaffinity(t.tid, size, &mut now) == 0 {
                        t.mask = now;
                    }
                }
                let mut mask = t.mask;
                libc::CPU_CLR(cpu, &mut mask);
                if libc::CPU_COUNT(&mask) > 0 && libc::sched_setaffinity(t.tid, size, &mask) == 0 {
                    narrowed = true;
                }
            }
        }
        if narrowed {
            p.excluded = Some(cpu);
            p.last = Some(cpu);
            PENDING.store(jobs, std::sync::atomic::Ordering::SeqCst);
        }
    }
}

/// Called by a helper job spawned after [`away_from_caller`] as it starts: the last one of them
/// gives the masks back.
pub fn job_started() {
    #[cfg(target_os = "linux")]
    {
        use std::sync::atomic::Ordering;
        let left = PENDING.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1));
        if left == Ok(1) {
            restore();
        }
    }
}

/// Give the pool's threads back the CPU masks they had before [`away_from_caller`] narrowed
/// them (a backstop: the last helper job to start does it, or else the call that woke them).
pub fn restore() {
    #[cfg(target_os = "linux")]
    {
        let Some(pool) = ours() else { return };
        let mut p = pool.lock().unwrap_or_else(|e| e.into_inner());
        if p.excluded.is_none() {
            return;
        }
        for t in &p.threads {
            // SAFETY: the thread's own mask, read by sched_getaffinity
            unsafe {
                libc::sched_setaffinity(t.tid, std::mem::size_of::<libc::cpu_set_t>(), &t.mask);
            }
        }
        p.excluded = None;
        PENDING.store(0, std::sync::atomic::Ordering::SeqCst);
    }
}

/// Whether every recorded pool thread's CPU mask leaves out `cpu` now (for tests).
pub fn masks_exclude(cpu: usize) -> bool {
    #[cfg(target_os = "linux")]
    if let Some(pool) = ours() {
        let p = pool.lock().unwrap_or_else(|e| e.into_inner());
        return !p.threads.is_empty()
            && p.threads.iter().all(|t| {
                // SAFETY: a zeroed cpu_set_t filled by the system call; CPU_ISSET checks its index
                unsafe {
                    let mut now: libc::cpu_set_t = std::mem::zeroed();
                    libc::sched_getaffinity(t.tid, std::mem::size_of::<libc::cpu_set_t>(), &mut now) == 0
                        && !libc::CPU_ISSET(cpu, &now)
                }
            });
    }
    let _ = cpu;
    false
}

/// Whether every recorded pool thread has the CPU mask it started with now (for tests; true
/// where nothing is recorded).
pub fn masks_as_recorded() -> bool {
    #[cfg(target_os = "linux")]
    if let Some(pool) = ours() {
        let p = pool.lock().unwrap_or_else(|e| e.into_inner());
        return p.threads.iter().all(|t| {
            // SAFETY: a zeroed cpu_set_t filled by the system call
            unsafe {
                let mut now: libc::cpu_set_t = std::mem::zeroed();
                libc::sched_getaffinity(t.tid, std::mem::size_of::<libc::cpu_set_t>(), &mut now) == 0
                    && libc::CPU_EQUAL(&now, &t.mask)
            }
        });
    }
    true
}

/// The CPU masks' state for tests: (pool threads recorded, the CPU they exclude now, the CPU
/// the last narrowing excluded).
pub fn state() -> (usize, Option<usize>, Option<usize>) {
    #[cfg(target_os = "linux")]
    if let Some(pool) = ours() {
        let p = pool.lock().unwrap_or_else(|e| e.into_inner());
        return (p.threads.len(), p.excluded, p.last);
    }
    (0, None, None)
}
