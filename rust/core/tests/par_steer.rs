//! `par::steer` in a process of its own (the spin time and the steering are read once per
//! process): the pool threads' CPU masks leave out the caller's CPU while a woken helper starts,
//! helpers start off that CPU, and every mask is back once the woken jobs have started, after a
//! call and after a wake alone.
#![cfg(target_os = "linux")]

use rotorid_core::par::{for_each_task, spinning_helpers, steer, wake_helpers};
use std::sync::Mutex;
use std::time::{Duration, Instant};

fn busy(us: u64) {
    let t = Instant::now();
    while t.elapsed() < Duration::from_micros(us) {
        std::hint::spin_loop();
    }
}

fn allowed_cpus() -> usize {
    // SAFETY: a zeroed cpu_set_t filled by the system call (0 CPUs if it fails)
    unsafe {
        let mut mask: libc::cpu_set_t = std::mem::zeroed();
        libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut mask);
        libc::CPU_COUNT(&mask) as usize
    }
}

fn this_cpu() -> usize {
    // SAFETY: sched_getcpu has no preconditions
    unsafe { libc::sched_getcpu() as usize }
}

/// Wait up to 2 s for `done`.
fn eventually(done: impl Fn() -> bool) -> bool {
    let t0 = Instant::now();
    while !done() && t0.elapsed() < Duration::from_secs(2) {
        std::thread::sleep(Duration::from_micros(200));
    }
    done()
}

#[test]
fn woken_helpers_start_off_the_callers_cpu_and_the_masks_come_back() {
    // the environment values first (read afresh by the parser, once by the core)
    for (v, want) in [("", None), (" 0 ", Some(false)), ("1", Some(true))] {
        std::env::set_var("ROTORID_STEER", v);
        assert_eq!(steer::steer_from_env().unwrap(), want, "{v:?}");
    }
    for bad in ["yes", "2", "-1", "on"] {
        std::env::set_var("ROTORID_STEER", bad);
        let err = steer::steer_from_env().unwrap_err().to_string();
        assert!(err.contains("ROTORID_STEER must be 0 or 1"), "{err}");
    }
    std::env::remove_var("ROTORID_STEER");
    // helpers sleep right after each call, so every call below wakes one
    std::env::set_var("ROTORID_SPIN_US", "0");
    assert!(steer::steering());
    let threads = rayon::current_num_threads();
    if allowed_cpus() < 2 || threads < 2 || threads > steer::MAX_STEERED_THREADS {
        eprintln!("one CPU, one pool thread or a pool too large to steer: nothing to steer");
        return;
    }
    // the first calls have the pool's threads record themselves
    let t0 = Instant::now();
    while steer::state().0 < threads && t0.elapsed() < Duration::from_secs(10) {
        for_each_task(8, |_| busy(20));
        std::thread::sleep(Duration::from_millis(2));
    }
    assert_eq!(steer::state().0, threads);
    assert!(eventually(steer::masks_as_recorded));

    // the narrowing itself, observed in the kernel's masks, and the giving back
    let cpu = this_cpu();
    steer::away_from_caller(1);
    let excluded = steer::state().1.expect("masks narrowed");
    assert!(steer::masks_exclude(excluded), "the kernel's masks leave out the caller's CPU");
    assert!(!steer::masks_as_recorded());
    assert!(excluded == cpu || excluded == this_cpu());
    steer::job_started(); // the one job it was narrowed for
    assert_eq!(steer::state().1, None);
    assert!(steer::masks_as_recorded(), "the last job to start gave the masks back");
    assert!(!steer::masks_exclude(excluded));

    // calls after an idle pause: every helper task runs off the CPU its call excluded
    let caller = std::thread::current().id();
    let mut helper_tasks = 0;
    for _ in 0..20 {
        std::thread::sleep(Duration::from_millis(3)); // the helpers are asleep
        let seen = Mutex::new(Vec::new());
        let before = steer::state().2;
        for_each_task(64, |_| {
            busy(50);
            if std::thread::current().id() != caller {
                seen.lock().unwrap().push(this_cpu());
            }
        });
        let (_, now, last) = steer::state();
        assert_eq!(now, None, "the masks are given back by the end of the call");
        assert!(steer::masks_as_recorded(), "every pool thread has its own CPU mask again");
        let last = last.expect("the call narrowed the masks");
        let tasks = seen.into_inner().unwrap();
        // the first task a helper took: it started while the masks excluded the caller's CPU
        if let Some(&first) = tasks.first() {
            assert_ne!(first, last, "a woken helper started on its caller's CPU (before: {before:?})");
        }
        helper_tasks += tasks.len();
    }
    assert!(helper_tasks > 0, "no woken helper took a task in 20 calls");

    // a wake that no call follows (an API call refusing its input, or rayon's own loop after it):
    // the masks come back as soon as the woken job starts, long before it stops spinning
    std::thread::sleep(Duration::from_millis(3));
    wake_helpers(Duration::from_millis(40));
    assert!(eventually(|| steer::state().1.is_none()), "the masks are given back once the woken job starts");
    assert!(steer::masks_as_recorded());
    assert!(spinning_helpers() > 0, "given back while the woken helper still spins, not when it stops");
}
