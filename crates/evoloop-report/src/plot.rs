//! Plots a person would rather look at than read: reference vs output and the control signal,
//! with the parameter swaps marked. PNG via plotters with an embedded DejaVu font, so no system
//! fonts are needed.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// Why a figure was not written.
#[derive(Debug)]
pub enum PlotError {
    /// The drawing library refused the figure: its file and the library's message.
    Draw {
        /// The PNG file.
        path: PathBuf,
        /// What the drawing library said.
        reason: String,
    },
    /// The file could not be created (`evoloop_files::create`'s error, which names it).
    Create(std::io::Error),
    /// The image could not be encoded or written to the file.
    Encode {
        /// The PNG file.
        path: PathBuf,
        /// The encoder's error.
        source: png::EncodingError,
    },
}

impl std::fmt::Display for PlotError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlotError::Draw { path, reason } => write!(f, "{}: {reason}", path.display()),
            PlotError::Create(e) => e.fmt(f),
            PlotError::Encode { path, source } => write!(f, "{}: {source}", path.display()),
        }
    }
}

impl std::error::Error for PlotError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PlotError::Draw { .. } => None,
            PlotError::Create(e) => e.source(),
            PlotError::Encode { source, .. } => Some(source),
        }
    }
}

/// Draw a `size` PNG with `draw` (which presents its root) and write it to `path` through
/// `files::create` (plotters' own file output follows a planted symbolic link).
fn png(
    path: &Path,
    size: (u32, u32),
    draw: impl for<'a> FnOnce(DrawingArea<BitMapBackend<'a>, Shift>) -> Result<(), String>,
) -> Result<(), PlotError> {
    let mut buf = vec![0u8; size.0 as usize * size.1 as usize * 3];
    draw(BitMapBackend::with_buffer(&mut buf, size).into_drawing_area()).map_err(|reason| {
        PlotError::Draw {
            path: path.to_path_buf(),
            reason,
        }
    })?;
    let file = evoloop_files::create(path).map_err(PlotError::Create)?;
    // 8-bit RGB, fast deflate, each row's filter chosen adaptively: the PNG the `image` crate's
    // encoder wrote with its defaults until 2026-12-07, byte for byte.
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    encoder.set_filter(png::FilterType::Sub);
    encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
    // `finish` writes the closing chunk and flushes, so a full disk is an error here and not a
    // cut-off file.
    let encoded = encoder.write_header().and_then(|mut w| {
        w.write_image_data(&buf)?;
        w.finish()
    });
    encoded.map_err(|source| PlotError::Encode {
        path: path.to_path_buf(),
        source,
    })
}

static FONT: Once = Once::new();

