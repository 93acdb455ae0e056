//! `--resolution WxH` and `--scale F`: the image size from the command line on `master`,
//! `demo` and `render`. `--resolution` overrides the scene file's `[resolution]`; `--scale`
//! then multiplies whichever size that left (each side rounded, at least one pixel), so
//! that `--scale 0.5` renders a 1920×1080 scene at 960×540 without naming its size. Both
//! are checked against the same per-side limit as the file ([`MAX_RESOLUTION`]) so that a
//! size the file may not hold cannot come in through the command line either.

use std::str::FromStr;

use gridlight_actors::state::Resolution;

use crate::scene::build::MAX_RESOLUTION;

/// Why a `--resolution` value was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ResolutionError {
    #[error("`{0}` is not WIDTHxHEIGHT (for example 1920x1080)")]
    Syntax(String),
    #[error("{side} {value} is not in 1..={MAX_RESOLUTION} pixels")]
    OutOfRange { side: &'static str, value: u64 },
    #[error("`{0}` is not a scale factor above 0 and at most {MAX_SCALE} (for example 0.5)")]
    Scale(String),
    #[error("--scale {scale} makes the {side} {value} pixels, over {MAX_RESOLUTION}")]
    ScaledOutOfRange { scale: f32, side: &'static str, value: u64 },
    #[error("`{0}` is not WIDTHxHEIGHT (for example 1920x1080) or `window`")]
    SizeSyntax(String),
}

/// The largest `--scale`: a 1×1 scene could not grow past the per-side limit anyway.
pub const MAX_SCALE: f32 = MAX_RESOLUTION as f32;

/// A factor on both sides of the image, `0 < F <= MAX_SCALE`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleArg(pub f32);

impl FromStr for ScaleArg {
    type Err = ResolutionError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().parse::<f32>() {
            Ok(f) if f.is_finite() && f > 0.0 && f <= MAX_SCALE => Ok(Self(f)),
            _ => Err(ResolutionError::Scale(s.to_owned())),
        }
    }
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

/// `--resolution` on `master` and `demo`: a size, or `window` (the render size follows the
/// window's picture area in physical pixels, times `--scale`; see `window::follow`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SizeArg {
    Fixed(ResolutionArg),
    Window,
}

impl SizeArg {
    /// The fixed size, if one was given.
    pub fn fixed(self) -> Option<ResolutionArg> {
        match self {
            Self::Fixed(r) => Some(r),
            Self::Window => None,
        }
    }
}

impl FromStr for SizeArg {
    type Err = ResolutionError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.trim().eq_ignore_ascii_case("window") {
            return Ok(Self::Window);
        }
        match s.parse::<ResolutionArg>() {
            Ok(r) => Ok(Self::Fixed(r)),
            Err(ResolutionError::Syntax(_)) => Err(ResolutionError::SizeSyntax(s.to_owned())),
            Err(e) => Err(e),
        }
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

/// `resolution` with the command line's override, if any, then scaled by `scale`; a
/// scaled side over the limit is refused.
pub fn apply(
    resolution: &mut Resolution,
    arg: Option<ResolutionArg>,
    scale: Option<ScaleArg>,
) -> Result<(), ResolutionError> {
    if let Some(ResolutionArg(r)) = arg {
        *resolution = r;
    }
    if let Some(ScaleArg(f)) = scale {
        let scaled = |side: &'static str, value: u32| {
            let value = (f64::from(value) * f64::from(f)).round().max(1.0) as u64;
            if value > u64::from(MAX_RESOLUTION) {
                return Err(ResolutionError::ScaledOutOfRange { scale: f, side, value });
            }
            Ok(value as u32)
        };
        *resolution = Resolution {
            width: scaled("width", resolution.width)?,
            height: scaled("height", resolution.height)?,
        };
    }
    Ok(())
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
    fn scale_multiplies_the_size_left_by_resolution() {
        let base = Resolution { width: 1920, height: 1080 };
        let run = |arg: Option<&str>, scale: &str| {
            let mut r = base;
            let arg = arg.map(|a| a.parse::<ResolutionArg>().expect("size"));
            apply(&mut r, arg, Some(scale.parse().expect("scale"))).map(|()| (r.width, r.height))
        };
        assert_eq!(run(None, "0.5"), Ok((960, 540)));
        assert_eq!(run(None, "2"), Ok((3840, 2160)));
        assert_eq!(run(Some("640x480"), "1.5"), Ok((960, 720)));
        // Rounded to the nearest pixel, never below one.
        assert_eq!(run(Some("3x3"), "0.5"), Ok((2, 2)));
        assert_eq!(run(Some("640x480"), "0.0001"), Ok((1, 1)));
        let mut r = base;
        apply(&mut r, None, None).expect("no flags");
        assert_eq!(r, base, "without flags the scene's size stays");
        let err = run(None, "10").expect_err("19200 is over the limit").to_string();
        assert!(err.contains("--scale 10") && err.contains("width 19200"), "{err}");
    }

    #[test]
    fn the_size_flag_takes_a_size_or_window() {
        assert_eq!("Window".parse::<SizeArg>(), Ok(SizeArg::Window));
        let fixed = "800x600".parse::<SizeArg>().expect("size").fixed().expect("fixed");
        assert_eq!(fixed.0, Resolution { width: 800, height: 600 });
        let err = "windows".parse::<SizeArg>().expect_err("not a size").to_string();
        assert!(err.contains("is not WIDTHxHEIGHT") && err.contains("`window`"), "{err}");
        let err = "0x5".parse::<SizeArg>().expect_err("out of range").to_string();
        assert!(err.contains("width 0 is not in 1..=16384"), "{err}");
    }

    #[test]
    fn bad_scales_are_refused() {
        for bad in ["0", "-1", "abc", "", "nan", "inf", "16385", "0x2"] {
            let err = bad.parse::<ScaleArg>().expect_err(bad).to_string();
            assert!(err.contains("is not a scale factor"), "{bad}: {err}");
        }
        assert_eq!("0.25".parse::<ScaleArg>(), Ok(ScaleArg(0.25)));
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
