//! `gridlight worker --gpu`: render with the GPU path tracer instead of CPU threads.
//!
//! `--gpu` (or `--gpu=on`) requires an adapter, software ones included (Mesa's lavapipe);
//! `--gpu=auto` uses a hardware adapter when there is one and the CPU threads otherwise.
//! A GPU worker measures its speed on the built-in Cornell box and opens as many
//! connections as keep the device full (`worker::gpu::connections_for`), unless
//! `--threads` says how many.

use anyhow::Context;
use tracing::info;

use crate::gpu::GpuContext;
use crate::render::gpu::GpuTracer;
use crate::worker::gpu::{calibrate, connections_for, GpuRenderer};
use crate::worker::{RendererKind, WorkerConfig};

/// Whether a worker renders on a GPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum GpuChoice {
    /// CPU threads only.
    #[default]
    Off,
    /// The GPU path tracer on the default adapter (software adapters included).
    On,
    /// The GPU when a hardware adapter exists, else CPU threads.
    Auto,
}

/// Turns `config` into a GPU worker's when `choice` asks for one and one is found;
/// `threads_given` is whether the user chose the number of connections.
pub fn apply(
    choice: GpuChoice,
    mut config: WorkerConfig,
    threads_given: bool,
) -> anyhow::Result<WorkerConfig> {
    let ctx = match choice {
        GpuChoice::Off => return Ok(config),
        GpuChoice::On => GpuContext::new().context("--gpu: no usable GPU adapter")?,
        GpuChoice::Auto => match GpuContext::new_hardware() {
            Ok(ctx) => ctx,
            Err(err) => {
                info!(cause = %err, "--gpu=auto: rendering on the CPU");
                return Ok(config);
            }
        },
    };
    if matches!(config.renderer, RendererKind::Null { .. }) {
        anyhow::bail!("--gpu and --null-render exclude each other");
    }
    let tracer = GpuTracer::new(ctx.shared());
    let speed = calibrate(&tracer).context("--gpu: measuring the GPU's speed")?;
    if !threads_given {
        config.threads = connections_for(speed, config.pipeline);
    }
    info!(
        adapter = tracer.adapter(),
        samples_per_second = speed as u64,
        connections = config.threads,
        "GPU worker"
    );
    config.renderer = RendererKind::Gpu(GpuRenderer::start(tracer)?);
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn gpu(args: &[&str]) -> Option<GpuChoice> {
        let cli =
            crate::cli::Cli::try_parse_from(["gridlight", "worker"].iter().chain(args).copied())
                .expect("valid command line");
        match cli.command {
            crate::cli::Command::Worker(a) => a.gpu,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn gpu_alone_means_on_and_takes_auto_and_off() {
        assert_eq!(gpu(&[]), None);
        assert_eq!(gpu(&["--gpu"]), Some(GpuChoice::On));
        assert_eq!(gpu(&["--gpu=auto"]), Some(GpuChoice::Auto));
        assert_eq!(gpu(&["--gpu=off"]), Some(GpuChoice::Off));
        // A value needs `=`: a bare word after --gpu is not taken as one.
        assert!(crate::cli::Cli::try_parse_from(["gridlight", "worker", "--gpu", "maybe"]).is_err());
    }
}
