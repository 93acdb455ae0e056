//! Line plots of the report, drawn with `plotters` into an RGB buffer and saved as PNG.
//!
//! Text is rasterised by plotters' `ab_glyph` backend with egui's embedded Ubuntu Light
//! font, so plotting needs no system font, fontconfig or display.

use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, Context};
use plotters::prelude::*;

/// One line of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

impl Series {
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.into(), points }
    }
}

/// One panel: axes, title and lines.
#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Fixed y range; `None` fits the data (from 0).
    pub y_range: Option<(f64, f64)>,
}

/// Width of a plot in pixels; each panel is `PANEL_HEIGHT` high.
const WIDTH: u32 = 900;
const PANEL_HEIGHT: u32 = 380;
const FONT: &str = "sans-serif";

static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The font is compiled in; it cannot be invalid.
            let _ = plotters::style::register_font(FONT, style, epaint_default_fonts::UBUNTU_LIGHT);
        }
    });
}

/// Draws `charts` stacked vertically into the PNG at `path`.
pub fn draw(path: &Path, charts: &[Chart]) -> anyhow::Result<()> {
    register_font();
    let height = PANEL_HEIGHT * charts.len().max(1) as u32;
    let mut buf = vec![255u8; (WIDTH * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let panels = root.split_evenly((charts.len().max(1), 1));
        for (chart, area) in charts.iter().zip(panels.iter()) {
            panel(area, chart).map_err(|e| anyhow!("drawing `{}`: {e}", chart.title))?;
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    image::RgbImage::from_raw(WIDTH, height, buf)
        .context("plot buffer size")?
        .save(path)
        .with_context(|| format!("writing {}", path.display()))
}

fn panel(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    chart: &Chart,
) -> Result<(), Box<dyn std::error::Error>> {
    let all = chart.series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for &(x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y1 = y1.max(y);
    }
    if !x0.is_finite() {
        (x0, x1, y1) = (0.0, 1.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let (ylo, yhi) = chart.y_range.unwrap_or((0.0, if y1 > 0.0 { y1 * 1.1 } else { 1.0 }));
    let mut ctx = ChartBuilder::on(area)
        .caption(&chart.title, (FONT, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, ylo..yhi)?;
    ctx.configure_mesh()
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .draw()?;
    for (i, s) in chart.series.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba().stroke_width(2);
        ctx.draw_series(LineSeries::new(s.points.iter().copied(), colour))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour));
        if s.points.len() <= 12 {
            ctx.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
        }
    }
    ctx.configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_is_a_png_with_lines_and_text() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("p.png");
        let chart = Chart {
            title: "test".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series::new("a", vec![(0.0, 0.0), (1.0, 1.0), (2.0, 0.5)])],
            y_range: None,
        };
        draw(&path, &[chart.clone(), chart]).expect("drawn");
        let img = image::open(&path).expect("a png").to_rgb8();
        assert_eq!(img.dimensions(), (WIDTH, 2 * PANEL_HEIGHT));
        let inked = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        assert!(inked > 2000, "only {inked} pixels drawn");
        let grey_text =
            img.pixels().filter(|p| p.0[0] < 100 && p.0[0] == p.0[1] && p.0[1] == p.0[2]).count();
        assert!(grey_text > 200, "no text or axes ({grey_text} dark pixels)");
    }
}
