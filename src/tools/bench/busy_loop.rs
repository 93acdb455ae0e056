//! The desk owner's program in `gridlight bench owner-impact`: a CPU-bound loop on a few
//! threads that counts its iterations (`gridlight bench busy-loop`, a hidden command run
//! as a separate process at normal priority, as the owner's programs are).

use std::hint::black_box;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// What one run of the loop did.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BusyLoop {
    pub threads: u32,
    pub iterations: u64,
    pub seconds: f64,
    pub iterations_per_second: f64,
}

/// Iterations between two looks at the clock.
const CHUNK: u64 = 1 << 16;

/// Spins `threads` threads for `seconds` and counts their iterations.
pub fn run(threads: u32, seconds: f64) -> BusyLoop {
    let threads = threads.max(1);
    let duration = Duration::from_secs_f64(seconds.max(0.0));
    let start = Arc::new(Barrier::new(threads as usize + 1));
    let stop = Arc::new(AtomicBool::new(false));
    let handles: Vec<_> = (0..threads)
        .map(|t| {
            let (start, stop) = (Arc::clone(&start), Arc::clone(&stop));
            std::thread::spawn(move || {
                start.wait();
                let mut x = u64::from(t) + 1;
                let mut n = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    for _ in 0..CHUNK {
                        // An LCG step: pure ALU work, no memory traffic.
                        x = black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1));
                    }
                    n += CHUNK;
                }
                black_box(x);
                n
            })
        })
        .collect();
    start.wait();
    let began = Instant::now();
    std::thread::sleep(duration);
    stop.store(true, Ordering::Relaxed);
    let iterations: u64 = handles.into_iter().map(|h| h.join().unwrap_or(0)).sum();
    let seconds = began.elapsed().as_secs_f64();
    BusyLoop { threads, iterations, seconds, iterations_per_second: iterations as f64 / seconds }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loop_counts_and_stops_on_time() {
        let r = run(2, 0.05);
        assert_eq!(r.threads, 2);
        assert!(r.iterations >= CHUNK, "{r:?}");
        assert!(r.seconds >= 0.05 && r.seconds < 5.0, "{r:?}");
    }
}
