//! Portable float maps (`.pfm`): linear f32 RGB, the simplest lossless format that both
//! this binary and a Python script (`scripts/oidn-anchor.py`) read and write without a
//! library. Rows are stored bottom to top; a negative scale means little-endian.

use std::path::Path;

use anyhow::{bail, Context};
use glam::Vec3;

/// Writes `pixels` (`width × height`, top row first) as a little-endian PFM.
pub fn write(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> anyhow::Result<()> {
    anyhow::ensure!(
        pixels.len() == width as usize * height as usize,
        "{width}x{height} image given {} pixels",
        pixels.len()
    );
    let mut bytes = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    bytes.reserve(pixels.len() * 12);
    for row in pixels.chunks_exact(width.max(1) as usize).rev() {
        for p in row {
            let p = if p.is_finite() { *p } else { Vec3::ZERO };
            p.to_array().iter().for_each(|c| bytes.extend_from_slice(&c.to_le_bytes()));
        }
    }
    std::fs::write(path, bytes).with_context(|| format!("writing `{}`", path.display()))
}

/// Reads an RGB PFM of either byte order; returns its size and pixels, top row first.
pub fn read(path: &Path) -> anyhow::Result<(u32, u32, Vec<Vec3>)> {
    let bytes = std::fs::read(path).with_context(|| format!("reading `{}`", path.display()))?;
    parse(&bytes).with_context(|| format!("`{}` is not an RGB PFM", path.display()))
}

fn parse(bytes: &[u8]) -> anyhow::Result<(u32, u32, Vec<Vec3>)> {
    // Three whitespace-separated header lines: "PF", "W H", the scale.
    let mut fields = Vec::new();
    let mut at = 0;
    while fields.len() < 4 {
        while bytes.get(at).is_some_and(u8::is_ascii_whitespace) {
            at += 1;
        }
        let start = at;
        while bytes.get(at).is_some_and(|b| !b.is_ascii_whitespace()) {
            at += 1;
        }
        if start == at {
            bail!("the header ends early");
        }
        fields.push(std::str::from_utf8(&bytes[start..at]).context("a header field")?);
    }
    if fields[0] != "PF" {
        bail!("its magic is `{}`, not `PF`", fields[0]);
    }
    let width: u32 = fields[1].parse().context("the width")?;
    let height: u32 = fields[2].parse().context("the height")?;
    let scale: f32 = fields[3].parse().context("the scale")?;
    let data = &bytes[at + 1..];
    let n = width as usize * height as usize;
    if data.len() != n * 12 {
        bail!("{width}x{height} needs {} bytes of data, it has {}", n * 12, data.len());
    }
    let value = |c: &[u8]| {
        let c = c.try_into().expect("chunks of 4");
        if scale < 0.0 {
            f32::from_le_bytes(c)
        } else {
            f32::from_be_bytes(c)
        }
    };
    let mut rows: Vec<Vec3> = data
        .chunks_exact(12)
        .map(|p| Vec3::new(value(&p[0..4]), value(&p[4..8]), value(&p[8..12])))
        .collect();
    // Bottom row first in the file.
    let mut pixels = Vec::with_capacity(n);
    for row in rows.chunks_exact_mut(width.max(1) as usize).rev() {
        pixels.extend_from_slice(row);
    }
    Ok((width, height, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_comes_back_as_written_top_row_first() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.pfm");
        let pixels: Vec<Vec3> =
            (0..6).map(|i| Vec3::new(i as f32, -0.5, 1e-3 * i as f32)).collect();
        write(&path, 3, 2, &pixels).expect("write");
        let bytes = std::fs::read(&path).expect("read back");
        // The file's first pixel is the bottom row's first: pixel 3.
        let header = b"PF\n3 2\n-1.0\n".len();
        assert_eq!(&bytes[header..header + 4], &3.0f32.to_le_bytes());
        assert_eq!(read(&path).expect("parse"), (3, 2, pixels));
    }

    #[test]
    fn a_big_endian_map_reads_and_a_short_one_is_refused() {
        let mut bytes = b"PF\n1 1\n1.0\n".to_vec();
        [1.0f32, 2.0, 3.0].iter().for_each(|c| bytes.extend_from_slice(&c.to_be_bytes()));
        assert_eq!(parse(&bytes).expect("parse").2, vec![Vec3::new(1.0, 2.0, 3.0)]);
        let err = parse(&bytes[..bytes.len() - 1]).expect_err("short");
        assert!(err.to_string().contains("needs 12 bytes"), "{err}");
        assert!(parse(b"P6\n1 1\n255\nabc").is_err());
    }
}
