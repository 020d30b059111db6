//! Draws a [`Figure`] (plain data from `rtls-sim`) as SVG and PNG with plotters.
//!
//! Text is rendered with the DejaVu Sans font embedded in the binary (crate `dejavu`), so the
//! PNGs look the same on a machine without system fonts.

use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use rtls_papers::report::{Figure, SeriesStyle};

const SIZE_PX: (u32, u32) = (960, 640);

/// Colour-blind-safe palette (Okabe & Ito, 2008), extended with darker tones for figures with
/// many series (maps with tunnels, readers and several tracks).
const PALETTE: [RGBColor; 14] = [
    RGBColor(0, 0, 0),
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
    RGBColor(136, 34, 85),
    RGBColor(17, 119, 51),
    RGBColor(51, 34, 136),
    RGBColor(153, 153, 51),
    RGBColor(102, 51, 0),
    RGBColor(68, 170, 153),
];

static FONT: Once = Once::new();

/// Registers the embedded DejaVu Sans as "sans-serif" for every figure (once).
pub(crate) fn register_font() {
    FONT.call_once(|| {
        // the only failure is a malformed font, which the embedded one is not
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// Writes `dir/<id>.svg` and `dir/<id>.png`.
///
/// # Errors
/// An empty figure, non-finite points, or a drawing/writing failure.
pub fn render(figure: &Figure, dir: &Path) -> Result<()> {
    register_font();
    let svg = dir.join(format!("{}.svg", figure.id));
    draw(figure, SVGBackend::new(&svg, SIZE_PX).into_drawing_area())?;
    let png = dir.join(format!("{}.png", figure.id));
    draw(figure, BitMapBackend::new(&png, SIZE_PX).into_drawing_area())?;
    Ok(())
}

/// The data range of the figure, padded by 5 %, squared up for equal-aspect figures.
fn ranges(figure: &Figure) -> Result<((f64, f64), (f64, f64))> {
    let points = || figure.series.iter().flat_map(|s| &s.points);
    if points().any(|p| !p[0].is_finite() || !p[1].is_finite()) {
        return Err(anyhow!("figure `{}` has a non-finite point", figure.id));
    }
    padded_ranges(points().copied(), 1e-9, figure.equal_aspect)
        .ok_or_else(|| anyhow!("figure `{}` has no points", figure.id))
}

/// The range of the finite `points`, each axis padded by 5 % of its span (at least
/// `min_span`); with `equal_aspect` the narrower axis is widened so that one unit is as long
/// on both (plot area ≈ 3:2). `None` without a finite point.
pub(crate) fn padded_ranges(
    points: impl Iterator<Item = [f64; 2]>,
    min_span: f64,
    equal_aspect: bool,
) -> Option<((f64, f64), (f64, f64))> {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for point in points.filter(|p| p[0].is_finite() && p[1].is_finite()) {
        x = (x.0.min(point[0]), x.1.max(point[0]));
        y = (y.0.min(point[1]), y.1.max(point[1]));
    }
    if !x.0.is_finite() {
        return None;
    }
    let pad = |(lo, hi): (f64, f64)| {
        let span = (hi - lo).max(min_span);
        (lo - 0.05 * span, hi + 0.05 * span)
    };
    let (mut x, mut y) = (pad(x), pad(y));
    if equal_aspect {
        let (width, height) = (x.1 - x.0, y.1 - y.0);
        let aspect = 1.5;
        if width / height < aspect {
            let grow = (height * aspect - width) / 2.0;
            x = (x.0 - grow, x.1 + grow);
        } else {
            let grow = (width / aspect - height) / 2.0;
            y = (y.0 - grow, y.1 + grow);
        }
    }
    Some((x, y))
}

fn draw<DB: DrawingBackend>(figure: &Figure, root: DrawingArea<DB, Shift>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let error = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
    let ((x0, x1), (y0, y1)) = ranges(figure)?;
    root.fill(&WHITE).map_err(error)?;
    // shrink long captions to fit the width (DejaVu Sans averages ≈ 0.55 em per character)
    let caption_px =
        (f64::from(SIZE_PX.0 - 40) / (0.55 * figure.title.chars().count().max(1) as f64)).clamp(11.0, 20.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(&figure.title, ("sans-serif", caption_px))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(error)?;
    chart
        .configure_mesh()
        .x_desc(figure.x_label.as_str())
        .y_desc(figure.y_label.as_str())
        .light_line_style(RGBColor(235, 235, 235))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(error)?;
    for (i, series) in figure.series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let points = series.points.iter().map(|p| (p[0], p[1]));
        let annotation = match series.style {
            SeriesStyle::Line => chart
                .draw_series(LineSeries::new(points, colour.stroke_width(1)))
                .map_err(error)?,
            SeriesStyle::Dashed => chart
                .draw_series(DashedLineSeries::new(points, 8, 5, colour.stroke_width(2)))
                .map_err(error)?,
            SeriesStyle::Points => chart
                .draw_series(points.map(|p| Circle::new(p, 2, colour.filled())))
                .map_err(error)?,
        };
        annotation
            .label(series.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(error)?;
    root.present().map_err(error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_papers::report::Series;

    #[test]
    fn renders_svg_and_png_and_rejects_bad_data() {
        let dir = std::env::temp_dir().join(format!("rtls-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let figure = Figure::new("t", "Test", "x (m)", "y (m)")
            .equal_aspect()
            .with(Series::new("truth", SeriesStyle::Line, vec![[0.0, 0.0], [1.0, 2.0]]))
            .with(Series::new("fixes", SeriesStyle::Points, vec![[0.5, 1.0]]))
            .with(Series::new("bound", SeriesStyle::Dashed, vec![[0.0, 1.0], [1.0, 1.0]]));
        render(&figure, &dir).unwrap();
        let svg = std::fs::read_to_string(dir.join("t.svg")).unwrap();
        assert!(svg.contains("truth") && svg.contains("x (m)"));
        let png = std::fs::read(dir.join("t.png")).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let empty = Figure::new("e", "Empty", "x", "y");
        assert!(render(&empty, &dir).is_err());
        let nan = Figure::new("n", "NaN", "x", "y").with(Series::new("s", SeriesStyle::Line, vec![[f64::NAN, 0.0]]));
        assert!(render(&nan, &dir).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
