//! The pure core of stage 1: layer rasters in, merged maps out.

use crate::layer::{PaintedLayer, Raster};
use crowd_core::config::MergeSettings;
use crowd_core::{Grid, LayerKind, MergedMaps, Progress};
use glam::Vec2;
use rayon::prelude::*;

/// Merges decoded layers (all of one pixel size, checked by [`crate::decode`]).
///
/// Deterministic whatever the thread count: every pixel is computed on its own, in layer order.
/// A layer of weight 0 is switched off.
pub fn merge(
    layers: &[PaintedLayer],
    settings: &MergeSettings,
    meters_per_pixel: f64,
    progress: &dyn Progress,
) -> MergedMaps {
    let (w, h) = layers
        .first()
        .map_or((0, 0), |l| (l.raster.width, l.raster.height));
    let mut maps = MergedMaps::empty(w, h, meters_per_pixel);
    progress.begin("merge", layers.len() as u64 + 1);
    let width = w as usize;
    for layer in layers.iter().filter(|l| l.weight > 0.0) {
        let weight = layer.weight as f32;
        let r = &layer.raster;
        match layer.kind {
            LayerKind::Density => accumulate(&mut maps.walkers, r, weight),
            LayerKind::Static => accumulate(&mut maps.standers, r, weight),
            LayerKind::Obstacles => {
                let threshold = settings.obstacle_threshold as f32;
                par_rows(maps.blocked.as_mut_slice(), width, |i, blocked| {
                    let (v, a) = r.gray_alpha(i);
                    *blocked |= v * a >= threshold;
                });
            }
            LayerKind::Direction => {
                let gradient = GrayGradient::new(r);
                par_rows2(&mut maps.flow, &mut maps.flow_weight, width, |i, f, fw| {
                    let (_, a) = r.gray_alpha(i);
                    if a > 0.0 {
                        *f += weight * a * gradient.at(i % width, i / width).normalize_or_zero();
                        *fw += weight * a;
                    }
                });
            }
            LayerKind::Flow => {
                let zero = (r.max + 1.0) / 2.0;
                let range = r.max - zero;
                // Vectors shorter than this are "no direction" (8-bit rounding around 128).
                let dead_zone = 1.5 / 127.0;
                par_rows2(&mut maps.flow, &mut maps.flow_weight, width, |i, f, fw| {
                    let (red, green, a) = r.red_green_alpha(i);
                    let v = Vec2::new(red - zero, green - zero) / range;
                    if a > 0.0 && v.length() > dead_zone {
                        *f += weight * a * v.normalize();
                        *fw += weight * a;
                    }
                });
            }
        }
        progress.advance(1);
    }
    clear_under_obstacles(&mut maps);
    progress.advance(1);
    maps
}

/// Weighted sum of a gray layer: `acc += weight x alpha x gray`.
fn accumulate(acc: &mut Grid<f32>, r: &Raster, weight: f32) {
    let width = acc.width() as usize;
    par_rows(acc.as_mut_slice(), width, |i, v| {
        let (gray, alpha) = r.gray_alpha(i);
        *v += weight * alpha * gray;
    });
}

fn clear_under_obstacles(maps: &mut MergedMaps) {
    let blocked = maps.blocked.as_slice();
    let cleared = blocked.iter().enumerate().filter(|(_, b)| **b);
    for (i, _) in cleared {
        maps.walkers.as_mut_slice()[i] = 0.0;
        maps.standers.as_mut_slice()[i] = 0.0;
        maps.flow.as_mut_slice()[i] = Vec2::ZERO;
        maps.flow_weight.as_mut_slice()[i] = 0.0;
    }
}

/// Runs `f(pixel index, value)` over a grid's pixels, a row per task.
fn par_rows<T: Send>(data: &mut [T], width: usize, f: impl Fn(usize, &mut T) + Sync) {
    data.par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, v) in row.iter_mut().enumerate() {
                f(y * width + x, v);
            }
        });
}

/// As [`par_rows`], over two grids of the same size at once.
fn par_rows2(
    a: &mut Grid<Vec2>,
    b: &mut Grid<f32>,
    width: usize,
    f: impl Fn(usize, &mut Vec2, &mut f32) + Sync,
) {
    a.as_mut_slice()
        .par_chunks_mut(width.max(1))
        .zip(b.as_mut_slice().par_chunks_mut(width.max(1)))
        .enumerate()
        .for_each(|(y, (ra, rb))| {
            for (x, (va, vb)) in ra.iter_mut().zip(rb).enumerate() {
                f(y * width + x, va, vb);
            }
        });
}

/// The gradient of a gray direction layer, from dark to bright, in the world frame.
///
/// Only painted pixels (alpha > 0) take part, so the edge of a painted stroke does not read as a
/// ramp down to the transparent gray behind it. Differences are central where both neighbours
/// are painted, one-sided at a stroke's edge, and averaged over three rows with weights 1-2-1
/// (a Sobel filter that tolerates holes), which smooths 8-bit quantisation on gentle ramps.
struct GrayGradient {
    width: usize,
    height: usize,
    gray: Vec<f32>,
    painted: Vec<bool>,
}

impl GrayGradient {
    fn new(r: &Raster) -> GrayGradient {
        let n = r.width as usize * r.height as usize;
        let (gray, painted) = (0..n)
            .map(|i| {
                let (g, a) = r.gray_alpha(i);
                (g, a > 0.0)
            })
            .unzip();
        GrayGradient {
            width: r.width as usize,
            height: r.height as usize,
            gray,
            painted,
        }
    }

