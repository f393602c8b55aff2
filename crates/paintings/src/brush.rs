//! The strokes a random painting is made of: rectangles, discs, ramps and walls on gray or RGBA
//! canvases. Plain pixel loops: the canvases are small and the strokes few.

use image::{GrayImage, Luma, Rgba, RgbaImage};

/// A rectangle of pixels, `x0..x1` by `y0..y1` (clipped to the canvas when painted).
#[derive(Debug, Clone, Copy)]
pub struct Rect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Rect {
    fn clipped(self, w: u32, h: u32) -> Rect {
        Rect {
            x0: self.x0.min(w),
            y0: self.y0.min(h),
            x1: self.x1.min(w),
            y1: self.y1.min(h),
        }
    }

    pub fn pixels(self, w: u32, h: u32) -> impl Iterator<Item = (u32, u32)> {
        let r = self.clipped(w, h);
        (r.y0..r.y1).flat_map(move |y| (r.x0..r.x1).map(move |x| (x, y)))
    }
}

/// Fills a rectangle with one gray level.
pub fn fill(img: &mut GrayImage, r: Rect, level: u8) {
    let (w, h) = img.dimensions();
    for (x, y) in r.pixels(w, h) {
        img.put_pixel(x, y, Luma([level]));
    }
}

/// Paints a hard disc of `level` (a round brush), centre and radius in pixels; returns how
/// many pixels it covered.
pub fn disc(img: &mut GrayImage, cx: f64, cy: f64, radius: f64, level: u8) -> usize {
    let mut painted = 0;
    for (x, y, p) in img.enumerate_pixels_mut() {
        let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
        if dx * dx + dy * dy <= radius * radius {
            *p = Luma([level]);
            painted += 1;
        }
    }
    painted
}

/// Adds a soft disc (a blob of paint) of peak `level` and radius `radius` pixels.
pub fn blob(img: &mut GrayImage, cx: f64, cy: f64, radius: f64, level: u8) {
    let (w, h) = img.dimensions();
    for y in 0..h {
        for x in 0..w {
            let d = ((x as f64 + 0.5 - cx).powi(2) + (y as f64 + 0.5 - cy).powi(2)).sqrt();
            if d < radius {
                let add = f64::from(level) * (1.0 - d / radius);
                let v = f64::from(img.get_pixel(x, y)[0]) + add;
                img.put_pixel(x, y, Luma([v.min(255.0) as u8]));
            }
        }
    }
}

/// A gray ramp from dark to bright along `angle` (radians, image axes), the whole canvas: a
/// direction layer whose people walk that way.
pub fn ramp(img: &mut RgbaImage, angle: f64, region: Rect, alpha: u8) {
    let (w, h) = img.dimensions();
    let (dx, dy) = (angle.cos(), angle.sin());
    let span = f64::from(w).hypot(f64::from(h)).max(1.0);
    for (x, y) in region.pixels(w, h) {
        let t = ((f64::from(x) - f64::from(w) / 2.0) * dx
            + (f64::from(y) - f64::from(h) / 2.0) * dy)
            / span
            + 0.5;
        let v = (t.clamp(0.0, 1.0) * 255.0) as u8;
        img.put_pixel(x, y, Rgba([v, v, v, alpha]));
    }
}

/// A flow-map region (R east, G north, 128 zero, A weight) walking along `(east, north)`.
pub fn flow(img: &mut RgbaImage, region: Rect, east: f64, north: f64, alpha: u8) {
    let (w, h) = img.dimensions();
    let encode = |v: f64| (128.0 + 127.0 * v.clamp(-1.0, 1.0)).round() as u8;
    for (x, y) in region.pixels(w, h) {
        img.put_pixel(x, y, Rgba([encode(east), encode(north), 128, alpha]));
    }
}

/// A straight wall `thickness` pixels thick from `(x, y)`, horizontal or vertical, `length`
/// long, with a gap of `gap` pixels at `gap_at` along it (0 = no gap).
pub struct Wall {
    pub x: u32,
    pub y: u32,
    pub length: u32,
    pub thickness: u32,
    pub horizontal: bool,
    pub gap_at: u32,
    pub gap: u32,
}

pub fn wall(img: &mut GrayImage, wall: &Wall) {
    for along in 0..wall.length {
        if along >= wall.gap_at && along < wall.gap_at + wall.gap {
            continue;
        }
        for across in 0..wall.thickness {
            let (x, y) = if wall.horizontal {
                (wall.x + along, wall.y + across)
            } else {
                (wall.x + across, wall.y + along)
            };
            if x < img.width() && y < img.height() {
                img.put_pixel(x, y, Luma([255]));
            }
        }
    }
}

/// The outline of a rectangle, one pixel thick: a pocket nobody can walk into.
pub fn pocket(img: &mut GrayImage, r: Rect) {
    let (w, h) = img.dimensions();
    for (x, y) in r.pixels(w, h) {
        let edge = x == r.x0 || y == r.y0 || x + 1 == r.x1.min(w) || y + 1 == r.y1.min(h);
        if edge {
            img.put_pixel(x, y, Luma([255]));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_disc_paints_the_pixels_whose_centres_are_within_its_radius() {
        let mut img = GrayImage::new(20, 20);
        let painted = disc(&mut img, 10.0, 10.0, 3.0, 200);
        // Pixel centres (x + 0.5, y + 0.5) within 3 of (10, 10): rows of 6, 6, 4 columns
        // out from the middle on each side, 32 in all.
        assert_eq!(painted, 32);
        assert_eq!(img.get_pixel(10, 10).0, [200]);
        assert_eq!(img.get_pixel(13, 10).0, [0]);
        assert_eq!(img.pixels().filter(|p| p.0 == [200]).count(), painted);
    }
}
