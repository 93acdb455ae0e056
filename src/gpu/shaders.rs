//! The WGSL sources, compiled into the binary. WGSL has no `#include`: every pass is
//! prefixed with `shaders/common.wgsl` (the uniform block and the discontinuity function).

/// Shared declarations: the `Params` uniform and D.
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
pub const ACCUMULATE: &str = include_str!("../../shaders/accumulate.wgsl");
pub const FILL: &str = include_str!("../../shaders/fill.wgsl");
pub const TEMPORAL: &str = include_str!("../../shaders/temporal.wgsl");
pub const GAUSSIAN: &str = include_str!("../../shaders/gaussian.wgsl");
pub const REMODULATE: &str = include_str!("../../shaders/remodulate.wgsl");
/// The G-buffer raster pass: standalone, it declares its own bindings.
pub const GBUFFER: &str = include_str!("../../shaders/gbuffer.wgsl");

/// Every compute pass by file name, for the passes and the naga validation test.
pub const PASSES: [(&str, &str); 5] = [
    ("accumulate.wgsl", ACCUMULATE),
    ("fill.wgsl", FILL),
    ("temporal.wgsl", TEMPORAL),
    ("gaussian.wgsl", GAUSSIAN),
    ("remodulate.wgsl", REMODULATE),
];

/// A compute pass's complete module source: the common block, then the pass.
pub fn with_common(pass: &str) -> String {
    format!("{COMMON}\n{pass}")
}
