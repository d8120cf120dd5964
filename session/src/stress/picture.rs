//! The one picture of a stress run (`stress.png`): per family, the t error in f32 ULPs and
//! the barycentric error in units of `f32::EPSILON` (median, p99, max, log scale) on the left; the
//! share of rays classed VARY and the rays that failed or fell through a hole on the right. The
//! families are numbered along x, their names listed under the charts.

use super::{FamilyResult, StressSummary};
use ::plot::{palette, Align, Axis, Chart, Image, Marker, Rect, Scale, Series, Style};
use model::stress::ErrorStats;

/// Values at or below this are drawn at it on the log axis (an exact result has error 0).
const FLOOR: f64 = 0.01;

fn stat_series(
    name: &str,
    families: &[FamilyResult],
    i: usize,
    of: &dyn Fn(&FamilyResult) -> ErrorStats,
    pick: &dyn Fn(&ErrorStats) -> Option<f64>,
) -> Series {
    Series {
        name: name.into(),
        points: families
            .iter()
            .enumerate()
            .filter_map(|(k, f)| pick(&of(f)).map(|v| ((k + 1) as f64, v.max(FLOOR))))
            .collect(),
        color: palette::series(i),
        style: Style::Scatter(Marker::nth(i)),
    }
}

fn share(f: &FamilyResult, v: u64) -> f64 {
    100.0 * v as f64 / f.rays.max(1) as f64
}
fn vary_pct(f: &FamilyResult) -> f64 {
    100.0 * f.vary_share
}
fn req_pct(f: &FamilyResult) -> f64 {
    share(f, f.req_violations)
}
fn double_pct(f: &FamilyResult) -> f64 {
    share(f, f.double_hits)
}
fn holes_pct(f: &FamilyResult) -> f64 {
    share(f, f.holes)
}

/// The picture of `summary`.
pub fn render(summary: &StressSummary) -> Image {
    let fams = &summary.families;
    let n = fams.len().max(1) as f64;
    let x = || Axis::new("family", Scale::Linear).with_range(0.5, n + 0.5);
    let t_ulps = |f: &FamilyResult| f.t_error_ulps;
    let bary = |f: &FamilyResult| f.bary_error_eps;
    let med = |s: &ErrorStats| s.median;
    let p99 = |s: &ErrorStats| s.p99;
    let max = |s: &ErrorStats| s.max;
    let left = Chart {
        title: format!(
            "Errors on {} (profile {}); below {FLOOR} drawn at {FLOOR}",
            summary.driver, summary.profile
        ),
        x: x(),
        y: Axis::new("t error (f32 ULPs); bary error (f32 eps)", Scale::Log10),
        series: vec![
            stat_series("t ULPs median", fams, 0, &t_ulps, &med),
            stat_series("t ULPs p99", fams, 1, &t_ulps, &p99),
            stat_series("t ULPs max", fams, 2, &t_ulps, &max),
            stat_series("bary eps p99", fams, 3, &bary, &p99),
            stat_series("bary eps max", fams, 4, &bary, &max),
        ],
        legend: true,
    };
    let right = Chart {
        title: "Rays per family (%)".into(),
        x: x(),
        y: Axis::new("share of the family's rays (%)", Scale::Linear).with_range(-5.0, 105.0),
        series: [
            ("classed VARY", vary_pct as fn(&FamilyResult) -> f64),
            ("REQ violations", req_pct),
            ("double hits", double_pct),
            ("holes", holes_pct),
        ]
        .iter()
        .enumerate()
        .map(|(i, (name, y))| Series {
            name: name.to_string(),
            points: fams
                .iter()
                .enumerate()
                .map(|(k, f)| ((k + 1) as f64, y(f)))
                .collect(),
            color: palette::series(i),
            style: Style::Scatter(Marker::nth(i)),
        })
        .collect(),
        legend: true,
    };
    let (w, h) = (900, 600);
    let rows = fams.len().div_ceil(3).max(1) as i32;
    let list_h = 20 + 22 * rows;
    let mut img = Image::new(2 * w as u32, (h + list_h) as u32, palette::WHITE);
    left.draw(&mut img, Rect::new(0, 0, w, h));
    right.draw(&mut img, Rect::new(w, 0, w, h));
    for (k, f) in fams.iter().enumerate() {
        let (col, row) = ((k % 3) as i32, (k / 3) as i32);
        let label = format!("{} {} ({} rays)", k + 1, f.family, f.rays);
        img.text(
            40 + col * (2 * w / 3),
            h + 10 + 22 * row,
            &label,
            palette::TEXT,
            2,
            Align::Left,
        );
    }
    img
}
