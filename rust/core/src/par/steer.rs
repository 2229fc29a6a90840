//! Keeping a woken helper off its caller's CPU (Linux).
//!
//! When a thread that is running wakes a sleeping one, Linux places the wakee on the waker's CPU
//! unless it finds an idle CPU it may use. On a virtual machine an idle vCPU is halted, and the
//! guest's scheduler counts a halted vCPU as preempted, not idle (`available_idle_cpu` asks
//! `vcpu_is_preempted`): the woken helper is queued behind its caller, which is busy with the
//! call's tasks, while the other vCPU stays idle. Measured on the 2-vCPU virtual machine of the
//! benchmarks (`perf sched timehist -w -M`, 100,000-speed identifications 30 ms apart): the
//! helper was migrated onto the caller's CPU and waited 3.9 ms there, so the call took 5.8-6.2 ms
//! on one CPU instead of 3.2 ms on two, in 8 of 12 calls.
//!
//! [`away_from_caller`] narrows the CPU masks of the pool's threads to the process's CPUs other
//! than the caller's before a call wakes them, so a woken helper can only start elsewhere, and
//! [`restore`] gives them back their own masks after the call (rayon's own loops, started from
//! outside the pool, need every CPU). Both are hints: an error (a cpuset that changed, a thread
//! gone) leaves the masks as they are, and the results never depend on where a task runs. Masks
//! are never narrowed to nothing (a process allowed one CPU is left alone), never touched in a
//! forked child (whose pool threads are not those recorded), and not touched at all with
//! `ROTORID_STEER=0`.

#[cfg(target_os = "linux")]
use std::sync::Mutex;
use std::sync::OnceLock;

/// A thread of the global pool: its kernel thread id and the CPU mask it started with.
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
}

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
        steering().then(|| (unsafe { libc::getpid() }, Mutex::new(Pool { threads: Vec::new(), excluded: None })))
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

/// Narrow the pool threads' CPU masks to exclude the calling thread's CPU (see the module
/// documentation); a no-op from inside a pool, when the masks already exclude it, or where a
/// thread would be left no CPU.
pub fn away_from_caller() {
    #[cfg(target_os = "linux")]
    {
        if rayon::current_thread_index().is_some() {
            return;
        }
        let Some(pool) = pool() else { return };
        // SAFETY: sched_getcpu has no preconditions
        let cpu = unsafe { libc::sched_getcpu() };
        let Ok(cpu) = usize::try_from(cpu) else { return };
        let mut p = pool.lock().unwrap_or_else(|e| e.into_inner());
        if p.excluded == Some(cpu) || cpu >= libc::CPU_SETSIZE as usize {
            return;
        }
        for t in &p.threads {
            let mut mask = t.mask;
            // SAFETY: cpu < CPU_SETSIZE; the masks are the threads' own, read by sched_getaffinity
            unsafe {
                libc::CPU_CLR(cpu, &mut mask);
                if libc::CPU_COUNT(&mask) > 0 {
                    libc::sched_setaffinity(t.tid, std::mem::size_of::<libc::cpu_set_t>(), &mask);
                }
            }
        }
        p.excluded = Some(cpu);
    }
}

/// Give the pool's threads back the CPU masks they started with, if [`away_from_caller`]
/// narrowed them.
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
    }
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

/// The CPU masks' state for tests: (pool threads recorded, the CPU they exclude now).
pub fn state() -> (usize, Option<usize>) {
    #[cfg(target_os = "linux")]
    if let Some(pool) = ours() {
        let p = pool.lock().unwrap_or_else(|e| e.into_inner());
        return (p.threads.len(), p.excluded);
    }
    (0, None)
}
