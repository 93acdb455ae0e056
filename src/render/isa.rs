//! Which instruction set the kernel runs in, under one name in three forms:
//! [`IsaLevel`], the run-time choice (the builds one binary holds, the fastest this CPU
//! runs, their names in the benchmarks' JSON); [`Isa`], the compile-time one (the type
//! parameter of the lane types, the node test and every kernel stage: [`V4`], [`V3`],
//! [`Baseline`]); and [`Cpu`], a value that exists only where this CPU runs a given
//! [`Isa`], which the kernel's entry points take so that code using an instruction set
//! cannot be reached on a CPU without it.
//!
//! A baseline binary still runs on every x86-64 CPU (the workers of a desktop grid are
//! whatever machines an office has), while those with AVX2 get the x86-64-v3 build and
//! those with AVX-512 the x86-64-v4 build. Every build gives the same pixels bit for bit
//! (each lane operation is one IEEE operation in the scalar code's order, and Rust never
//! contracts or reorders float arithmetic), so a grid may mix them.

use std::fmt::Debug;
use std::marker::PhantomData;

/// An instruction-set level the kernel is compiled for, fastest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IsaLevel {
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

impl IsaLevel {
    /// Every level, fastest first.
    pub const ALL: [Self; 3] = [Self::V4, Self::V3, Self::Baseline];

    /// The fastest level this CPU runs.
    pub fn best() -> Self {
        Self::ALL.into_iter().find(|b| b.available()).unwrap_or(Self::Baseline)
    }

    /// Whether this CPU runs the level (the features its build is compiled with, listed
    /// beside them in `integrator/builds.rs`).
    pub fn available(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Self::V4 => super::integrator::v4::available(),
            #[cfg(target_arch = "x86_64")]
            Self::V3 => super::integrator::v3::available(),
            #[cfg(not(target_arch = "x86_64"))]
            Self::V4 | Self::V3 => false,
            Self::Baseline => true,
        }
    }

    /// The level's name, as the benchmarks report it.
    pub fn name(self) -> &'static str {
        match self {
            Self::V4 => "x86-64-v4",
            Self::V3 => "x86-64-v3",
            Self::Baseline => "baseline",
        }
    }
}

/// An instruction-set level as a type: the lane types' operators, the node test and the
/// kernel's stages compile to its instructions. `F32s<V4>` may only be used by code
/// inlined into the x86-64-v4 build and `F32s<V3>` by code of the v3 build, whose
/// features make their intrinsics inline there; the kernel reaches them only through a
/// [`Cpu`].
pub trait Isa: Copy + Default + Debug + PartialEq + Eq + 'static {
    const LEVEL: IsaLevel;
}

/// [`IsaLevel::V4`]: one AVX-512 register per lane group.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct V4;

impl Isa for V4 {
    const LEVEL: IsaLevel = IsaLevel::V4;
}

/// [`IsaLevel::V3`]: two AVX/AVX2 registers per lane group, node tests in one AVX register.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct V3;

impl Isa for V3 {
    const LEVEL: IsaLevel = IsaLevel::V3;
}

/// [`IsaLevel::Baseline`]: four SSE2 quarters per lane group (every x86-64 CPU; scalar
/// elsewhere).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Baseline;

impl Isa for Baseline {
    const LEVEL: IsaLevel = IsaLevel::Baseline;
}

/// This CPU runs `I`: made only by [`Cpu::detect`] (or [`Cpu::BASELINE`], which every CPU
/// runs), and taken by the kernel's and the BVH's entry points.
#[derive(Clone, Copy, Debug)]
pub struct Cpu<I>(PhantomData<I>);

impl<I: Isa> Cpu<I> {
    /// The proof, where this CPU has every feature `I`'s build is compiled with.
    pub fn detect() -> Option<Self> {
        I::LEVEL.available().then_some(Self(PhantomData))
    }
}

impl Cpu<Baseline> {
    /// Every CPU runs the baseline.
    pub const BASELINE: Self = Self(PhantomData);
}
