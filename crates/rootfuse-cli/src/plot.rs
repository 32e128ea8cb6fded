//! Plots for the demo report, each written as PNG and SVG.
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// Registers the embedded DejaVu Sans as plotters' `sans-serif` (once per process), so text
/// renders without system font libraries.
fn fonts() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err("the embedded font could not be loaded".into())
    }
}

const SIZE: (u32, u32) = (1000, 480);

/// Width of the legend column right of the demo's charts, pixels: the legend never covers a
/// bar or a curve.
const LEGEND_WIDTH: u32 = 260;

/// Checks before drawing that `path` can be written: plotters reports a missing or
/// read-only folder only when it saves, as a debug dump of nested errors.
fn writable(path: &Path) -> Result<(), String> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!(
            "{}: the folder {} does not exist: create it or write the plot elsewhere",
            path.display(),
            dir.display()
        ));
    }
    let probe = dir.join(format!(".rootfuse-plot-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| {
            format!(
                "{}: cannot write in {}: {e}: choose a folder you can write to",
                path.display(),
                dir.display()
            )
        })?;
    // The probe is ours and empty; failing to remove it changes nothing the user asked for.
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// The legend of a demo chart in its own column: a swatch (a line or a box) and a name per
/// entry, top-aligned.
fn side_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(&str, RGBColor)],
    line: bool,
) -> Drawn
where
    DB::ErrorType: 'static,
{
    for (i, (name, color)) in entries.iter().enumerate() {
        let y = 56 + 22 * i as i32;
        if line {
            area.draw(&PathElement::new(
                vec![(8, y), (30, y)],
                color.stroke_width(3),
            ))?;
        } else {
            area.draw(&Rectangle::new([(10, y - 6), (24, y + 6)], color.filled()))?;
        }
        area.draw(&Text::new(
            name.to_string(),
            (38, y - 7),
            ("sans-serif", 13),
        ))?;
    }
    Ok(())
}

/// The frame every plot shares: white background left to the caller, title, margins and the
/// x axis label area; `y_label_area` (pixels) depends on the width of the y tick labels.
fn titled<'a, 'b, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    title: &str,
    y_label_area: u32,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(y_label_area);
    builder
}

type Drawn = Result<(), Box<dyn std::error::Error>>;

/// Twelve distinguishable colours (more than the registry has filters: no two filters of a
/// chart share one).
const COLORS: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
    RGBColor(255, 187, 120),
];

fn palette(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

fn finite_max<'a>(values: impl Iterator<Item = &'a f64>) -> f64 {
    values
        .copied()
        .filter(|v| v.is_finite())
        .fold(1.0f64, f64::max)
}

/// Error over time (degrees) of several filters on one recording sampled at `rate` Hz.
/// Returns the PNG's file name.
pub fn error_over_time(
    dir: &Path,
    stem: &str,
    title: &str,
    rate: f64,
    series: &[(String, Vec<f64>)],
) -> Result<String, String> {
    fonts()?;
    writable(&dir.join(format!("{stem}.png")))?;
    let y_max = finite_max(series.iter().flat_map(|(_, v)| v)) * 1.05;
    let t_max = series.iter().map(|(_, v)| v.len()).max().unwrap_or(1) as f64 / rate;
    let (png, svg) = (
        dir.join(format!("{stem}.png")),
        dir.join(format!("{stem}.svg")),
    );
    draw_time(
        BitMapBackend::new(&png, SIZE).into_drawing_area(),
        title,
        rate,
        (t_max, y_max),
        series,
    )
    .map_err(|e| format!("{}: {e}", png.display()))?;
    draw_time(
        SVGBackend::new(&svg, SIZE).into_drawing_area(),
        title,
        rate,
        (t_max, y_max),
        series,
    )
    .map_err(|e| format!("{}: {e}", svg.display()))?;
    Ok(format!("{stem}.png"))
}

fn draw_time<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    rate: f64,
    (t_max, y_max): (f64, f64),
    series: &[(String, Vec<f64>)],
) -> Drawn
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (plot, side) = root.split_horizontally(SIZE.0 - LEGEND_WIDTH);
    let mut chart = titled(&plot, title, 52).build_cartesian_2d(0.0..t_max, 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("total error (deg)")
        .draw()?;
    for (i, (_, values)) in series.iter().enumerate() {
        let points = values
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(k, v)| (k as f64 / rate, *v));
        chart.draw_series(LineSeries::new(points, palette(i).stroke_width(2)))?;
    }
    let entries: Vec<(&str, RGBColor)> = series
        .iter()
        .enumerate()
        .map(|(i, (name, _))| (name.as_str(), palette(i)))
        .collect();
    side_legend(&side, &entries, true)?;
    root.present()?;
    Ok(())
}