    fn get(&self, x: isize, y: isize) -> Option<f32> {
        let inside = x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height;
        if !inside {
            return None;
        }
        let i = y as usize * self.width + x as usize;
        self.painted[i].then(|| self.gray[i])
    }

    /// Difference along (dx, dy) at (x, y): central, else one-sided.
    fn diff(&self, x: isize, y: isize, dx: isize, dy: isize) -> Option<f32> {
        let (before, here, after) = (
            self.get(x - dx, y - dy),
            self.get(x, y),
            self.get(x + dx, y + dy),
        );
        match (before, here, after) {
            (Some(b), _, Some(a)) => Some((a - b) / 2.0),
            (None, Some(h), Some(a)) => Some(a - h),
            (Some(b), Some(h), None) => Some(h - b),
            _ => None,
        }
    }

    /// Smoothed difference along one image axis, across the three lines beside it.
    fn smoothed(&self, x: isize, y: isize, along_x: bool) -> f32 {
        let (mut sum, mut weight) = (0.0, 0.0);
        for (offset, k) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
            let d = if along_x {
                self.diff(x, y + offset, 1, 0)
            } else {
                self.diff(x + offset, y, 0, 1)
            };
            if let Some(d) = d {
                sum += k * d;
                weight += k;
            }
        }
        if weight > 0.0 { sum / weight } else { 0.0 }
    }

    /// Gradient at pixel (x, y), world frame (image rows grow southward).
    fn at(&self, x: usize, y: usize) -> Vec2 {
        let (x, y) = (x as isize, y as isize);
        Vec2::new(self.smoothed(x, y, true), -self.smoothed(x, y, false))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layer::Channels;

    fn layer(
        kind: LayerKind,
        weight: f64,
        channels: Channels,
        w: u32,
        values: Vec<f32>,
    ) -> PaintedLayer {
        let per = match channels {
            Channels::Gray => 1,
            Channels::GrayAlpha => 2,
            Channels::Rgb => 3,
            Channels::Rgba => 4,
        };
        let h = values.len() as u32 / (w * per);
        PaintedLayer {
            kind,
            weight,
            raster: Raster {
                width: w,
                height: h,
                channels,
                max: 255.0,
                values,
            },
        }
    }

    fn run(layers: &[PaintedLayer]) -> MergedMaps {
        merge(layers, &MergeSettings::default(), 1.0, &())
    }

    #[test]
    fn densities_add_up_weighted_by_layer_weight_and_alpha() {
        let a = layer(LayerKind::Density, 1.0, Channels::Gray, 2, vec![255.0, 0.0]);
        let b = layer(
            LayerKind::Density,
            0.5,
            Channels::GrayAlpha,
            2,
            vec![255.0, 255.0, 255.0, 51.0],
        );
        let m = run(&[a, b]);
        assert_eq!(m.walkers.as_slice(), &[1.5, 0.1]);
    }

    #[test]
    fn obstacles_are_a_union_that_clears_densities() {
        let d = layer(LayerKind::Density, 1.0, Channels::Gray, 3, vec![255.0; 3]);
        let o1 = layer(
            LayerKind::Obstacles,
            1.0,
            Channels::Gray,
            3,
            vec![255.0, 0.0, 0.0],
        );
        let o2 = layer(
            LayerKind::Obstacles,
            1.0,
            Channels::Gray,
            3,
            vec![0.0, 0.0, 200.0],
        );
        let m = run(&[d, o1, o2]);
        assert_eq!(m.blocked.as_slice(), &[true, false, true]);
        assert_eq!(m.walkers.as_slice(), &[0.0, 1.0, 0.0]);
    }

    #[test]
    fn people_walk_from_dark_to_bright() {
        // A ramp bright at the top (north) of the image: walk north.
        let values = (0..4).flat_map(|y| [255.0 - 60.0 * y as f32; 4]).collect();
        let m = run(&[layer(LayerKind::Direction, 1.0, Channels::Gray, 4, values)]);
        for v in m.flow.as_slice() {
            assert!((v.normalize() - Vec2::Y).length() < 1e-6, "{v}");
        }
    }

    #[test]
    fn transparent_pixels_do_not_bend_a_stroke() {
        // An eastward ramp painted only in the middle row; the rows around are black and clear.
        let mut values = vec![0.0; 2 * 5 * 3];
        for x in 0..5 {
            values[2 * (5 + x)] = 50.0 * x as f32;
            values[2 * (5 + x) + 1] = 255.0;
        }
        let m = run(&[layer(
            LayerKind::Direction,
            1.0,
            Channels::GrayAlpha,
            5,
            values,
        )]);
        for x in 0..5 {
            assert!((m.flow.get(x, 1).normalize() - Vec2::X).length() < 1e-6);
            assert_eq!(*m.flow_weight.get(x, 0), 0.0);
        }
    }

    #[test]
    fn flow_maps_decode_east_and_north() {
        let px = |r: f32, g: f32| [r, g, 128.0, 255.0];
        let values = [px(255.0, 128.0), px(128.0, 0.0), px(128.0, 128.0)].concat();
        let m = run(&[layer(LayerKind::Flow, 1.0, Channels::Rgba, 3, values)]);
        assert!((m.flow.get(0, 0).normalize() - Vec2::X).length() < 1e-6);
        assert!((m.flow.get(1, 0).normalize() + Vec2::Y).length() < 1e-6);
        assert_eq!(*m.flow_weight.get(2, 0), 0.0, "128,128 is no direction");
    }
}
