//! The calling thread's CPU time, what the simulated grid and the kernel benchmarks time
//! work in (other processes on the cores do not count), and its busy time (running or
//! waiting for a core), what the scheduler measures the master's own cost per result
//! with (`scheduler::job_size`): on a machine whose cores other work shares, the master
//! gets through fewer results a second than its CPU time per result says.

/// CPU time consumed by the calling thread, in seconds (NaN where the clock fails, and
/// on platforms without a thread CPU clock in `libc`: callers then time by the wall or
/// go without).
#[cfg(not(any(target_os = "linux", target_os = "macos")))]
pub fn thread_cpu_seconds() -> f64 {
    f64::NAN
}

/// CPU time consumed by the calling thread, in seconds (NaN where the clock fails).
#[cfg(any(target_os = "linux", target_os = "macos"))]
pub fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid out-pointer; this clock exists on every Linux kernel and
    // on macOS since 10.12.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Seconds the calling thread ran or waited, runnable, for a core since it started: what
/// its work cost it on this machine as it is loaded (a thread that shares its cores with
/// other busy processes gets through less in a second). On Linux from
/// `/proc/thread-self/schedstat` (run time and run-queue delay); elsewhere, or where that
/// cannot be read, the CPU time alone ([`thread_cpu_seconds`]).
pub fn thread_busy_seconds() -> f64 {
    #[cfg(target_os = "linux")]
    if let Some(s) = std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|text| schedstat_busy_seconds(&text))
    {
        return s;
    }
    thread_cpu_seconds()
}

/// Run time plus run-queue delay of a `schedstat` line (nanoseconds), in seconds.
fn schedstat_busy_seconds(text: &str) -> Option<f64> {
    let mut fields = text.split_whitespace().map(|f| f.parse::<u64>().ok());
    let (ran, waited) = (fields.next()??, fields.next()??);
    Some((ran + waited) as f64 * 1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn busy_time_is_run_time_plus_run_queue_delay() {
        assert_eq!(schedstat_busy_seconds("1500000000 500000000 42\n"), Some(2.0));
        assert_eq!(schedstat_busy_seconds("12 oops 1"), None);
        assert_eq!(schedstat_busy_seconds(""), None);
        let (a, b) = (thread_busy_seconds(), thread_busy_seconds());
        assert!(a.is_nan() || b >= a, "busy time went back: {a} then {b}");
    }

    #[test]
    fn the_thread_clock_counts_this_threads_work_and_not_its_sleep() {
        let start = thread_cpu_seconds();
        if start.is_nan() {
            return; // no thread clock here: callers go without
        }
        std::thread::sleep(std::time::Duration::from_millis(30));
        let slept = thread_cpu_seconds() - start;
        let mut x = 0u64;
        let spin = std::time::Instant::now();
        while spin.elapsed() < std::time::Duration::from_millis(30) {
            x = std::hint::black_box(x.wrapping_add(1));
        }
        let worked = thread_cpu_seconds() - start - slept;
        assert!(slept < 0.02, "sleeping cost {slept} s of CPU");
        assert!(worked > 0.0, "spinning cost no CPU");
    }
}
