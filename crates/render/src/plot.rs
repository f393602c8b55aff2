//! Plain pictures for figures that are not stage files: curves per iteration or per time step,
//! and a top view of trajectories (the way the editing paper draws its scenes). The command
//! line composes them; their legends are given as text beside them.

use crate::draw::Canvas;
use glam::DVec2;
use image::{Rgb, RgbImage};

const BACKGROUND: Rgb<u8> = Rgb([255, 255, 255]);
const INK: Rgb<u8> = Rgb([20, 20, 20]);
const GRID: Rgb<u8> = Rgb([215, 215, 215]);

/// One curve of a plot: a value per sample (NaN leaves a gap).
pub struct Curve<'a> {
    pub values: &'a [f64],
    pub colour: Rgb<u8>,
}

/// The curves over their common sample index, y from 0 to the largest value (linear) or over
/// the decades they span (`log`); gray lines at each tenth of the top (linear) or each decade.
pub fn plot(curves: &[Curve], log: bool, width: u32, height: u32) -> RgbImage {
    let margin = 12.0;
    let mut canvas = Canvas::new(width, height, BACKGROUND);
    let finite = || {
        curves
            .iter()
            .flat_map(|c| c.values.iter().copied())
            .filter(|v| v.is_finite() && (!log || *v > 0.0))
    };
    let samples = curves
        .iter()
        .map(|c| c.values.len())
        .max()
        .unwrap_or(0)
        .max(2);
    let (lo, hi) = if log {
        let lo = finite().fold(f64::INFINITY, f64::min).log10().floor();
        let hi = finite().fold(f64::NEG_INFINITY, f64::max).log10().ceil();
        if lo.is_finite() && hi.is_finite() {
            (lo, hi.max(lo + 1.0))
        } else {
            (0.0, 1.0)
        }
    } else {
        (0.0, finite().fold(0.0, f64::max).max(1e-12) * 1.05)
    };
    let (w, h) = (width as f64 - 2.0 * margin, height as f64 - 2.0 * margin);
    let scale = |v: f64| if log { v.log10() } else { v };
    let at = |i: usize, v: f64| {
        let x = margin + i as f64 / (samples - 1) as f64 * w;
        let y = margin + h * (1.0 - (scale(v) - lo) / (hi - lo));
        (x, y)
    };
    let levels: Vec<f64> = if log {
        (lo as i32..=hi as i32).map(|e| 10f64.powi(e)).collect()
    } else {
        (0..=10).map(|k| hi / 1.05 * k as f64 / 10.0).collect()
    };
    for level in levels {
        canvas.thick_line(at(0, level), at(samples - 1, level), 1, GRID);
    }
    for curve in curves {
        for (i, pair) in curve.values.windows(2).enumerate() {
            let ok = |v: f64| v.is_finite() && (!log || v > 0.0);
            if ok(pair[0]) && ok(pair[1]) {
                canvas.thick_line(at(i, pair[0]), at(i + 1, pair[1]), 2, curve.colour);
            }
        }
    }
    let corner = (margin, height as f64 - margin);
    canvas.thick_line(corner, (width as f64 - margin, corner.1), 1, INK);
    canvas.thick_line(corner, (margin, margin), 1, INK);
    canvas.into_image()
}

/// A rectangle drawn as an outline.
pub struct Outline {
    pub min: DVec2,
    pub max: DVec2,
    pub colour: Rgb<u8>,
}

/// What a top view shows: the world's extent, its obstacles and marked areas, the
/// trajectories, and discs (characters at one instant, or targets).
pub struct TopView<'a> {
    pub min: DVec2,
    pub max: DVec2,
    pub obstacles: &'a [(DVec2, DVec2)],
    pub outlines: &'a [Outline],
    pub paths: &'a [(Vec<DVec2>, Rgb<u8>)],
    /// Centre, radius in metres, colour, filled.
    pub discs: &'a [(DVec2, f64, Rgb<u8>, bool)],
}

/// The top view at `px_per_m` pixels per metre, y up.
pub fn top_view(view: &TopView, px_per_m: f64) -> RgbImage {
    let size = (view.max - view.min) * px_per_m;
    let (width, height) = (size.x.ceil().max(1.0) as u32, size.y.ceil().max(1.0) as u32);
    let mut canvas = Canvas::new(width, height, Rgb([246, 246, 242]));
    let px = |p: DVec2| {
        let q = (p - view.min) * px_per_m;
        (q.x, height as f64 - q.y)
    };
    for (lo, hi) in view.obstacles {
        let (a, b) = (px(*lo), px(*hi));
        canvas.fill_f(a.0, b.1, b.0, a.1, Rgb([90, 90, 96]));
    }
    for path in view.paths {
        for w in path.0.windows(2) {
            canvas.thick_line(px(w[0]), px(w[1]), 1, path.1);
        }
    }
    for o in view.outlines {
        let (a, b) = (px(o.min), px(o.max));
        let corners = [(a.0, a.1), (b.0, a.1), (b.0, b.1), (a.0, b.1), (a.0, a.1)];
        for w in corners.windows(2) {
            canvas.thick_line(w[0], w[1], 3, o.colour);
        }
    }
    for &(c, r, colour, filled) in view.discs {
        let radius = (r * px_per_m).round().max(1.0) as i32;
        canvas.disc(px(c), radius, colour, filled);
    }
    canvas.into_image()
}

/// Pictures side by side on a white sheet, `gap` pixels apart.
pub fn side_by_side(pictures: &[RgbImage], gap: u32) -> RgbImage {
    let width = pictures.iter().map(|p| p.width() + gap).sum::<u32>() + gap;
    let height = pictures.iter().map(|p| p.height()).max().unwrap_or(0) + 2 * gap;
    let mut canvas = Canvas::new(width, height, BACKGROUND);
    let mut x = gap;
    for p in pictures {
        canvas.paste(p, x, gap);
        x += p.width() + gap;
    }
    canvas.into_image()
}
