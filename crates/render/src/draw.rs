//! A few drawing primitives over imageproc, and the colour scales of the pictures.

use glam::Vec2;
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_filled_rect_mut, draw_line_segment_mut};
use imageproc::rect::Rect;

pub struct Canvas(RgbImage);

impl Canvas {
    pub fn new(width: u32, height: u32, background: Rgb<u8>) -> Canvas {
        Canvas(RgbImage::from_pixel(width, height, background))
    }

    pub fn fill(&mut self, x: u32, y: u32, w: u32, h: u32, colour: Rgb<u8>) {
        if w > 0 && h > 0 {
            let rect = Rect::at(x as i32, y as i32).of_size(w, h);
            draw_filled_rect_mut(&mut self.0, rect, colour);
        }
    }

    /// Fills the rectangle between two corners given in fractional pixels.
    pub fn fill_f(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, colour: Rgb<u8>) {
        let (x0, y0) = (x0.round() as u32, y0.round() as u32);
        let (x1, y1) = (x1.round() as u32, y1.round() as u32);
        self.fill(
            x0,
            y0,
            x1.saturating_sub(x0).max(1),
            y1.saturating_sub(y0).max(1),
            colour,
        );
    }

    /// A line `width` pixels wide (parallel strokes).
    pub fn thick_line(&mut self, a: (f64, f64), b: (f64, f64), width: u32, colour: Rgb<u8>) {
        let d = Vec2::new((b.0 - a.0) as f32, (b.1 - a.1) as f32);
        let n = d.perp().normalize_or_zero();
        for i in 0..width {
            let o = n * (i as f32 - (width as f32 - 1.0) / 2.0);
            draw_line_segment_mut(
                &mut self.0,
                (a.0 as f32 + o.x, a.1 as f32 + o.y),
                (b.0 as f32 + o.x, b.1 as f32 + o.y),
                colour,
            );
        }
    }

    /// An arrow from `from` to `to`, with a dark outline so it reads on light and dark shades.
    pub fn arrow(&mut self, from: Vec2, to: Vec2, colour: Rgb<u8>) {
        let d = to - from;
        let len = d.length();
        if len < 1.0 {
            return;
        }
        let head = (len * 0.35).max(2.0);
        let back = -d / len * head;
        let left = from_angle(0.5).rotate(back);
        let right = from_angle(-0.5).rotate(back);
        let width = if len > 12.0 { 2 } else { 1 };
        let seg = |v: Vec2| (v.x as f64, v.y as f64);
        for (stroke, c) in [(width + 2, Rgb([20, 20, 20])), (width, colour)] {
            self.thick_line(seg(from), seg(to), stroke, c);
            self.thick_line(seg(to), seg(to + left), stroke, c);
            self.thick_line(seg(to), seg(to + right), stroke, c);
        }
    }

    pub fn into_image(self) -> RgbImage {
        self.0
    }
}

fn from_angle(a: f32) -> Vec2 {
    Vec2::new(a.cos(), a.sin())
}

/// A perceptually ordered scale (an approximation of viridis): 0 dark blue, 1 yellow.
pub fn colormap(t: f32) -> Rgb<u8> {
    const STOPS: [[f32; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * (STOPS.len() - 1) as f32;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f32;
    let mix = |k: usize| (STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f).round() as u8;
    Rgb([mix(0), mix(1), mix(2)])
}

/// Hue from a heading (world frame), brightness from a weight in 0..1.
pub fn heading_colour(flow: Vec2, weight: f32) -> Rgb<u8> {
    if flow.length_squared() == 0.0 || weight <= 0.0 {
        return Rgb([20, 20, 20]);
    }
    let hue = flow.y.atan2(flow.x).rem_euclid(std::f32::consts::TAU) / std::f32::consts::TAU;
    let v = 0.35 + 0.65 * weight.clamp(0.0, 1.0);
    let h6 = hue * 6.0;
    let x = 1.0 - (h6 % 2.0 - 1.0).abs();
    let (r, g, b) = match h6 as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    let c = |u: f32| (u * v * 255.0).round() as u8;
    Rgb([c(r), c(g), c(b)])
}

impl Canvas {
    /// A filled disc, or a ring when `filled` is false.
    pub fn disc(&mut self, centre: (f64, f64), radius: i32, colour: Rgb<u8>, filled: bool) {
        let c = (centre.0.round() as i32, centre.1.round() as i32);
        if filled {
            imageproc::drawing::draw_filled_circle_mut(&mut self.0, c, radius, colour);
        } else {
            imageproc::drawing::draw_hollow_circle_mut(&mut self.0, c, radius, colour);
            imageproc::drawing::draw_hollow_circle_mut(&mut self.0, c, radius - 1, colour);
        }
    }

    /// Paints another picture at (x, y).
    pub fn paste(&mut self, other: &RgbImage, x: u32, y: u32) {
        image::imageops::overlay(&mut self.0, other, x as i64, y as i64);
    }
}

/// A diverging scale for signed errors: blue (negative) through green (0) to red (positive).
pub fn diverging(t: f32) -> Rgb<u8> {
    let t = if t.is_finite() {
        t.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let green = [60.0, 170.0, 90.0];
    let end = if t < 0.0 {
        [40.0, 60.0, 200.0]
    } else {
        [215.0, 40.0, 40.0]
    };
    let f = t.abs();
    let mix = |k: usize| (green[k] * (1.0 - f) + end[k] * f).round() as u8;
    Rgb([mix(0), mix(1), mix(2)])
}

/// A hue for the `i`-th of many lines, easy to tell from its neighbours.
pub fn line_colour(i: usize) -> Rgb<u8> {
    const PALETTE: [[u8; 3]; 8] = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
        [227, 119, 194],
        [23, 190, 207],
    ];
    Rgb(PALETTE[i % PALETTE.len()])
}
