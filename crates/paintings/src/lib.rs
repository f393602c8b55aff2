//! Random paintings: a seeded generator of scenes with every layer kind (density, static,
//! gray direction, RGBA flow, obstacles with thin walls, narrow gaps and closed pockets;
//! uniform, empty and saturated regions), from 2 x 2 patches up, with the patch side, the
//! period and the pixel size varied within what the pipeline accepts. The tests build a few of
//! them through the whole pipeline and hold every guarantee to them (`verdict`);
//! `cargo xtask soak` builds many and prints each failure's seed, so that anyone can write the
//! scene out again (`crowd-paintings write --seed N`) and rebuild it with `crowd build`.

pub mod brush;
pub mod verdict;

use brush::Rect;
use image::{GrayImage, RgbaImage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

/// How large the random scenes may be.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// The most patches along either side of the scene (at least 2).
    pub max_patches: u32,
}

/// One layer of a painting.
pub enum Layer {
    Gray {
        kind: &'static str,
        image: GrayImage,
    },
    Rgba {
        kind: &'static str,
        image: RgbaImage,
    },
}

impl Layer {
    pub fn kind(&self) -> &'static str {
        match self {
            Layer::Gray { kind, .. } | Layer::Rgba { kind, .. } => kind,
        }
    }
}

/// A painted scene and the settings of its build.
pub struct Painting {
    pub seed: u64,
    pub meters_per_pixel: f64,
    pub patch_side_m: f64,
    pub period_s: f64,
    pub radius_m: f64,
    pub walkers: u64,
    pub standers: u64,
    /// Patches along x and y (the maps may be a strip wider, which the graph leaves out).
    pub patches: (u32, u32),
    pub layers: Vec<Layer>,
}

/// The painting of `seed`.
pub fn random(seed: u64, limits: Limits) -> Painting {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (patch_side_m, meters_per_pixel) = *pick(&mut rng, &SIDES);
    let side_px = (patch_side_m / meters_per_pixel).round() as u32;
    let max = limits.max_patches.max(2);
    let patches = (rng.random_range(2..=max), rng.random_range(2..=max));
    // A quarter of the scenes leave a strip that is not a whole patch.
    let strip = |rng: &mut ChaCha8Rng| {
        if rng.random_bool(0.25) {
            rng.random_range(1..side_px)
        } else {
            0
        }
    };
    let w = patches.0 * side_px + strip(&mut rng);
    let h = patches.1 * side_px + strip(&mut rng);
    let obstacles = obstacles(&mut rng, w, h, side_px);
    let density = density(&mut rng, w, h, side_px);
    let mut layers = vec![Layer::Gray {
        kind: "Density",
        image: density,
    }];
    if rng.random_bool(0.4) {
        layers.push(Layer::Gray {
            kind: "Static",
            image: blobs(&mut rng, w, h, side_px),
        });
    }
    if let Some(layer) = direction(&mut rng, w, h) {
        layers.push(layer);
    }
    let free_m2 = free_area(&obstacles, w, h, meters_per_pixel);
    if let Some(o) = obstacles {
        layers.push(Layer::Gray {
            kind: "Obstacles",
            image: o,
        });
    }
    // People per free square metre: from sparse to a third of the default rho_max of 0.35.
    let walker_density = rng.random_range(0.01..0.12);
    let walkers = ((walker_density * free_m2) as u64).max(2);
    let has_static = layers.iter().any(|l| l.kind() == "Static");
    let standers = if has_static {
        (rng.random_range(0.0..0.01) * free_m2) as u64
    } else {
        0
    };
    Painting {
        seed,
        meters_per_pixel,
        patch_side_m,
        period_s: f64::from(rng.random_range(10u32..=30)),
        radius_m: *pick(&mut rng, &[0.25, 0.3, 0.3, 0.35]),
        walkers,
        standers,
        patches,
        layers,
    }
}

/// (patch side, metres per pixel): a whole number of pixels a patch, sides of 4 to 10 m.
const SIDES: [(f64, f64); 6] = [
    (4.0, 0.5),
    (5.0, 1.0),
    (6.0, 0.5),
    (8.0, 1.0),
    (8.0, 0.5),
    (10.0, 1.0),
];

fn pick<'a, T>(rng: &mut ChaCha8Rng, from: &'a [T]) -> &'a T {
    &from[rng.random_range(0..from.len())]
}

fn rect(rng: &mut ChaCha8Rng, w: u32, h: u32, min: u32) -> Rect {
    let (rw, rh) = (
        rng.random_range(min.min(w)..=w),
        rng.random_range(min.min(h)..=h),
    );
    let (x0, y0) = (rng.random_range(0..=w - rw), rng.random_range(0..=h - rh));
    Rect {
        x0,
        y0,
        x1: x0 + rw,
        y1: y0 + rh,
    }
}

/// Walker density: a uniform, blobby or banded base, then empty and saturated regions.
fn density(rng: &mut ChaCha8Rng, w: u32, h: u32, side: u32) -> GrayImage {
    let mut img = match rng.random_range(0..3) {
        0 => GrayImage::from_pixel(w, h, image::Luma([rng.random_range(40..=255)])),
        1 => blobs(rng, w, h, side),
        _ => {
            let mut img = GrayImage::new(w, h);
            for _ in 0..rng.random_range(1..4) {
                let r = rect(rng, w, h, side);
                brush::fill(&mut img, r, rng.random_range(60..=255));
            }
            img
        }
    };
    for _ in 0..rng.random_range(0..3) {
        let r = rect(rng, w / 2, h / 2, side / 2);
        brush::fill(&mut img, r, 0);
    }
    if rng.random_bool(0.3) {
        let r = rect(rng, w / 2, h / 2, side / 2);
        brush::fill(&mut img, r, 255);
    }
    img
}

