//! `--plot`: the bounce pass's convergence trace as an SVG, error against
//! run time. Drawn with plotters' SVG backend, whose text is plain SVG
//! `<text>` laid out by the viewer, so it needs no system fonts.
//!
//! Plotted against seconds since the bounce pass started, on a log axis:
//! the unshot power fraction (unshot power over the power put in) and the
//! error estimate (the ambient term for the unshot light over the mean
//! gathered, see `solve::TracePoint`), and with `--reference` the true
//! error: the relative RMSE against the CPU reference at the probe texels,
//! with the reference's own noise as a dashed line (the floor it can resolve).

use anyhow::{Result, anyhow};
use plotters::prelude::*;

use crate::report::SceneReport;

/// A curve: its legend, colour and (seconds, value) points.
type Series = (&'static str, RGBColor, Vec<(f64, f64)>);

/// Width and height of the plot in SVG pixels.
pub const SIZE: (u32, u32) = (800, 480);

/// Values below this are drawn at it (a log axis has no 0).
const FLOOR: f64 = 1e-7;

/// The convergence plot of `scene` as an SVG document. A scene without a
/// bounce pass gets a plot that says why instead of a curve.
pub fn convergence_svg(scene: &SceneReport) -> Result<String> {
    let mut svg = String::new();
    draw(scene, &mut svg).map_err(|e| anyhow!("drawing the convergence plot: {e}"))?;
    Ok(svg)
}

fn draw(scene: &SceneReport, svg: &mut String) -> Result<(), Box<dyn std::error::Error + Send + Sync + 'static>> {
    let root = SVGBackend::with_string(svg, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let title = format!("{}: convergence of the bounce pass", scene.name);
    let Some(bounce) = scene.bounce.as_ref().filter(|b| !b.trace.is_empty()) else {
        let reason = scene
            .skipped
            .iter()
            .find(|s| s.pass == "bounce")
            .map_or("no trace was recorded".to_string(), |s| format!("bounce pass left out: {}", s.reason));
        root.titled(&title, ("sans-serif", 20))?.draw(&Text::new(reason, (40, 60), ("sans-serif", 16)))?;
        root.present()?;
        return Ok(());
    };
    let trace = &bounce.trace;
    let at = |v: f64| if v.is_finite() { v.max(FLOOR) } else { FLOOR };
    let mut series: Vec<Series> = vec![
        (
            "unshot power fraction",
            RGBColor(31, 119, 180),
            trace.iter().map(|t| (t.seconds, at(t.unshot_fraction))).collect(),
        ),
        (
            "error estimate (relative)",
            RGBColor(214, 39, 40),
            trace.iter().map(|t| (t.seconds, at(t.error_estimate))).collect(),
        ),
    ];
    let t_max = trace.iter().map(|t| t.seconds).fold(0.0f64, f64::max).max(1e-3) * 1.05;
    let reference = scene.reference.as_ref().filter(|_| trace.iter().any(|t| t.reference_error.is_some()));
    if let Some(reference) = reference {
        let points = trace.iter().filter_map(|t| t.reference_error.map(|e| (t.seconds, at(e)))).collect();
        series.push(("error against the CPU reference (relative RMSE)", RGBColor(44, 160, 44), points));
        series.push((
            "noise of the reference",
            RGBColor(150, 150, 150),
            vec![(0.0, at(reference.noise)), (t_max, at(reference.noise))],
        ));
    }
    let values = series.iter().flat_map(|s| s.2.iter().map(|p| p.1));
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    // Whole decades, with a little give so that 1.0000001 stays under 10⁰.
    let lo = 10f64.powf((lo.log10() + 1e-6).floor());
    let hi = 10f64.powf((hi.log10() - 1e-6).ceil()).max(lo * 10.0);

    let caption = format!(
        "{title} ({} shots, stopped: {}, {:.2}% unshot)",
        bounce.shots,
        bounce.stopped_by,
        bounce.unshot_fraction * 100.0
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 16))
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..t_max, (lo..hi).log_scale())?;
    // The trace's last point is after the contact fix-up when it took texels.
    let contact = scene.texels.fixups.iter().any(|f| f.stage == "contact" && f.texels > 0);
    let x_desc = if contact {
        "seconds since the bounce pass started (the last point: after the contact fix-up)"
    } else {
        "seconds since the bounce pass started"
    };
    chart.configure_mesh().x_desc(x_desc).y_desc("fraction (log)").y_label_formatter(&|v| format!("{v:.0e}")).draw()?;
    for (label, color, points) in series {
        chart
            .draw_series(LineSeries::new(points.iter().copied(), color.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        if points.len() > 2 {
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