/// Mean error per scenario (degrees), one group of bars per scenario. Returns the PNG's name.
pub fn error_per_scenario(
    dir: &Path,
    stem: &str,
    scenarios: &[&str],
    rows: &[(String, Vec<f64>)],
) -> Result<String, String> {
    fonts()?;
    writable(&dir.join(format!("{stem}.png")))?;
    let y_max = finite_max(rows.iter().flat_map(|(_, v)| v)) * 1.1;
    let (png, svg) = (
        dir.join(format!("{stem}.png")),
        dir.join(format!("{stem}.svg")),
    );
    draw_bars(
        BitMapBackend::new(&png, SIZE).into_drawing_area(),
        scenarios,
        y_max,
        rows,
    )
    .map_err(|e| format!("{}: {e}", png.display()))?;
    draw_bars(
        SVGBackend::new(&svg, SIZE).into_drawing_area(),
        scenarios,
        y_max,
        rows,
    )
    .map_err(|e| format!("{}: {e}", svg.display()))?;
    Ok(format!("{stem}.png"))
}

fn draw_bars<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    scenarios: &[&str],
    y_max: f64,
    rows: &[(String, Vec<f64>)],
) -> Drawn
where
    DB::ErrorType: 'static,
{
    let groups = scenarios.len();
    // Each scenario is a group of one bar per filter plus a gap.
    let width = rows.len().max(1) as f64 + 1.0;
    root.fill(&WHITE)?;
    let (plot, side) = root.split_horizontally(SIZE.0 - LEGEND_WIDTH);
    let mut chart = titled(&plot, "mean total RMSE per scenario (9D)", 52)
        .build_cartesian_2d(0.0..(groups as f64 * width), 0.0..y_max)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc("deg")
        .draw()?;
    // Category names above their groups: tick positions of a numeric axis would miss them.
    chart.draw_series(scenarios.iter().enumerate().map(|(g, name)| {
        Text::new(
            name.to_string(),
            (g as f64 * width + 0.5, y_max * 0.97),
            ("sans-serif", 15),
        )
    }))?;
    for (i, (_, values)) in rows.iter().enumerate() {
        let color = palette(i);
        let bars = values.iter().enumerate().map(|(g, v)| {
            let x0 = g as f64 * width + 0.5 + i as f64;
            Rectangle::new([(x0, 0.0), (x0 + 0.9, v.min(y_max))], color.filled())
        });
        chart.draw_series(bars)?;
    }
    let entries: Vec<(&str, RGBColor)> = rows
        .iter()
        .enumerate()
        .map(|(i, (name, _))| (name.as_str(), palette(i)))
        .collect();
    side_legend(&side, &entries, false)?;
    root.present()?;
    Ok(())
}

/// One line of [`stress_trace`]: a form in one precision.
pub struct TraceSeries {
    /// Form name.
    pub form: String,
    /// Double precision (drawn dashed) or single.
    pub f64: bool,
    /// `(step, relative error)`.
    pub points: Vec<(u64, f64)>,
}

/// Relative error against the reference over the steps of one stress scenario, log scale,
/// one line per form and precision (f32 solid, f64 dashed). Written to `path` as PNG or SVG
/// by its extension.
pub fn stress_trace(path: &Path, title: &str, series: &[TraceSeries]) -> Result<(), String> {
    fonts()?;
    writable(path)?;
    let positive = || {
        series
            .iter()
            .flat_map(|l| &l.points)
            .map(|p| p.1)
            .filter(|e| e.is_finite() && *e > 0.0)
    };
    // Exact agreement (error 0) is drawn at the floor of the axis.
    let y_min = positive().fold(f64::INFINITY, f64::min).max(1e-17) / 2.0;
    let y_max = positive().fold(1e-16, f64::max) * 2.0;
    let x_max = series
        .iter()
        .flat_map(|l| &l.points)
        .map(|p| p.0)
        .max()
        .unwrap_or(1) as f64;
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let drawn = if svg {
        let root = SVGBackend::new(path, SIZE).into_drawing_area();
        draw_trace(root, title, (x_max, y_min, y_max), series)
    } else {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        draw_trace(root, title, (x_max, y_min, y_max), series)
    };
    drawn.map_err(|e| format!("{}: {e}", path.display()))
}

