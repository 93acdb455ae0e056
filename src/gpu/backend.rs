//! Which implementation a master-side computation runs on (reconstruction and G-buffers
//! alike): the choice that `--reconstruct` and the scene's render settings make.

/// Which implementation to use (for reconstruction and for G-buffers alike): the CPU
/// path, the GPU path, or the GPU only on a hardware adapter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Backend {
    Cpu,
    Gpu,
    /// The GPU when a hardware adapter exists, else the CPU.
    #[default]
    Auto,
}
