//! `--resolution WxH`: the image size from the command line, overriding the scene file's
//! `[resolution]` on `master`, `demo` and `render`. Checked against the same per-side limit
//! as the file ([`MAX_RESOLUTION`]) so that a size the file may not hold cannot come in
//! through the command line either.

use std::str::FromStr;

use gridlight_actors::state::Resolution;

use crate::scene::build::MAX_RESOLUTION;

/// Why a `--resolution` value was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ResolutionError {
    #[error("`{0}` is not WIDTHxHEIGHT (for example 1920x1080)")]
    Syntax(String),
    #[error("{side} {value} is not in 1..={MAX_RESOLUTION} pixels")]
    OutOfRange { side: &'static str, value: u64 },
}

/// An image size given as `WIDTHxHEIGHT` (`x` or `×`, either case).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResolutionArg(pub Resolution);

impl FromStr for ResolutionArg {
    type Err = ResolutionError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let syntax = || ResolutionError::Syntax(s.to_owned());
        let (w, h) = s.trim().split_once(['x', 'X', '×']).ok_or_else(syntax)?;
        let width = side("width", w).map_err(|e| e.unwrap_or_else(syntax))?;
        let height = side("height", h).map_err(|e| e.unwrap_or_else(syntax))?;
        Ok(Self(Resolution { width, height }))
    }
}

/// One side: `Err(None)` for text that is not a number, `Err(Some(..))` for one out of range.
fn side(name: &'static str, text: &str) -> Result<u32, Option<ResolutionError>> {
    let text = text.trim();
    if text.is_empty() || !text.bytes().all(|b| b.is_ascii_digit()) {
        return Err(None);
    }
    // Digits only: a parse failure can only be an overflow, which is out of range too.
    let value = text.parse::<u64>().unwrap_or(u64::MAX);
    if value == 0 || value > u64::from(MAX_RESOLUTION) {
        return Err(Some(ResolutionError::OutOfRange { side: name, value }));
    }
    Ok(value as u32)
}

/// `resolution` with the command line's override, if any.
pub fn apply(resolution: &mut Resolution, arg: Option<ResolutionArg>) {
    if let Some(ResolutionArg(r)) = arg {
        *resolution = r;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<(u32, u32), String> {
        s.parse::<ResolutionArg>().map(|r| (r.0.width, r.0.height)).map_err(|e| e.to_string())
    }

    #[test]
    fn accepts_the_usual_spellings() {
        assert_eq!(parse("1920x1080"), Ok((1920, 1080)));
        assert_eq!(parse("3840X2160"), Ok((3840, 2160)));
        assert_eq!(parse("640×480"), Ok((640, 480)));
        assert_eq!(parse("16384x1"), Ok((MAX_RESOLUTION, 1)));
    }

    #[test]
    fn bad_values_say_what_is_wrong() {
        let cases = [
            ("0x5", "width 0 is not in 1..=16384"),
            ("5x0", "height 0 is not in 1..=16384"),
            ("100000x100000", "width 100000 is not in 1..=16384"),
            ("640x16385", "height 16385 is not in 1..=16384"),
            ("99999999999999999999999x2", "is not in 1..=16384"),
            ("abc", "`abc` is not WIDTHxHEIGHT"),
            ("640", "`640` is not WIDTHxHEIGHT"),
            ("640x", "`640x` is not WIDTHxHEIGHT"),
            ("-640x480", "`-640x480` is not WIDTHxHEIGHT"),
            ("640x480x2", "`640x480x2` is not WIDTHxHEIGHT"),
        ];
        for (input, expected) in cases {
            let err = parse(input).expect_err(input);
            assert!(err.contains(expected), "{input}: {err}");
        }
    }
}
