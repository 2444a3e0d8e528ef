//! Line plots, learning curves and confusion matrices as PNG files
//! (plotters, with an embedded DejaVu Sans font so no system font library
//! is needed).

use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        // DejaVu Sans (Bitstream Vera license, lab/assets/fonts/LICENSE-DejaVu.txt).
        let bytes: &'static [u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// Draws `ys` against `xs` as a line plot into a PNG at `path`.
pub fn line_plot(path: &Path, title: &str, x_label: &str, y_label: &str, xs: &[f64], ys: &[f64]) -> Result<(), String> {
    lines_plot(path, title, x_label, y_label, &[("", xs, ys)])
}

/// Draws several `(legend, xs, ys)` series as lines into a PNG at `path`
/// (a legend is drawn when any name is non-empty).
pub fn lines_plot(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[(&str, &[f64], &[f64])]) -> Result<(), String> {
    let points: Vec<(&str, Vec<(f64, f64)>)> =
        series.iter().map(|(name, xs, ys)| (*name, xs.iter().copied().zip(ys.iter().copied()).collect())).collect();
    xy_plot(path, title, (x_label, y_label), &points, Mark::Line)
}

/// Draws several `(legend, points)` series as dots on linear axes into a
/// PNG at `path`.
pub fn scatter_plot(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[(&str, &[(f64, f64)])]) -> Result<(), String> {
    let points: Vec<(&str, Vec<(f64, f64)>)> = series.iter().map(|(name, p)| (*name, p.to_vec())).collect();
    xy_plot(path, title, (x_label, y_label), &points, Mark::Dot)
}

/// How [`xy_plot`] marks a series.
#[derive(Clone, Copy, PartialEq)]
enum Mark {
    Line,
    Dot,
}

