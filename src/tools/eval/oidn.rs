//! Intel Open Image Denoise, the external anchor of `gridlight eval motion` (issue 41).
//!
//! OIDN 2 is the denoiser of the viewports users compare gridlight with. It runs through
//! `scripts/oidn-anchor.py` (embedded here, so any binary can run it) in a child Python
//! that has `pyoidn`; it is never a dependency of the binary. Frames go to the script as
//! PFM files in a temporary directory, all at once, so that OIDN's set-up is paid once
//! and only each filter execution is timed.

use std::path::Path;
use std::process::Command;

use anyhow::{bail, Context};
use glam::Vec3;

use super::pfm;

/// The script, as kept in `scripts/`.
const SCRIPT: &str = include_str!("../../../scripts/oidn-anchor.py");

/// How to reach OIDN.
#[derive(Clone, Debug)]
pub struct Oidn {
    /// The Python interpreter that has `pyoidn`.
    pub python: String,
    /// OIDN's threads (0: every core).
    pub threads: u32,
}

/// One frame for the denoiser: linear HDR colour and the primary hits' albedo and normal.
pub struct Noisy {
    pub colour: Vec<Vec3>,
    pub albedo: Vec<Vec3>,
    pub normal: Vec<Vec3>,
}

/// A denoised frame and the milliseconds of its filter execution.
pub struct Denoised {
    pub colour: Vec<Vec3>,
    pub ms: f64,
}

impl Oidn {
    /// `Err` with what to do when the interpreter or `pyoidn` is missing.
    pub fn check(&self) -> anyhow::Result<()> {
        let out = Command::new(&self.python)
            .args(["-c", "import pyoidn"])
            .output()
            .with_context(|| format!("running `{}`", self.python))?;
        if !out.status.success() {
            bail!(
                "`{} -c \"import pyoidn\"` failed ({}): install it with `pip install pyoidn`",
                self.python,
                String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("no message")
            );
        }
        Ok(())
    }

    /// Denoises `frames` (each `width × height`), in order.
    pub fn denoise(
        &self,
        frames: &[Noisy],
        width: u32,
        height: u32,
    ) -> anyhow::Result<Vec<Denoised>> {
        let dir = tempfile::tempdir().context("a directory for OIDN's frames")?;
        let script = dir.path().join("oidn-anchor.py");
        std::fs::write(&script, SCRIPT).context("writing the OIDN script")?;
        let name = |i: usize| format!("{i:05}");
        for (i, f) in frames.iter().enumerate() {
            let at = |what: &str| dir.path().join(format!("{}-{what}.pfm", name(i)));
            pfm::write(&at("color"), width, height, &f.colour)?;
            pfm::write(&at("albedo"), width, height, &f.albedo)?;
            pfm::write(&at("normal"), width, height, &f.normal)?;
        }
        let out = Command::new(&self.python)
            .arg(&script)
            .arg(dir.path())
            .args(["--threads", &self.threads.to_string()])
            .output()
            .with_context(|| format!("running `{}` on the OIDN script", self.python))?;
        if !out.status.success() {
            bail!("the OIDN script failed: {}", String::from_utf8_lossy(&out.stderr).trim());
        }
        let timings = execution_ms(&String::from_utf8_lossy(&out.stdout))?;
        (0..frames.len())
            .map(|i| {
                let ms = *timings
                    .get(&name(i))
                    .with_context(|| format!("the OIDN script did not report frame {i}"))?;
                let colour =
                    read_sized(&dir.path().join(format!("{}-out.pfm", name(i))), width, height)?;
                Ok(Denoised { colour, ms })
            })
            .collect()
    }
}

/// The script's `{"name", "ms"}` lines by name.
fn execution_ms(stdout: &str) -> anyhow::Result<std::collections::HashMap<String, f64>> {
    let mut out = std::collections::HashMap::new();
    for line in stdout.lines().filter(|l| !l.trim().is_empty()) {
        let v: serde_json::Value = serde_json::from_str(line)
            .with_context(|| format!("the OIDN script printed `{line}`"))?;
        if let (Some(name), Some(ms)) = (v["name"].as_str(), v["ms"].as_f64()) {
            out.insert(name.to_string(), ms);
        }
    }
    Ok(out)
}

fn read_sized(path: &Path, width: u32, height: u32) -> anyhow::Result<Vec<Vec3>> {
    let (w, h, pixels) = pfm::read(path)?;
    if (w, h) != (width, height) {
        bail!("`{}` is {w}x{h}, not {width}x{height}", path.display());
    }
    Ok(pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scripts_lines_give_each_frames_execution_time() {
        let got = execution_ms("{\"setup_ms\": 12.5}\n{\"name\": \"00000\", \"ms\": 3.25}\n")
            .expect("parse");
        assert_eq!(got.len(), 1);
        assert_eq!(got["00000"], 3.25);
        assert!(execution_ms("Traceback (most recent call last):").is_err());
    }

    #[test]
    fn a_missing_interpreter_names_itself() {
        let oidn = Oidn { python: "/nonexistent/python3".into(), threads: 0 };
        let err = oidn.check().expect_err("no such interpreter");
        assert!(format!("{err:#}").contains("/nonexistent/python3"), "{err:#}");
    }

    /// Runs only where `pyoidn` is installed (`pip install pyoidn`): denoising a noisy
    /// flat frame brings it closer to its mean.
    #[test]
    fn where_pyoidn_is_installed_a_noisy_flat_frame_comes_back_flatter() {
        let oidn = Oidn { python: "python3".into(), threads: 2 };
        if oidn.check().is_err() {
            eprintln!("pyoidn is not installed: nothing to check");
            return;
        }
        let (w, h) = (32, 24);
        let mut seed = 0x9e37_79b9_u32;
        let colour: Vec<Vec3> = (0..w * h)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                Vec3::splat(0.5 + (seed % 1000) as f32 / 1000.0 - 0.5)
            })
            .collect();
        let noisy = Noisy {
            colour: colour.clone(),
            albedo: vec![Vec3::splat(0.8); colour.len()],
            normal: vec![Vec3::Z; colour.len()],
        };
        let out = oidn.denoise(&[noisy], w, h).expect("denoise");
        let spread = |v: &[Vec3]| {
            let mean = v.iter().map(|p| p.x).sum::<f32>() / v.len() as f32;
            v.iter().map(|p| (p.x - mean).powi(2)).sum::<f32>() / v.len() as f32
        };
        assert_eq!(out.len(), 1);
        assert!(out[0].ms > 0.0);
        assert!(spread(&out[0].colour) < 0.25 * spread(&colour));
    }
}
