//! Which instructions the node test (and the stream kernel's lanes) may use: tokens that
//! exist only where the CPU has them.

/// Which instructions the node test (and the stream kernel's lanes) may use: [`Sse`] on
/// every x86-64, [`Avx`] (one eight-lane register per plane) only where the CPU has AVX
/// and AVX2, which its constructor checks. Both give the same bits.
pub trait Lanes: Copy {
    /// Whether node tests run on eight-lane AVX registers.
    const AVX: bool;
    /// The stream kernel's lane types in this build ([`crate::render::lanes`]).
    type Simd: crate::render::lanes::Isa;
}

/// Node tests in two four-lane halves (every x86-64; scalar elsewhere).
#[derive(Clone, Copy, Debug)]
pub struct Sse;

impl Lanes for Sse {
    const AVX: bool = false;
    type Simd = crate::render::lanes::Sse2;
}

/// Node tests in one eight-lane AVX register per plane: only a CPU with AVX and AVX2 has
/// one (its lanes' integer operations are AVX2).
#[derive(Clone, Copy, Debug)]
pub struct Avx(());

impl Lanes for Avx {
    const AVX: bool = true;
    type Simd = crate::render::lanes::Avx2;
}

/// [`Avx`]'s node tests with the stream kernel's paths in sixteen-lane AVX-512
/// registers: only a CPU with AVX-512 F, BW, DQ and VL has one.
#[derive(Clone, Copy, Debug)]
pub struct Avx512(());

impl Lanes for Avx512 {
    const AVX: bool = true;
    type Simd = crate::render::lanes::Avx512;
}

impl Avx512 {
    /// The token, where this CPU has AVX2 and AVX-512 F, BW, DQ and VL.
    #[cfg(target_arch = "x86_64")]
    pub fn detect() -> Option<Self> {
        let avx512 = Avx::detect().is_some()
            && std::is_x86_feature_detected!("avx512f")
            && std::is_x86_feature_detected!("avx512bw")
            && std::is_x86_feature_detected!("avx512dq")
            && std::is_x86_feature_detected!("avx512vl");
        avx512.then_some(Self(()))
    }

    /// The token, where this CPU has AVX-512 (never, off x86-64).
    #[cfg(not(target_arch = "x86_64"))]
    pub fn detect() -> Option<Self> {
        None
    }
}

impl Avx {
    /// The token, where this CPU has AVX and AVX2.
    #[cfg(target_arch = "x86_64")]
    pub fn detect() -> Option<Self> {
        let avx2 = std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("avx2");
        avx2.then_some(Self(()))
    }

    /// The token, where this CPU has AVX and AVX2 (never, off x86-64).
    #[cfg(not(target_arch = "x86_64"))]
    pub fn detect() -> Option<Self> {
        None
    }
}