/// Linear axes fitted to the finite points of every series (a 5 % margin;
/// lines span the x range exactly), one colour per series.
fn xy_plot(
    path: &Path,
    title: &str,
    (x_label, y_label): (&str, &str),
    series: &[(&str, Vec<(f64, f64)>)],
    mark: Mark,
) -> Result<(), String> {
    register_font();
    let finite: Vec<Vec<(f64, f64)>> =
        series.iter().map(|(_, p)| p.iter().filter(|(x, y)| x.is_finite() && y.is_finite()).copied().collect()).collect();
    let all: Vec<(f64, f64)> = finite.iter().flatten().copied().collect();
    if all.is_empty() {
        return Err("nothing to plot: no finite values".into());
    }
    let (x0, x1) = all.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| (a.min(*x), b.max(*x)));
    let (y0, y1) = all.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, y)| (a.min(*y), b.max(*y)));
    let pad = |a: f64, b: f64| if b > a { (b - a) * 0.05 } else { a.abs().max(1.0) * 0.05 };
    let py = pad(y0, y1);
    let px = match mark {
        Mark::Dot => pad(x0, x1),
        Mark::Line if x1 > x0 => 0.0,
        Mark::Line => 0.5,
    };
    let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (900, if mark == Mark::Dot { 600 } else { 540 })).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(80)
        .build_cartesian_2d((x0 - px)..(x1 + px), (y0 - py)..(y1 + py))
        .map_err(|e| err(&e))?;
    chart.configure_mesh().x_desc(x_label).y_desc(y_label).label_style(("sans-serif", 14)).draw().map_err(|e| err(&e))?;
    let colours = [BLUE, RED, GREEN, MAGENTA, BLACK];
    for (k, ((name, _), points)) in series.iter().zip(finite).enumerate() {
        let colour = colours[k % colours.len()];
        match mark {
            Mark::Line => {
                let drawn = chart.draw_series(LineSeries::new(points, colour)).map_err(|e| err(&e))?;
                if !name.is_empty() {
                    drawn.label(*name).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
                }
            }
            Mark::Dot => {
                let drawn =
                    chart.draw_series(points.into_iter().map(|p| Circle::new(p, 3, colour.mix(0.6).filled()))).map_err(|e| err(&e))?;
                drawn.label(*name).legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
            }
        }
    }
    if series.iter().any(|(n, _)| !n.is_empty()) {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Draws labelled points on log-log axes into a PNG at `path`; highlighted
/// points are drawn filled in red. Non-positive values are clamped to
/// `floor` so exact references still appear.
pub fn scatter_loglog(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[(f64, f64, String, bool)],
    floor: f64,
) -> Result<(), String> {
    register_font();
    let pts: Vec<(f64, f64, &str, bool)> =
        points.iter().filter(|p| p.0.is_finite() && p.1.is_finite()).map(|p| (p.0.max(floor), p.1.max(floor), p.2.as_str(), p.3)).collect();
    if pts.is_empty() {
        return Err("nothing to plot: no finite values".into());
    }
    let (x0, x1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y0, y1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(80)
        .build_cartesian_2d((x0 / 1.5..x1 * 1.5).log_scale(), (y0 / 10.0..y1 * 10.0).log_scale())
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    chart
        .draw_series(pts.iter().map(|&(x, y, label, hi)| {
            let style = if hi { RED.filled() } else { BLUE.stroke_width(2) };
            EmptyElement::at((x, y)) + Circle::new((0, 0), 5, style) + Text::new(label.to_string(), (8, -6), ("sans-serif", 13))
        }))
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// One learner's learning curve for [`learning_curve_plot`]: its name and,
/// per training-set size, `(examples, precision %, recall %)`.
pub type Curve<'a> = (&'a str, &'a [(f64, f64, f64)]);

/// Draws learning curves into a PNG at `path`: training examples on a log
/// axis labelled in examples, one colour per learner, precision as a solid
/// line through filled dots and recall as a dashed line through open
/// squares, so a learner's two curves read as a pair.
pub fn learning_curve_plot(path: &Path, title: &str, y_label: &str, curves: &[Curve]) -> Result<(), String> {
    register_font();
    let finite = |p: &&(f64, f64, f64)| p.0 > 0.0 && p.0.is_finite() && p.1.is_finite() && p.2.is_finite();
    let all: Vec<(f64, f64, f64)> = curves.iter().flat_map(|(_, ps)| ps.iter().filter(finite).copied()).collect();
    if all.is_empty() {
        return Err("nothing to plot: no finite values".into());
    }
    let (x0, x1) = all.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y0, y1) = all.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.1).min(p.2), b.max(p.1).max(p.2)));
    let py = if y1 > y0 { (y1 - y0) * 0.08 } else { 1.0 };
    let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d((x0 / 1.3..x1 * 1.3).log_scale(), (y0 - py)..(y1 + py))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("training examples")
        .y_desc(y_label)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    let colours = [BLUE, RED, GREEN, MAGENTA, BLACK];
    for (k, (name, points)) in curves.iter().enumerate() {
        let colour = colours[k % colours.len()];
        let points: Vec<(f64, f64, f64)> = points.iter().filter(finite).copied().collect();
        let precision: Vec<(f64, f64)> = points.iter().map(|p| (p.0, p.1)).collect();
        let recall: Vec<(f64, f64)> = points.iter().map(|p| (p.0, p.2)).collect();
        chart
            .draw_series(LineSeries::new(precision.clone(), colour.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(format!("{name}: precision"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        chart.draw_series(precision.iter().map(|p| Circle::new(*p, 4, colour.filled()))).map_err(|e| err(&e))?;
        chart
            .draw_series(DashedLineSeries::new(recall.clone(), 8, 5, colour.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(format!("{name}: recall"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 8, y)], colour.stroke_width(2)));
        chart
            .draw_series(recall.iter().map(|p| EmptyElement::at(*p) + Rectangle::new([(-4, -4), (4, 4)], colour.stroke_width(2))))
            .map_err(|e| err(&e))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Draws a confusion matrix (`counts[truth][predicted]`) as a grid of cells
/// shaded by the fraction of each true class, with the counts written in,
/// into a PNG at `path`.
pub fn confusion_plot(path: &Path, title: &str, labels: &[&str], counts: &[Vec<usize>]) -> Result<(), String> {
    register_font();
    let n = labels.len();
    if n == 0 || counts.len() != n || counts.iter().any(|r| r.len() != n) {
        return Err(format!("cannot draw {}: a confusion matrix needs {n} × {n} counts", path.display()));
    }
    let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (760, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(96)
        // plotters' integer ranges include their end: 0..n-1 gives n cells.
        .build_cartesian_2d((0..n - 1).into_segmented(), (0..n - 1).into_segmented())
        .map_err(|e| err(&e))?;
    let name = |v: &SegmentValue<usize>| match v {
        SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => labels.get(*i).map_or(String::new(), |s| s.to_string()),
        SegmentValue::Last => String::new(),
    };
    // Rows run top to bottom in label order: the y axis is flipped.
    let row_name = |v: &SegmentValue<usize>| match v {
        SegmentValue::CenterOf(i) | SegmentValue::Exact(i) if *i < n => labels[n - 1 - i].to_string(),
        _ => String::new(),
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("predicted")
        .y_desc("true class")
        .x_label_formatter(&name)
        .y_label_formatter(&row_name)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    for (t, row) in counts.iter().enumerate() {
        let total = row.iter().sum::<usize>().max(1) as f64;
        for (p, &k) in row.iter().enumerate() {
            let share = k as f64 / total;
            let y = n - 1 - t;
            let shade = RGBColor((255.0 * (1.0 - 0.8 * share)) as u8, (255.0 * (1.0 - 0.6 * share)) as u8, 255);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(SegmentValue::Exact(p), SegmentValue::Exact(y)), (SegmentValue::Exact(p + 1), SegmentValue::Exact(y + 1))],
                    shade.filled(),
                )))
                .map_err(|e| err(&e))?;
            let ink = if share > 0.6 { WHITE } else { BLACK };
            chart
                .draw_series(std::iter::once(Text::new(
                    k.to_string(),
                    (SegmentValue::CenterOf(p), SegmentValue::CenterOf(y)),
                    ("sans-serif", 16).into_font().color(&ink),
                )))
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// One panel of [`heatmaps_plot`]: `values[i * ys.len() + k]` at `xs[i]`, `ys[k]`.
pub struct Heatmap<'a> {
    /// The panel's title.
    pub title: String,
    /// Column positions (increasing, evenly spaced).
    pub xs: &'a [f64],
    /// Row positions (increasing; drawn on a log axis, so positive).
    pub ys: &'a [f64],
    /// The values.
    pub values: &'a [f64],
}

/// Draws heatmaps side by side in a grid of `columns` (a Q-scan's panels),
/// with a log y axis, coloured by viridis from 0 to `max` (values above
/// are saturated), into a PNG at `path`.
pub fn heatmaps_plot(path: &Path, title: &str, labels: (&str, &str), panels: &[Heatmap], columns: usize, max: f64) -> Result<(), String> {
    register_font();
    let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
    check_heatmaps(path, panels)?;
    let columns = columns.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(columns);
    let root = BitMapBackend::new(path, (520 * columns as u32, 420 * rows as u32 + 40)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(|e| err(&e))?;
    for (area, p) in root.split_evenly((rows, columns)).iter().zip(panels) {
        draw_heatmap(area, p, labels, max).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// A named line: `(legend, xs, ys)`.
pub type Line<'a> = (&'a str, &'a [f64], &'a [f64]);

/// Draws `(legend, xs, ys)` lines across the top (a whitened time series
/// and a fit over it) and heatmaps side by side below (the Q-scans of the
/// data and the residual), into a PNG at `path`.
pub fn lines_over_heatmaps_plot(
    path: &Path,
    title: &str,
    (lines, line_labels): (&[Line], (&str, &str)),
    (panels, heatmap_labels): (&[Heatmap], (&str, &str)),
    max: f64,
) -> Result<(), String> {
    register_font();
    let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
    check_heatmaps(path, panels)?;
    let points: Vec<(f64, f64)> = lines
        .iter()
        .flat_map(|(_, xs, ys)| xs.iter().copied().zip(ys.iter().copied()))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if points.is_empty() {
        return Err(err(&"no finite line values"));
    }
    let (x0, x1) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| (a.min(*x), b.max(*x)));
    let y = points.iter().fold(0.0f64, |m, (_, y)| m.max(y.abs())).max(1e-12) * 1.05;
    let columns = panels.len().max(1);
    let root = BitMapBackend::new(path, (520 * columns as u32, 760)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(|e| err(&e))?;
    let (top, bottom) = root.split_vertically(320);
    let mut chart = ChartBuilder::on(&top)
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(x0..x1.max(x0 + 1e-9), -y..y)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(line_labels.0)
        .y_desc(line_labels.1)
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    let colours = [RGBColor(150, 150, 150), RED, BLUE];
    for (k, (name, xs, ys)) in lines.iter().enumerate() {
        let colour = colours[k % colours.len()];
        let line = xs.iter().copied().zip(ys.iter().copied()).filter(|(x, y)| x.is_finite() && y.is_finite());
        let stroke = if k == 0 { colour.stroke_width(1) } else { colour.stroke_width(2) };
        chart
            .draw_series(LineSeries::new(line, stroke))
            .map_err(|e| err(&e))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    for (area, p) in bottom.split_evenly((1, columns)).iter().zip(panels) {
        draw_heatmap(area, p, heatmap_labels, max).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

fn check_heatmaps(path: &Path, panels: &[Heatmap]) -> Result<(), String> {
    for p in panels {
        if p.xs.len() < 2 || p.ys.len() < 2 || p.values.len() != p.xs.len() * p.ys.len() || p.ys[0] <= 0.0 {
            return Err(format!("cannot draw {}: panel `{}` needs at least 2 × 2 values on a positive y axis", path.display(), p.title));
        }
    }
    Ok(())
}

/// One heatmap panel on a log y axis, viridis from 0 to `max`.
fn draw_heatmap<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Heatmap,
    (x_label, y_label): (&str, &str),
    max: f64,
) -> Result<(), String> {
    use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let (x0, x1) = (p.xs[0], 2.0 * p.xs[p.xs.len() - 1] - p.xs[p.xs.len() - 2]);
    let (y0, y1) = (p.ys[0], p.ys[p.ys.len() - 1]);
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
        .map_err(|e| err(&e))?;
    chart.configure_mesh().disable_mesh().x_desc(x_label).y_desc(y_label).label_style(("sans-serif", 13)).draw().map_err(|e| err(&e))?;
    let ny = p.ys.len();
    let dx = p.xs[1] - p.xs[0];
    // Row edges halfway between rows (geometric mean on the log axis).
    let edge = |k: usize| {
        if k == 0 {
            y0
        } else if k == ny {
            y1
        } else {
            (p.ys[k - 1] * p.ys[k]).sqrt()
        }
    };
    let cells = p.xs.iter().enumerate().flat_map(|(i, x)| {
        (0..ny).map(move |k| {
            let v = (p.values[i * ny + k] / max).clamp(0.0, 1.0);
            Rectangle::new([(*x, edge(k)), (x + dx, edge(k + 1))], ViridisRGB.get_color(v as f32).filled())
        })
    });
    chart.draw_series(cells).map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The full glitch run's curves draw into a PNG; curves without a
    /// finite point are refused. (Set GWML_KEEP_PLOTS to keep the PNG in
    /// the temporary directory and look at it.)
    #[test]
    fn learning_curves_are_drawn_and_empty_ones_refused() {
        let cnn = [(500.0, 90.0, 86.0), (1500.0, 94.7, 89.7), (5000.0, 96.4, 94.1), (15000.0, 96.7, 94.7), (50000.0, 97.2, 95.8)];
        let net = [(500.0, 95.4, 91.3), (1500.0, 95.9, 93.7), (5000.0, 97.2, 95.9), (15000.0, 98.0, 96.4), (50000.0, 98.4, 97.4)];
        let path = std::env::temp_dir().join(format!("gwml-learning-curve-{}.png", std::process::id()));
        learning_curve_plot(&path, "learning curves", "macro %", &[("CNN", &cnn), ("template net", &net)]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000, "{} bytes", bytes.len());
        if std::env::var_os("GWML_KEEP_PLOTS").is_none() {
            let _ = std::fs::remove_file(&path);
        }
        let nan = [(500.0, f64::NAN, 1.0)];
        assert!(learning_curve_plot(&path, "t", "y", &[("x", &nan)]).unwrap_err().contains("nothing to plot"));
    }
}
