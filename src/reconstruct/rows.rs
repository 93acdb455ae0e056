//! Row kernels: how the CPU passes run, one output row at a time, in parallel bands of
//! rows, in the best instruction-set build this CPU has.
//!
//! The kernels are written once on the renderer's lane types ([`crate::render::lanes`],
//! [`WIDTH`] pixels per vector), generic over the instruction set
//! ([`crate::render::isa::Isa`]); [`run_rows`] runs each band of rows through
//! [`run_in_build`], which compiles the kernel into the renderer's baseline, x86-64-v3
//! and x86-64-v4 builds with their `#[target_feature]`s. What is specific to rows lives
//! here: the kernel trait, the bands, and the loads and stores of a row's last, shorter
//! run of pixels.

use rayon::prelude::*;

use crate::render::integrator::{run_in_build, BuildTask};
use crate::render::isa::{Cpu, Isa, IsaLevel};
use crate::render::lanes::WIDTH;

/// A pass that writes its output one row at a time; `R` is one row of the output.
pub trait RowKernel<R>: Sync {
    /// What a thread keeps from one row to the next: it is handed consecutive rows.
    type Scratch: Send;

    fn scratch(&self) -> Self::Scratch;

    /// Writes row `y` with the lanes of `I`. Implementations are `#[inline(always)]`, so
    /// that [`run_rows`] compiles them within functions that enable `I`'s instructions.
    fn row<I: Isa>(&self, y: usize, out: R, scratch: &mut Self::Scratch);
}

/// Bands of consecutive rows that a thread takes at a time: about four per thread, enough
/// to share out uneven rows, few enough that the kernels' warm-up at a band's first row
/// costs little.
fn band(rows: usize) -> usize {
    rows.div_ceil(4 * rayon::current_num_threads()).max(1)
}

/// Runs `kernel` on every row of `rows` (each with its y), in parallel bands, in the
/// build of [`IsaLevel::best`].
pub fn run_rows<R: Send, K: RowKernel<R>>(kernel: &K, rows: Vec<(usize, R)>) {
    let build = IsaLevel::best();
    let band = band(rows.len());
    rows.into_par_iter().chunks(band).for_each(|rows| run_in_build(build, Band { kernel, rows }));
}

/// Consecutive rows of one kernel, run with one scratch.
struct Band<'k, R, K> {
    kernel: &'k K,
    rows: Vec<(usize, R)>,
}

impl<R, K: RowKernel<R>> BuildTask for Band<'_, R, K> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, _: Cpu<I>) {
        let mut scratch = self.kernel.scratch();
        for (y, row) in self.rows {
            self.kernel.row::<I>(y, row, &mut scratch);
        }
    }
}

/// The first [`WIDTH`] entries of `src`, padded with `fill` where it is shorter.
#[inline(always)]
pub fn load<T: Copy>(src: &[T], fill: T) -> [T; WIDTH] {
    match <&[T; WIDTH]>::try_from(src) {
        Ok(a) => *a,
        Err(_) => std::array::from_fn(|k| src.get(k).copied().unwrap_or(fill)),
    }
}

/// Writes the first `dst.len()` (at most [`WIDTH`]) entries of `v` to `dst`.
#[inline(always)]
pub fn store<T: Copy>(dst: &mut [T], v: &[T; WIDTH]) {
    // A whole run is one vector store; only a row's last run copies fewer lanes.
    let n = dst.len();
    match <&mut [T; WIDTH]>::try_from(&mut *dst) {
        Ok(d) => *d = *v,
        Err(_) => dst.copy_from_slice(&v[..n]),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    #[test]
    fn load_pads_and_store_writes_the_row_tail() {
        let src: Vec<u32> = (0..5).collect();
        let a = load(&src, 9);
        assert_eq!(&a[..5], &[0, 1, 2, 3, 4]);
        assert!(a[5..].iter().all(|&v| v == 9));
        let whole: Vec<u32> = (0..WIDTH as u32).collect();
        assert_eq!(load(&whole, 9).as_slice(), whole.as_slice());
        let mut dst = [0u32; 7];
        store(&mut dst[..3], &a);
        assert_eq!(dst, [0, 1, 2, 0, 0, 0, 0]);
    }

    /// Counts the rows it is given and checks each row's y.
    struct Count(AtomicUsize);

    impl RowKernel<(usize, &mut u32)> for Count {
        type Scratch = Option<usize>;

        fn scratch(&self) -> Option<usize> {
            None
        }

        fn row<I: Isa>(&self, y: usize, (y2, out): (usize, &mut u32), last: &mut Option<usize>) {
            assert_eq!(y, y2);
            // A band's rows come in order.
            assert!(last.is_none_or(|l| l < y));
            *last = Some(y);
            *out += 1;
            self.0.fetch_add(1, Ordering::Relaxed);
        }
    }

    #[test]
    fn run_rows_runs_every_row_once() {
        let mut out = [0u32; 37];
        let rows = out.iter_mut().enumerate().map(|(y, o)| (y, (y, o))).collect();
        let count = Count(AtomicUsize::new(0));
        run_rows(&count, rows);
        assert_eq!(count.0.into_inner(), 37);
        assert!(out.iter().all(|&o| o == 1));
    }
}
