//! The pool's helpers between calls (`par::for_each_task`, `par::wake_helpers`): they take part
//! in calls made while they spin, go back to sleep by themselves, and every task still runs
//! exactly once whichever way a helper joins. One test function: the spinning helpers are
//! process-wide state, so nothing else may run in this process meanwhile.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rotorid_core::par::{for_each_task, spin_time, spin_time_from_env, spinning_helpers, wake_helpers, DEFAULT_SPIN, MAX_SPIN};

fn all_asleep_within(limit: Duration) -> Duration {
    let t = Instant::now();
    while spinning_helpers() > 0 {
        assert!(t.elapsed() < limit, "helpers still spinning after {limit:?}");
        std::thread::sleep(Duration::from_micros(50));
    }
    t.elapsed()
}

fn every_task_once(n: usize) {
    let hits: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
    for_each_task(n, |i| {
        // a little work per task, so that a helper has time to join
        std::hint::black_box((0..200).sum::<usize>());
        hits[i].fetch_add(1, Ordering::Relaxed);
    });
    assert!(hits.iter().all(|h| h.load(Ordering::Relaxed) == 1), "n = {n}");
}

/// How many threads run the tasks of one call of n 1-ms tasks (so a helper has ample time to
/// join).
fn threads_taking_part(n: usize) -> usize {
    let ids = std::sync::Mutex::new(std::collections::HashSet::new());
    for_each_task(n, |_| {
        std::thread::sleep(Duration::from_millis(1));
        ids.lock().unwrap().insert(std::thread::current().id());
    });
    let k = ids.lock().unwrap().len();
    k
}

#[test]
fn helpers_spin_between_calls_and_then_sleep() {
    // the default spin time (ROTORID_SPIN_US unset in the test run)
    std::env::remove_var("ROTORID_SPIN_US");
    assert_eq!(spin_time_from_env().unwrap(), None);
    assert_eq!(spin_time(), DEFAULT_SPIN);
    let helpers = rayon::current_num_threads() - 1;
    assert_eq!(spinning_helpers(), 0);

    // a call: every task once, then the helpers spin for the spin time (not much longer) and
    // go back to sleep
    every_task_once(1000);
    assert!(spinning_helpers() <= helpers);
    all_asleep_within(Duration::from_secs(2));

    // still spinning after a call whose caller finished long after them, although the deadline
    // they found had passed (the caller sets the new one only after its wait): the caller's
    // first task takes 100 µs, every other task nothing; checked on the calls that took under
    // 180 µs in all (on a busy machine a call can stall in the wake-up of a sleeping thread)
    let mut checked = 0;
    for _ in 0..60 {
        std::thread::sleep(Duration::from_millis(1)); // helpers asleep, the last deadline long past
        let caller = std::thread::current().id();
        let slowed = std::sync::atomic::AtomicBool::new(false);
        let t = Instant::now();
        for_each_task(64, |_| {
            if std::thread::current().id() == caller && !slowed.swap(true, Ordering::Relaxed) {
                let until = Instant::now() + Duration::from_micros(100);
                while Instant::now() < until {
                    std::hint::spin_loop();
                }
            }
        });
        let n = spinning_helpers();
        if t.elapsed() < Duration::from_micros(180) {
            checked += 1;
            assert_eq!(n, helpers, "helpers left before the call ended");
        }
    }
    assert!(helpers == 0 || checked > 0, "no call came under 180 µs");
    all_asleep_within(Duration::from_secs(2));

    // calls back to back, each joined by the helpers still spinning after the one before
    for n in [2, 3, 17, 1000, 5000] {
        every_task_once(n);
    }
    all_asleep_within(Duration::from_secs(2));

    // woken ahead of a call: spinning at once, then a call ends the long wait (the helpers
    // spin for the spin time after it, not for the 5 s asked for)
    wake_helpers(Duration::from_secs(5));
    assert_eq!(spinning_helpers(), helpers);
    wake_helpers(Duration::from_secs(5)); // no second set of helpers
    assert_eq!(spinning_helpers(), helpers);
    // no job is spawned for a helper already spinning: the call reaches it through the offer
    // alone, so a second thread taking tasks shows that path works
    if helpers > 0 {
        assert!(threads_taking_part(200) >= 2, "no spinning helper joined the call");
    }
    every_task_once(500);
    all_asleep_within(Duration::from_secs(2));

    // woken with no call after: the wait ends by itself after max_wait, and after MAX_SPIN at
    // the longest whatever max_wait was
    wake_helpers(Duration::from_millis(2));
    let slept_after = all_asleep_within(Duration::from_secs(2));
    assert!(slept_after < Duration::from_millis(500), "{slept_after:?}");
    wake_helpers(Duration::from_secs(3600));
    let slept_after = all_asleep_within(Duration::from_secs(2));
    assert!(slept_after < MAX_SPIN + Duration::from_millis(450), "{slept_after:?}");

    // from inside a pool nothing spins (the pool's own threads run its calls)
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    pool.install(|| wake_helpers(Duration::from_secs(5)));
    pool.install(|| every_task_once(300));
    assert_eq!(spinning_helpers(), 0);

    // a panicking task still reaches the caller, and the helpers still go back to sleep
    let r = std::panic::catch_unwind(|| for_each_task(64, |i| assert_ne!(i, 9, "task 9")));
    assert!(r.is_err());
    all_asleep_within(Duration::from_secs(2));
    every_task_once(1000);

    // calls from several threads at once (one offer at a time: a call whose offer is replaced
    // runs on its caller and whoever joined it; every task still once)
    // never more helper jobs spinning than the pool has helpers (sampled meanwhile)
    let running = std::sync::atomic::AtomicBool::new(true);
    let most = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        let (running, most) = (&running, &most);
        scope.spawn(move || {
            while running.load(Ordering::Relaxed) {
                most.fetch_max(spinning_helpers(), Ordering::Relaxed);
                std::hint::spin_loop();
            }
        });
        let callers: Vec<_> = (0..4usize)
            .map(|t| {
                scope.spawn(move || {
                    for k in 0..200usize {
                        every_task_once(2 + (t * 37 + k * 11) % 600);
                        if k % 4 == t {
                            // a pause now and then: helpers leave, and calls find none spinning
                            std::thread::sleep(Duration::from_micros(300));
                        }
                    }
                })
            })
            .collect();
        for c in callers {
            c.join().unwrap();
        }
        running.store(false, Ordering::Relaxed);
    });
    assert!(most.load(Ordering::Relaxed) <= helpers, "{} helper jobs spinning at once", most.load(Ordering::Relaxed));
    all_asleep_within(Duration::from_secs(2));

    // the spin time the environment asks for, and misspellings refused
    for (v, want) in [("0", Some(Duration::ZERO)), ("150", Some(Duration::from_micros(150))), (" 1e3 ", Some(Duration::from_millis(1))), ("50000", Some(MAX_SPIN)), ("", None)] {
        std::env::set_var("ROTORID_SPIN_US", v);
        assert_eq!(spin_time_from_env().unwrap(), want, "{v:?}");
    }
    for v in ["-1", "50001", "2e6", "nan", "inf", "200us", "fast"] {
        std::env::set_var("ROTORID_SPIN_US", v);
        let e = spin_time_from_env().unwrap_err().to_string();
        assert!(e.contains("ROTORID_SPIN_US") && e.contains(v), "{v:?}: {e}");
    }
    std::env::remove_var("ROTORID_SPIN_US");
}
