//! `trajectory.png`: the estimated and ground-truth camera paths seen from above, and the
//! translation error over the frames, drawn with `plotters` into an RGB image.
//!
//! The two plotted axes are the two world axes along which the ground truth (or, without
//! it, the estimate) extends most; for ICL-NUIM, whose vertical axis is y, that is x and z.
//! Text uses the DejaVu Sans font bundled in `assets/fonts/` (no system fonts needed).
//! This module draws and writes a picture; it computes no metric other than the plotted
//! per-frame error (no alignment: both paths share the dataset's world frame).

use std::path::Path;
#[cfg(not(target_arch = "wasm32"))]
use std::sync::Once;

use glam::{DMat4, DVec3};
use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;
#[cfg(not(target_arch = "wasm32"))]
use plotters::style::FontStyle;

use crate::eval::DEFAULT_MAX_DT;
use crate::{Error, Result};

/// Default size of `trajectory.png`, pixels.
pub const TRAJECTORY_PLOT_SIZE: (u32, u32) = (1400, 640);

const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const FONT_NAME: &str = "wgslam-sans";
const EST_COLOR: RGBColor = RGBColor(220, 60, 30);
const GT_COLOR: RGBColor = RGBColor(30, 90, 200);

/// plotters draws no text on wasm32 (its font support is native only): the browser page
/// draws its own trajectory plot on a canvas instead.
#[cfg(target_arch = "wasm32")]
fn register_font() -> Result<()> {
    let _ = FONT_BYTES;
    Err(Error::format(
        "assets/fonts/DejaVuSans.ttf",
        "plotters has no fonts in the browser build; the page draws the trajectory itself",
    ))
}

#[cfg(not(target_arch = "wasm32"))]
fn register_font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut ok = true;
    ONCE.call_once(|| {
        ok = plotters::style::register_font(FONT_NAME, FontStyle::Normal, FONT_BYTES).is_ok();
    });
    if ok {
        Ok(())
    } else {
        Err(Error::format(
            "assets/fonts/DejaVuSans.ttf",
            "the bundled font does not parse",
        ))
    }
}

/// The two world axes (0 = x, 1 = y, 2 = z), in ascending order, along which `points`
/// extend most. Ties keep the lower axis.
pub fn horizontal_axes(points: &[DVec3]) -> (usize, usize) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in points.iter().filter(|p| p.is_finite()) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let ext = (hi - lo)
        .to_array()
        .map(|e| if e.is_finite() { e } else { 0.0 });
    // Drop the axis with the smallest extent (the last one among equals).
    let mut drop = 2;
    for a in (0..3).rev() {
        if ext[a] < ext[drop] {
            drop = a;
        }
    }
    match drop {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// `(stamp, estimated position, ground-truth position)` of every estimated pose that the
/// evaluation associates with a ground-truth pose ([`crate::eval::associate`] with its
/// default window), so the plotted error is the error the ATE measures.
pub fn associate(est: &[(f64, DMat4)], gt: &[(f64, DMat4)]) -> Vec<(f64, DVec3, DVec3)> {
    crate::eval::associate(est, gt, DEFAULT_MAX_DT)
        .into_iter()
        .map(|(ie, ig)| {
            (
                est[ie].0,
                est[ie].1.w_axis.truncate(),
                gt[ig].1.w_axis.truncate(),
            )
        })
        .collect()
}

const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::format("trajectory plot", format!("plotting failed: {e}"))
}