fn blobs(rng: &mut ChaCha8Rng, w: u32, h: u32, side: u32) -> GrayImage {
    let mut img = GrayImage::new(w, h);
    for _ in 0..rng.random_range(1..6) {
        let (cx, cy) = (
            rng.random_range(0.0..f64::from(w)),
            rng.random_range(0.0..f64::from(h)),
        );
        let radius = rng.random_range(f64::from(side)..f64::from(side * 4));
        brush::blob(&mut img, cx, cy, radius, rng.random_range(80..=255));
    }
    img
}

/// A gray direction ramp, an RGBA flow map, or no direction at all.
fn direction(rng: &mut ChaCha8Rng, w: u32, h: u32) -> Option<Layer> {
    let whole = Rect {
        x0: 0,
        y0: 0,
        x1: w,
        y1: h,
    };
    match rng.random_range(0..10) {
        0..4 => {
            let mut img = RgbaImage::new(w, h);
            let region = if rng.random_bool(0.5) {
                whole
            } else {
                rect(rng, w, h, 4)
            };
            let angle = rng.random_range(0.0..std::f64::consts::TAU);
            brush::ramp(&mut img, angle, region, rng.random_range(128..=255));
            Some(Layer::Rgba {
                kind: "Direction",
                image: img,
            })
        }
        4..7 => {
            let mut img = RgbaImage::from_pixel(w, h, image::Rgba([128, 128, 128, 0]));
            for _ in 0..rng.random_range(1..4) {
                let r = rect(rng, w, h, 4);
                let angle = rng.random_range(0.0..std::f64::consts::TAU);
                brush::flow(
                    &mut img,
                    r,
                    angle.cos(),
                    angle.sin(),
                    rng.random_range(96..=255),
                );
            }
            Some(Layer::Rgba {
                kind: "Flow",
                image: img,
            })
        }
        _ => None,
    }
}

/// Obstacles, in two scenes of three: thin walls with narrow gaps, closed pockets, blocks.
fn obstacles(rng: &mut ChaCha8Rng, w: u32, h: u32, side: u32) -> Option<GrayImage> {
    if rng.random_bool(1.0 / 3.0) {
        return None;
    }
    let mut img = GrayImage::new(w, h);
    for _ in 0..rng.random_range(0..4) {
        let horizontal = rng.random_bool(0.5);
        let length = rng.random_range(side..=if horizontal { w } else { h }.max(side));
        let (x, y) = (rng.random_range(0..w), rng.random_range(0..h));
        let wall = brush::Wall {
            x,
            y,
            length,
            thickness: rng.random_range(1..=2),
            horizontal,
            gap_at: rng.random_range(0..length),
            gap: rng.random_range(0..=side / 2),
        };
        brush::wall(&mut img, &wall);
    }
    if rng.random_bool(0.3) {
        let r = rect(rng, w / 3, h / 3, 3);
        brush::pocket(&mut img, r);
    }
    for _ in 0..rng.random_range(0..3) {
        let r = rect(rng, (w / 4).max(1), (h / 4).max(1), 1);
        brush::fill(&mut img, r, 255);
    }
    Some(img)
}

/// Square metres free of obstacles.
fn free_area(obstacles: &Option<GrayImage>, w: u32, h: u32, meters_per_pixel: f64) -> f64 {
    let free = obstacles.as_ref().map_or(w as usize * h as usize, |o| {
        o.pixels().filter(|p| p[0] < 128).count()
    });
    free as f64 * meters_per_pixel * meters_per_pixel
}

impl Painting {
    /// Writes the layers and `pipeline.ron` (building into `out`, beside them) into `dir`;
    /// returns the pipeline's path.
    pub fn write(&self, dir: &Path) -> anyhow::Result<PathBuf> {
        use anyhow::Context;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
        let mut specs = String::new();
        for layer in &self.layers {
            let file = format!("{}.png", layer.kind().to_lowercase());
            match layer {
                Layer::Gray { image, .. } => image.save(dir.join(&file)),
                Layer::Rgba { image, .. } => image.save(dir.join(&file)),
            }
            .with_context(|| format!("{}: cannot write", dir.join(&file).display()))?;
            specs += &format!("            (kind: {}, path: \"{file}\"),\n", layer.kind());
        }
        let text = format!(
            "// Random painting {seed} ({px} x {py} patches): `crowd-paintings write --seed {seed}`.\n\
             (\n    scene: (\n        meters_per_pixel: {mpp:?},\n        layers: [\n{specs}        ],\n    ),\n    \
             walkers: {walkers},\n    standers: {standers},\n    patch_side_m: {side:?},\n    \
             period_s: {period:?},\n    radius_m: {radius:?},\n    seed: {seed},\n    output: \"out\",\n)\n",
            seed = self.seed,
            px = self.patches.0,
            py = self.patches.1,
            mpp = self.meters_per_pixel,
            walkers = self.walkers,
            standers = self.standers,
            side = self.patch_side_m,
            period = self.period_s,
            radius = self.radius_m,
        );
        let path = dir.join("pipeline.ron");
        std::fs::write(&path, text).with_context(|| format!("{}: cannot write", path.display()))?;
        Ok(path)
    }
}