fn ensure_font() {
    FONT.call_once(|| {
        // The embedded font is valid TrueType; a failure would only lose the labels.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// A named series.
pub struct Series<'a> {
    /// Legend label.
    pub name: &'a str,
    /// One value per sample of the plot's shared axis (`t`), in the panel's units.
    pub values: &'a [f64],
}

fn bounds(series: &[Series]) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for s in series {
        for v in s.values.iter().filter(|v| v.is_finite()) {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1e-6);
    (lo - pad, hi + pad)
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(140, 86, 75),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

/// One panel of a plot: its series and its y-axis label.
pub struct Panel<'a> {
    /// The series drawn in this panel, coloured in order.
    pub series: &'a [Series<'a>],
    /// The y-axis label (e.g. "position (mm)").
    pub label: &'a str,
}

/// Two stacked panels sharing the time axis `t`: `top` (e.g. reference and outputs) and `bottom`
/// (control), with vertical lines at `marks` (e.g. accepted parameter swaps).
pub fn two_panel_png(
    path: &Path,
    title: &str,
    t: &[f64],
    top: Panel,
    bottom: Panel,
    marks: &[f64],
) -> Result<(), PlotError> {
    stacked_png(path, title, t, &[top, bottom], marks)
}

/// Panels stacked over a shared time axis `t` (1200 px wide; two panels share 800 px, 460 to the
/// first, more panels get 250 px each), with vertical lines at `marks` in every panel.
pub fn stacked_png(
    path: &Path,
    title: &str,
    t: &[f64],
    panels: &[Panel],
    marks: &[f64],
) -> Result<(), PlotError> {
    stacked_png_over(path, title, (t, "t [s]"), panels, marks)
}

/// `stacked_png` over another shared axis: its values and its label (e.g. the experiment).
pub fn stacked_png_over(
    path: &Path,
    title: &str,
    (t, x_label): (&[f64], &str),
    panels: &[Panel],
    marks: &[f64],
) -> Result<(), PlotError> {
    ensure_font();
    let (height, breaks): (u32, Vec<u32>) = match panels.len() {
        2 => (800, vec![460]),
        k => (
            40 + 250 * k as u32,
            (1..k as u32).map(|i| 250 * i).collect(),
        ),
    };
    png(path, (1200, height), |root| {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 24))
            .map_err(|e| e.to_string())?;
        let areas = root.split_by_breakpoints(Vec::<u32>::new(), breaks);
        let t0 = t.first().copied().unwrap_or(0.0);
        let t1 = t.last().copied().unwrap_or(1.0).max(t0 + 1e-9);
        for (area, Panel { series, label }) in areas.iter().zip(panels) {
            let (lo, hi) = bounds(series);
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(t0..t1, lo..hi)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(*label)
                .label_style(("sans-serif", 16))
                .draw()
                .map_err(|e| e.to_string())?;
            for m in marks {
                chart
                    .draw_series(LineSeries::new(
                        [(*m, lo), (*m, hi)],
                        ShapeStyle::from(&RGBColor(255, 127, 14)).stroke_width(2),
                    ))
                    .map_err(|e| e.to_string())?;
            }
            for (i, s) in series.iter().enumerate() {
                let c = COLOURS[i % COLOURS.len()];
                // Thin out very long runs: a PNG 1200 px wide cannot show more than a few thousand points.
                let stride = (t.len() / 6000).max(1);
                chart
                    .draw_series(LineSeries::new(
                        t.iter()
                            .zip(s.values)
                            .step_by(stride)
                            .map(|(a, b)| (*a, *b)),
                        ShapeStyle::from(&c).stroke_width(2),
                    ))
                    .map_err(|e| e.to_string())?
                    .label(s.name)
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 20, y)], c.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 16))
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())
    })
}

/// How an x-y series is drawn.
#[derive(Clone, Copy, PartialEq)]
pub enum Style {
    /// Joined by a line (non-finite points left out).
    Line,
    /// A dot per point, unjoined.
    Points,
}

/// A named x-y series.
pub struct XySeries<'a> {
    /// Legend label; an empty name keeps the series out of the legend.
    pub name: &'a str,
    /// The points' x values.
    pub x: &'a [f64],
    /// The points' y values, one per x; pairs with a non-finite value are not drawn.
    pub y: &'a [f64],
    /// Line or points.
    pub style: Style,
}

/// A named curve owned by its caller: (name, x, y).
pub type Curve = (String, Vec<f64>, Vec<f64>);

