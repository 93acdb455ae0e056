//! The kernel's builds per instruction set (baseline x86-64, x86-64-v3, x86-64-v4), the
//! same source compiled with each build's `#[target_feature]`s, and the dispatch that runs
//! the best build this CPU has.

use super::gbuffer::primary_hits_with;
use super::{RenderStats, Strategy};
use crate::render::accel::Sse;
use crate::render::{PixelSample, RenderScene};

/// A compiled build of the stream kernel ([`crate::render::stream`]). A baseline binary still
/// runs on every x86-64 CPU (the workers of a desktop grid are whatever machines an
/// office has), while those with AVX2 get the x86-64-v3 build and those with AVX-512 the
/// x86-64-v4 build. Every build gives the same pixels bit for bit (each lane operation is
/// one IEEE operation in the scalar code's order, and Rust never contracts or reorders
/// float arithmetic), so a grid may mix them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelBuild {
    /// x86-64-v4: paths in one AVX-512 register (F, VL, BW, DQ, CD enabled: EVEX
    /// encoding, 32 vector registers, mask registers for comparisons), node tests as v3.
    V4,
    /// x86-64-v3: paths in two AVX2 registers, node tests in one AVX register,
    /// TZCNT/LZCNT in traversal, VEX three-operand code.
    V3,
    /// Baseline x86-64: paths in four SSE2 quarters, node tests in two SSE halves (scalar
    /// code off x86-64).
    Baseline,
}

impl KernelBuild {
    /// Every build, fastest first.
    pub const ALL: [Self; 3] = [Self::V4, Self::V3, Self::Baseline];

    /// The fastest build this CPU runs.
    pub fn best() -> Self {
        Self::ALL.into_iter().find(|b| b.available()).unwrap_or(Self::Baseline)
    }

    /// Whether this CPU runs the build.
    pub fn available(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Self::V4 => v4::available(),
            #[cfg(target_arch = "x86_64")]
            Self::V3 => v3::available(),
            #[cfg(not(target_arch = "x86_64"))]
            Self::V4 | Self::V3 => false,
            Self::Baseline => true,
        }
    }

    /// The instruction-set level the build is compiled for.
    pub fn name(self) -> &'static str {
        match self {
            Self::V4 => "x86-64-v4",
            Self::V3 => "x86-64-v3",
            Self::Baseline => "baseline",
        }
    }
}

/// [`render_pixels_counted`] in the given build.
///
/// # Panics
/// Where this CPU cannot run `build` (see [`KernelBuild::available`]).
pub fn render_pixels_in(
    build: KernelBuild,
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    assert!(build.available(), "this CPU cannot run the {} build of the kernel", build.name());
    match build {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has every feature the build is compiled with (asserted).
        KernelBuild::V4 => unsafe { v4::render_pixels(scene, frame, pixels, out, strategy) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as V4.
        KernelBuild::V3 => unsafe { v3::render_pixels(scene, frame, pixels, out, strategy) },
        #[cfg(not(target_arch = "x86_64"))]
        KernelBuild::V4 | KernelBuild::V3 => unreachable!("no SIMD build off x86-64"),
        KernelBuild::Baseline => {
            crate::render::stream::render(Sse, scene, frame, pixels, out, strategy)
        }
    }
}

/// A module holding the kernel compiled with `#[target_feature]`s `$features` (one string
/// literal, as the attribute takes; `$f` the same features one by one, for detection),
/// its lanes named by the [`crate::render::accel::Lanes`] token `$lanes`: node tests in
/// one eight-lane AVX register, TZCNT/LZCNT in BVH traversal, and the paths' lanes in
/// two AVX2 halves (v3) or one AVX-512 register (v4). The same source for both builds.
#[cfg(target_arch = "x86_64")]
macro_rules! simd_build {
    ($(#[$doc:meta])* $name:ident, $lanes:ident, $features:literal, [$($f:tt),*]) => {
        $(#[$doc])*
        pub(crate) mod $name {
            use super::*;

            /// Whether this CPU can run [`render_pixels`] (cached by std after the first
            /// call).
            #[inline]
            pub fn available() -> bool {
                $(std::is_x86_feature_detected!($f))&&*
            }

            /// # Safety
            /// Only on a CPU for which [`available`] is true.
            #[target_feature(enable = $features)]
            pub unsafe fn render_pixels(
                scene: &RenderScene,
                frame: u64,
                pixels: &[u32],
                out: &mut Vec<PixelSample>,
                strategy: Strategy,
            ) -> RenderStats {
                // `available` checked every feature the token needs.
                let lanes = crate::render::accel::$lanes::detect().expect("the build's features");
                crate::render::stream::render(lanes, scene, frame, pixels, out, strategy)
            }

            /// # Safety
            /// Only on a CPU for which [`available`] is true.
            #[target_feature(enable = $features)]
            pub unsafe fn primary_hits(scene: &RenderScene, first: u32, out: &mut [PixelSample]) {
                let lanes = crate::render::accel::$lanes::detect().expect("the build's features");
                primary_hits_with(lanes, scene, first, out)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
simd_build!(
    /// The kernel compiled for x86-64-v3.
    v3,
    Avx,
    "avx,avx2,bmi1,bmi2,lzcnt,popcnt,fma",
    ["avx", "avx2", "bmi1", "bmi2", "lzcnt", "popcnt", "fma"]
);

#[cfg(target_arch = "x86_64")]
simd_build!(
    /// The kernel compiled for x86-64-v4 (the v3 features and AVX-512 F/VL/BW/DQ/CD).
    v4,
    Avx512,
    "avx,avx2,bmi1,bmi2,lzcnt,popcnt,fma,avx512f,avx512vl,avx512bw,avx512dq,avx512cd",
    [
        "avx", "avx2", "bmi1", "bmi2", "lzcnt", "popcnt", "fma", "avx512f", "avx512vl",
        "avx512bw", "avx512dq", "avx512cd"
    ]
);

/// [`primary_hit`] of pixels `first..first + out.len()` into `out`, in the kernel build
/// [`render_pixels_counted`] would pick (the same values bit for bit).
pub fn primary_hits(scene: &RenderScene, first: u32, out: &mut [PixelSample]) {
    match KernelBuild::best() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `best` picks only a build whose features the CPU has.
        KernelBuild::V4 => unsafe { v4::primary_hits(scene, first, out) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as V4.
        KernelBuild::V3 => unsafe { v3::primary_hits(scene, first, out) },
        _ => primary_hits_with(Sse, scene, first, out),
    }
}