/// Draws the trajectory figure: on the left the paths from above (estimate and, when
/// given, ground truth; start marked), on the right the translation error per frame
/// (`|t_est - t_gt|`, metres) when ground truth overlaps the estimate. Poses are
/// `(stamp, t_cam_to_world)`, metres.
pub fn trajectory_plot(
    estimated: &[(f64, DMat4)],
    ground_truth: &[(f64, DMat4)],
    size: (u32, u32),
) -> Result<RgbImage> {
    let (w, h) = size;
    crate::render::check_size(w, h)?;
    if estimated.is_empty() {
        return Err(Error::Argument("no estimated pose to plot".into()));
    }
    register_font()?;
    let est_pts: Vec<DVec3> = estimated.iter().map(|(_, t)| t.w_axis.truncate()).collect();
    let gt_pts = ground_truth_in_range(estimated, ground_truth);
    let pairs = associate(estimated, ground_truth);
    let axes = horizontal_axes(if gt_pts.len() >= 2 { &gt_pts } else { &est_pts });
    let view = SquareView::around(&est_pts, &gt_pts, axes)?;

    let mut buf = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let (left, right) = root.split_horizontally(w * 9 / 20);
        draw_paths(&left, &est_pts, &gt_pts, axes, &view)?;
        if pairs.is_empty() {
            draw_no_error_note(&right, ground_truth.is_empty(), (w, h))?;
        } else {
            draw_error(&right, &pairs)?;
        }
        root.present().map_err(plot_error)?;
    }
    Ok(RgbImage::from_raw(w, h, buf).expect("buffer size matches the image size"))
}

/// One half of the figure, drawn into the image's buffer.
type Panel<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// The bundled font at `px` pixels.
fn font(px: u32) -> FontDesc<'static> {
    (FONT_NAME, px).into_font()
}

/// The ground-truth positions within the estimate's stamp range (widened by the
/// association window): the dataset may hold more.
fn ground_truth_in_range(estimated: &[(f64, DMat4)], ground_truth: &[(f64, DMat4)]) -> Vec<DVec3> {
    let (s0, s1) = estimated
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (s, _)| {
            (a.min(*s), b.max(*s))
        });
    ground_truth
        .iter()
        .filter(|(s, _)| *s >= s0 - DEFAULT_MAX_DT && *s <= s1 + DEFAULT_MAX_DT)
        .map(|(_, t)| t.w_axis.truncate())
        .collect()
}

/// The square data range of the path panel, so that the picture is not distorted: centre
/// `(c0, c1)` and half-width `half` along the plotted axes, metres.
struct SquareView {
    c0: f64,
    c1: f64,
    half: f64,
}

impl SquareView {
    /// The square around every finite position of both paths, with a margin, along `axes`.
    fn around(est_pts: &[DVec3], gt_pts: &[DVec3], (a0, a1): (usize, usize)) -> Result<Self> {
        let all: Vec<(f64, f64)> = est_pts
            .iter()
            .chain(gt_pts.iter())
            .filter(|p| p.is_finite())
            .map(|p| (p[a0], p[a1]))
            .collect();
        if all.is_empty() {
            return Err(Error::Numerical(
                "every estimated position is NaN or infinite".into(),
            ));
        }
        let (mut lo0, mut hi0, mut lo1, mut hi1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for (x, y) in &all {
            lo0 = lo0.min(*x);
            hi0 = hi0.max(*x);
            lo1 = lo1.min(*y);
            hi1 = hi1.max(*y);
        }
        let half = ((hi0 - lo0).max(hi1 - lo1) * 0.55).max(0.05);
        let (c0, c1) = ((lo0 + hi0) * 0.5, (lo1 + hi1) * 0.5);
        Ok(Self { c0, c1, half })
    }
}

/// The left panel: both paths from above along `axes`, the start marked, with a legend.
fn draw_paths(
    area: &Panel<'_>,
    est_pts: &[DVec3],
    gt_pts: &[DVec3],
    (a0, a1): (usize, usize),
    view: &SquareView,
) -> Result<()> {
    let SquareView { c0, c1, half } = *view;
    let mut chart = ChartBuilder::on(area)
        .caption("Camera path, seen from above", font(22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(c0 - half..c0 + half, c1 - half..c1 + half)
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_labels(6)
        .x_desc(format!("{} [m]", AXIS_NAMES[a0]))
        .y_desc(format!("{} [m]", AXIS_NAMES[a1]))
        .label_style(font(15))
        .axis_desc_style(font(17))
        .draw()
        .map_err(plot_error)?;
    if gt_pts.len() >= 2 {
        chart
            .draw_series(LineSeries::new(
                gt_pts.iter().map(|p| (p[a0], p[a1])),
                GT_COLOR.stroke_width(3),
            ))
            .map_err(plot_error)?
            .label("ground truth")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 24, y)], GT_COLOR.stroke_width(3)));
    }
    chart
        .draw_series(LineSeries::new(
            est_pts
                .iter()
                .filter(|p| p.is_finite())
                .map(|p| (p[a0], p[a1])),
            EST_COLOR.stroke_width(2),
        ))
        .map_err(plot_error)?
        .label("estimated")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 24, y)], EST_COLOR.stroke_width(2)));
    let start = est_pts[0];
    chart
        .draw_series(std::iter::once(Circle::new(
            (start[a0], start[a1]),
            6,
            BLACK.filled(),
        )))
        .map_err(plot_error)?
        .label("start")
        .legend(|(x, y)| Circle::new((x + 12, y), 5, BLACK.filled()));
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight)
}