fn draw_trace<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    (x_max, y_min, y_max): (f64, f64, f64),
    series: &[TraceSeries],
) -> Drawn
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let mut chart =
        titled(&root, title, 64).build_cartesian_2d(0.0..x_max, (y_min..y_max).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("step")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_desc("relative error vs reference")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    let forms: Vec<&str> =
        series
            .iter()
            .map(|l| l.form.as_str())
            .fold(Vec::new(), |mut seen, n| {
                if !seen.contains(&n) {
                    seen.push(n);
                }
                seen
            });
    for line in series {
        let color = palette(forms.iter().position(|f| *f == line.form).unwrap_or(0));
        let label = format!("{} {}", line.form, if line.f64 { "f64" } else { "f32" });
        let clamp = |e: f64| if e.is_finite() { e.max(y_min) } else { y_max };
        let xy: Vec<(f64, f64)> = line
            .points
            .iter()
            .map(|&(k, e)| (k as f64, clamp(e)))
            .collect();
        let style = color.stroke_width(2);
        let drawn = if line.f64 {
            chart.draw_series(DashedLineSeries::new(xy, 6, 4, style))?
        } else {
            chart.draw_series(LineSeries::new(xy, style))?
        };
        drawn.label(label).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
        });
    }
    chart
        .configure_series_labels()
        // The middle of a stress run is where the curves are flat: keep the legend there.
        .position(SeriesLabelPosition::LowerMiddle)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// One measured line of [`throughput_sweep`]: a label and `(channels, channel-updates/s)`.
pub struct SweepLine {
    /// Legend text.
    pub label: String,
    /// Points, channels ascending.
    pub points: Vec<(f64, f64)>,
}

/// Throughput against the number of channels (both axes logarithmic), with a vertical
/// marker where the channels' state fills each cache level (`(name, channels)`). Written to
/// `path` as PNG or SVG by its extension.
pub fn throughput_sweep(
    path: &Path,
    title: &str,
    lines: &[SweepLine],
    caches: &[(String, f64)],
) -> Result<(), String> {
    fonts()?;
    writable(path)?;
    let all = || lines.iter().flat_map(|l| &l.points);
    let x_min = all().map(|p| p.0).fold(f64::INFINITY, f64::min).max(1.0) / 1.5;
    let x_max = all().map(|p| p.0).fold(1.0, f64::max) * 1.5;
    let y_max = finite_max(all().map(|p| &p.1)) * 2.0;
    let y_min = all()
        .map(|p| p.1)
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold(f64::INFINITY, f64::min)
        .min(y_max / 4.0)
        / 2.0;
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let range = (x_min, x_max, y_min, y_max);
    let drawn = if svg {
        let root = SVGBackend::new(path, SIZE).into_drawing_area();
        draw_sweep(root, title, range, lines, caches)
    } else {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        draw_sweep(root, title, range, lines, caches)
    };
    drawn.map_err(|e| format!("{}: {e}", path.display()))
}

fn draw_sweep<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    (x_min, x_max, y_min, y_max): (f64, f64, f64, f64),
    lines: &[SweepLine],
    caches: &[(String, f64)],
) -> Drawn
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let mut chart = titled(&root, title, 72)
        .build_cartesian_2d((x_min..x_max).log_scale(), (y_min..y_max).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("channels")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_desc("channel-updates per second")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    for (i, (name, at)) in caches.iter().enumerate() {
        if *at < x_min || *at > x_max {
            continue;
        }
        let grey = RGBColor(150, 150, 150);
        chart.draw_series(DashedLineSeries::new(
            vec![(*at, y_min), (*at, y_max)],
            4,
            4,
            grey.stroke_width(1),
        ))?;
        // Labels alternate in height so neighbouring markers stay readable.
        let y = y_min * (y_max / y_min).powf(if i % 2 == 0 { 0.08 } else { 0.16 });
        chart.draw_series(std::iter::once(Text::new(
            name.clone(),
            (*at * 1.08, y),
            ("sans-serif", 14).into_font().color(&grey),
        )))?;
    }
    for (i, line) in lines.iter().enumerate() {
        let color = palette(i);
        let style = color.stroke_width(2);
        chart
            .draw_series(LineSeries::new(line.points.clone(), style))?
            .label(line.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart.draw_series(
            line.points
                .iter()
                .map(|&p| Circle::new(p, 3, color.filled())),
        )?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every registered filter gets its own colour in a chart of all of them.
    #[test]
    fn palette_has_a_colour_per_filter() {
        let n = rootfuse_attitude::registry::FilterKind::ALL.len();
        let colours: Vec<RGBColor> = (0..n).map(palette).collect();
        for (i, a) in colours.iter().enumerate() {
            assert!(!colours[..i].contains(a), "filter {i} repeats a colour");
        }
    }

    /// A plot into a missing folder is one readable line naming the path and the folder.
    #[test]
    fn unwritable_plot_paths_are_one_clear_line() {
        let err = writable(Path::new("/nonexistent-rootfuse-dir/x.png")).unwrap_err();
        assert_eq!(
            err,
            "/nonexistent-rootfuse-dir/x.png: the folder /nonexistent-rootfuse-dir does not exist: create it or write the plot elsewhere"
        );
    }
}