impl<'a> XySeries<'a> {
    /// Borrow each curve as a series drawn in `style`.
    pub fn from_curves(curves: &'a [Curve], style: Style) -> Vec<XySeries<'a>> {
        curves
            .iter()
            .map(|(name, x, y)| XySeries { name, x, y, style })
            .collect()
    }
}

/// One x-y chart (lines and/or scatter) with a legend; empty names are left out of it.
pub fn xy_png(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[XySeries],
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    ensure_font();
    png(path, (1000, 700), |root| {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let xs: Vec<Series> = series
            .iter()
            .map(|s| Series {
                name: s.name,
                values: s.x,
            })
            .collect();
        let ys: Vec<Series> = series
            .iter()
            .map(|s| Series {
                name: s.name,
                values: s.y,
            })
            .collect();
        let (x0, x1) = x_range.unwrap_or_else(|| bounds(&xs));
        let (y0, y1) = y_range.unwrap_or_else(|| bounds(&ys));
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let mut legend = false;
        for (i, s) in series.iter().enumerate() {
            let c = COLOURS[i % COLOURS.len()];
            let pts =
                s.x.iter()
                    .zip(s.y)
                    .filter(|(a, b)| a.is_finite() && b.is_finite())
                    .map(|(a, b)| (*a, *b));
            let anno = match s.style {
                Style::Line => chart
                    .draw_series(LineSeries::new(pts, ShapeStyle::from(&c).stroke_width(2)))
                    .map_err(|e| e.to_string())?,
                Style::Points => chart
                    .draw_series(pts.map(|p| Circle::new(p, 3, c.filled())))
                    .map_err(|e| e.to_string())?,
            };
            if !s.name.is_empty() {
                legend = true;
                anno.label(s.name).legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], c.stroke_width(3))
                });
            }
        }
        if legend {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 16))
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())
    })
}

/// A colour map of z over a grid (`z[j][i]` at `x = xs[i]`, `y = ys[j]`), blue (low) to red (high),
/// with the z range in the title: for control surfaces.
pub fn heatmap_png(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    xs: &[f64],
    ys: &[f64],
    z: &[Vec<f64>],
) -> Result<(), PlotError> {
    ensure_font();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in z.iter().flatten().filter(|v| v.is_finite()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if !lo.is_finite() || xs.len() < 2 || ys.len() < 2 {
        return Err(PlotError::Draw {
            path: path.to_path_buf(),
            reason: "heatmap needs a grid of at least 2 x 2 finite values".into(),
        });
    }
    png(path, (900, 760), |root| {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (dx, dy) = (xs[1] - xs[0], ys[1] - ys[0]);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{title} (blue {lo:.3} .. red {hi:.3})"),
                ("sans-serif", 20),
            )
            .margin(14)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(
                xs[0] - dx / 2.0..xs[xs.len() - 1] + dx / 2.0,
                ys[0] - dy / 2.0..ys[ys.len() - 1] + dy / 2.0,
            )
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let colour = |v: f64| {
            let s = if hi > lo { (v - lo) / (hi - lo) } else { 0.5 };
            // Blue -> white -> red.
            let (r, g, b) = if s < 0.5 {
                let t = s * 2.0;
                (t, t, 1.0)
            } else {
                let t = (1.0 - s) * 2.0;
                (1.0, t, t)
            };
            RGBColor((r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8)
        };
        for (j, y) in ys.iter().enumerate() {
            for (i, x) in xs.iter().enumerate() {
                let c = colour(z[j][i]);
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x - dx / 2.0, y - dy / 2.0), (x + dx / 2.0, y + dy / 2.0)],
                        c.filled(),
                    )))
                    .map_err(|e| e.to_string())?;
            }
        }
        root.present().map_err(|e| e.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A figure that cannot be drawn, or whose file cannot be made, says which file and why;
    /// nothing is left at the name.
    #[test]
    fn a_figure_that_cannot_be_written_names_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("h.png");
        let e = heatmap_png(&path, "t", "x", "y", &[0.0], &[0.0], &[vec![1.0]]).unwrap_err();
        assert!(
            matches!(&e, PlotError::Draw { path: p, .. } if p == &path),
            "{e:?}"
        );
        assert!(
            e.to_string().starts_with(&path.display().to_string()),
            "{e}"
        );
        assert!(!path.exists());
        let inside = dir.path().join("missing").join("x.png");
        let series = [XySeries {
            name: "s",
            x: &[0.0, 1.0],
            y: &[0.0, 1.0],
            style: Style::Line,
        }];
        let e = xy_png(&inside, "t", "x", "y", &series, None, None).unwrap_err();
        assert!(matches!(e, PlotError::Create(_)), "{e:?}");
        assert!(e.to_string().contains(&inside.display().to_string()), "{e}");
    }
}
