//! The kernel's builds per instruction set (baseline x86-64, x86-64-v3, x86-64-v4), the
//! same source compiled with each build's `#[target_feature]`s, and the dispatch that runs
//! the best build this CPU has. Other code written on the lane types (the reconstruction's
//! row kernels) runs in the same builds through [`BuildTask`] and [`run_in_build`], so that
//! each build's feature list is written once, here: the kernel itself and its primary hits
//! are such tasks too.

use super::gbuffer::primary_block_with;
use super::{RenderStats, Strategy};
use crate::render::isa::{Cpu, Isa, IsaLevel};
use crate::render::{PixelSample, RenderScene};

/// Work written on the lane types, to be compiled into each build: implementations make
/// [`BuildTask::run`] `#[inline(always)]`, so that it is compiled within a function that
/// enables the build's features, where the intrinsics of `I`'s lanes inline.
pub trait BuildTask {
    type Output;

    /// Does the work with the lanes of `I`, which `cpu` proves this CPU runs.
    fn run<I: Isa>(self, cpu: Cpu<I>) -> Self::Output;
}

/// Runs `task` in the build of the given level.
///
/// # Panics
/// Where this CPU cannot run `build` (see [`IsaLevel::available`]).
pub fn run_in_build<T: BuildTask>(build: IsaLevel, task: T) -> T::Output {
    assert!(build.available(), "this CPU cannot run the {} build", build.name());
    match build {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has every feature the build is compiled with (asserted).
        IsaLevel::V4 => unsafe { v4::run(task) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as V4.
        IsaLevel::V3 => unsafe { v3::run(task) },
        #[cfg(not(target_arch = "x86_64"))]
        IsaLevel::V4 | IsaLevel::V3 => unreachable!("no SIMD build off x86-64"),
        IsaLevel::Baseline => task.run(Cpu::BASELINE),
    }
}

/// [`super::render_pixels_counted`] in the build of the given level.
///
/// # Panics
/// Where this CPU cannot run `build` (see [`IsaLevel::available`]).
pub fn render_pixels_in(
    build: IsaLevel,
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    run_in_build(build, RenderPixels { scene, frame, pixels, out, strategy })
}

/// [`super::primary_hit`] of the pixels `x0..x0 + width` × `y0..y0 + height` (`height` ≤
/// [`super::PRIMARY_TILE`]) into `out`, row by row, their rays traced a tile at a time in the
/// build of the given level (the same values bit for bit in every build).
///
/// # Panics
/// Where this CPU cannot run `build`, or `out` is not `width × height` long.
pub fn primary_block_in(
    build: IsaLevel,
    scene: &RenderScene,
    corner: (u32, u32),
    size: (u32, u32),
    out: &mut [PixelSample],
) {
    assert!(size.1 <= super::PRIMARY_TILE, "a block is at most one tile tall");
    assert_eq!(out.len(), size.0 as usize * size.1 as usize, "one sample per pixel");
    run_in_build(build, PrimaryBlock { scene, corner, size, out })
}

/// The stream kernel over a pixel list, as a [`BuildTask`].
struct RenderPixels<'a> {
    scene: &'a RenderScene,
    frame: u64,
    pixels: &'a [u32],
    out: &'a mut Vec<PixelSample>,
    strategy: Strategy,
}

impl BuildTask for RenderPixels<'_> {
    type Output = RenderStats;

    #[inline(always)]
    fn run<I: Isa>(self, cpu: Cpu<I>) -> RenderStats {
        crate::render::stream::render(
            cpu,
            self.scene,
            self.frame,
            self.pixels,
            self.out,
            self.strategy,
        )
    }
}

/// Primary hits of a block of pixels, as a [`BuildTask`].
struct PrimaryBlock<'a> {
    scene: &'a RenderScene,
    corner: (u32, u32),
    size: (u32, u32),
    out: &'a mut [PixelSample],
}

impl BuildTask for PrimaryBlock<'_> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, cpu: Cpu<I>) {
        primary_block_with(cpu, self.scene, self.corner, self.size, self.out)
    }
}

/// A module holding the kernel compiled with `#[target_feature]`s `$features` (one string
/// literal, as the attribute takes; `$f` the same features one by one, for detection),
/// its lanes, node tests and stages in the [`crate::render::isa::Isa`] `$isa`: node tests in
/// one eight-lane AVX register, TZCNT/LZCNT in BVH traversal, and the paths' lanes in
/// two AVX2 halves (v3) or one AVX-512 register (v4). The same source for both builds.
#[cfg(target_arch = "x86_64")]
macro_rules! isa_build {
    ($(#[$doc:meta])* $name:ident, $isa:ident, $features:literal, [$($f:tt),*]) => {
        $(#[$doc])*
        pub(crate) mod $name {
            use super::*;

            /// Whether this CPU can run this build's functions (cached by std after the first
            /// call).
            #[inline]
            pub fn available() -> bool {
                $(std::is_x86_feature_detected!($f))&&*
            }

            /// [`BuildTask::run`] of `task`, compiled with this build's features.
            ///
            /// # Safety
            /// Only on a CPU for which [`available`] is true.
            #[target_feature(enable = $features)]
            pub unsafe fn run<T: BuildTask>(task: T) -> T::Output {
                let cpu = Cpu::<crate::render::isa::$isa>::detect().expect("the build's features");
                task.run(cpu)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
isa_build!(
    /// The kernel compiled for x86-64-v3.
    v3,
    V3,
    "avx,avx2,bmi1,bmi2,lzcnt,popcnt,fma",
    ["avx", "avx2", "bmi1", "bmi2", "lzcnt", "popcnt", "fma"]
);

#[cfg(target_arch = "x86_64")]
isa_build!(
    /// The kernel compiled for x86-64-v4 (the v3 features and AVX-512 F/VL/BW/DQ/CD).
    v4,
    V4,
    "avx,avx2,bmi1,bmi2,lzcnt,popcnt,fma,avx512f,avx512vl,avx512bw,avx512dq,avx512cd",
    [
        "avx", "avx2", "bmi1", "bmi2", "lzcnt", "popcnt", "fma", "avx512f", "avx512vl",
        "avx512bw", "avx512dq", "avx512cd"
    ]
);