/// The chart's legend at `position`, in the figure's font on a light box.
fn draw_legend<'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, CT>,
    position: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .label_font(font(16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(position)
        .draw()
        .map_err(plot_error)
}

/// The right panel without an error curve: a line saying why (no ground truth, or no stamp
/// in common). `size` is the whole figure's, pixels.
fn draw_no_error_note(area: &Panel<'_>, no_ground_truth: bool, (w, h): (u32, u32)) -> Result<()> {
    let msg = if no_ground_truth {
        "no ground truth: translation error not plotted"
    } else {
        "no ground-truth stamp matches an estimated one"
    };
    area.draw(&Text::new(
        msg,
        ((w - w * 9 / 20) as i32 / 8, h as i32 / 2),
        font(18),
    ))
    .map_err(plot_error)?;
    Ok(())
}

/// The right panel: the translation error of each associated pose over the stamps, in
/// millimetres, with its RMSE in the caption. `pairs` is not empty.
fn draw_error(area: &Panel<'_>, pairs: &[(f64, DVec3, DVec3)]) -> Result<()> {
    let errs: Vec<(f64, f64)> = pairs
        .iter()
        .map(|(s, e, g)| (*s, (*e - *g).length()))
        .collect();
    let (f0, f1) = (errs[0].0, errs[errs.len() - 1].0);
    let f1 = if f1 > f0 { f1 } else { f0 + 1.0 };
    let emax = errs
        .iter()
        .map(|e| e.1)
        .filter(|e| e.is_finite())
        .fold(0.0, f64::max);
    let emax = if emax > 0.0 { emax * 1.1 } else { 0.01 };
    let rmse = (errs.iter().map(|e| e.1 * e.1).sum::<f64>() / errs.len() as f64).sqrt();
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "Translation error (no alignment), RMSE {:.1} mm",
                rmse * 1000.0
            ),
            font(22),
        )
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(f0..f1, 0.0..emax * 1000.0)
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc("frame (dataset stamp)")
        .y_desc("|t_est - t_gt| [mm]")
        .label_style(font(15))
        .axis_desc_style(font(17))
        .draw()
        .map_err(plot_error)?;
    chart
        .draw_series(LineSeries::new(
            errs.iter().map(|(s, e)| (*s, e * 1000.0)),
            EST_COLOR.stroke_width(2),
        ))
        .map_err(plot_error)?
        .label("translation error")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 24, y)], EST_COLOR.stroke_width(2)));
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)
}

/// Draws [`trajectory_plot`] at [`TRAJECTORY_PLOT_SIZE`] and writes it as a PNG at `path`,
/// completely or not at all.
pub fn write_trajectory_plot(
    path: &Path,
    estimated: &[(f64, DMat4)],
    ground_truth: &[(f64, DMat4)],
) -> Result<()> {
    let img = trajectory_plot(estimated, ground_truth, TRAJECTORY_PLOT_SIZE)?;
    crate::render::write_png(path, &img)
}
