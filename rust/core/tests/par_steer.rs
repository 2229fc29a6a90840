//! `par::steer` in a process of its own (the spin time and the steering are read once per
//! process): helpers woken by a call start on another CPU than the caller's, and the pool's
//! threads get their own CPU masks back after the call, or after a wake that no call follows.

use rotorid_core::par::{for_each_task, steer};
use std::sync::Mutex;
use std::time::{Duration, Instant};

fn busy(us: u64) {
    let t = Instant::now();
    while t.elapsed() < Duration::from_micros(us) {
        std::hint::spin_loop();
    }
}

#[cfg(target_os = "linux")]
fn allowed_cpus() -> usize {
    // SAFETY: a zeroed cpu_set_t filled by the system call
    unsafe {
        let mut mask: libc::cpu_set_t = std::mem::zeroed();
        libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut mask);
        libc::CPU_COUNT(&mask) as usize
    }
}

#[cfg(target_os = "linux")]
#[test]
fn woken_helpers_start_off_the_callers_cpu_and_the_masks_come_back() {
    // the environment values first (read afresh by the parsers, once by the core)
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
    if allowed_cpus() < 2 || rayon::current_num_threads() < 2 {
        eprintln!("one CPU or one pool thread: nothing to steer");
        return;
    }
    // the first calls have the pool's threads record themselves
    let t0 = Instant::now();
    while steer::state().0 < rayon::current_num_threads() && t0.elapsed() < Duration::from_secs(10) {
        for_each_task(8, |_| busy(20));
        std::thread::sleep(Duration::from_millis(2));
    }
    assert_eq!(steer::state().0, rayon::current_num_threads());
    let caller = std::thread::current().id();
    let mut steered_tasks = 0;
    for _ in 0..20 {
        std::thread::sleep(Duration::from_millis(3)); // the helpers are asleep
        let seen = Mutex::new(Vec::new());
        for_each_task(64, |_| {
            busy(50);
            if std::thread::current().id() != caller {
                // SAFETY: sched_getcpu has no preconditions
                let cpu = unsafe { libc::sched_getcpu() } as usize;
                seen.lock().unwrap().push((cpu, steer::state().1));
            }
        });
        assert_eq!(steer::state().1, None, "the masks are given back after the call");
        assert!(steer::masks_as_recorded(), "every pool thread has its own CPU mask again");
        for (cpu, excluded) in seen.into_inner().unwrap() {
            if let Some(x) = excluded {
                assert_ne!(cpu, x, "a helper task ran on the CPU its call's caller was on");
                steered_tasks += 1;
            }
        }
    }
    assert!(steered_tasks > 0, "no helper took a task while the masks excluded the caller's CPU");
    // a wake that no call follows (an API call refusing its input after waking the pool): the
    // last helper to stop spinning gives the masks back
    std::thread::sleep(Duration::from_millis(3));
    rotorid_core::par::wake_helpers(Duration::from_millis(1));
    assert!(steer::state().1.is_some(), "the wake narrowed the masks");
    let t0 = Instant::now();
    while steer::state().1.is_some() && t0.elapsed() < Duration::from_secs(2) {
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(steer::state().1, None, "the masks are given back when the woken helpers stop spinning");
    assert!(steer::masks_as_recorded());
}
