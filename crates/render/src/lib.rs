//! Pictures of stage files. Each function is pure: a stage file in, an image out; the command
//! line saves it. [`legend`] texts say what the colours mean, since the pictures carry no text.

mod draw;
mod optimize;
pub mod plot;

pub use draw::line_colour;
pub use optimize::{PATCH_LEGEND, PATTERNS_LEGEND, render_patch, render_patterns};

use crowd_core::patch_graph::{BorderAxis, Cell};
use crowd_core::{MergedMaps, PatchGraph};
use draw::{Canvas, colormap};
use glam::{DVec2, Vec2};
use image::{Rgb, RgbImage};

const BACKGROUND: Rgb<u8> = Rgb([250, 250, 250]);
const EMPTY: Rgb<u8> = Rgb([236, 236, 236]);
const OBSTACLE: Rgb<u8> = Rgb([60, 60, 66]);
const CLOSED: Rgb<u8> = Rgb([230, 40, 40]);
const COMPONENT_EDGE: Rgb<u8> = Rgb([0, 0, 0]);
const ARROW: Rgb<u8> = Rgb([255, 255, 255]);
const GRID: Rgb<u8> = Rgb([120, 120, 120]);
const STANDERS: Rgb<u8> = Rgb([255, 120, 200]);

/// What the merged-maps picture shows.
pub const MAPS_LEGEND: &str = "four panels: top left walker density, top right stander density \
(dark blue = none, yellow = the densest pixel of each map); bottom left painted direction (hue = \
heading: red east, green-yellow north, cyan west, blue-violet south; brightness = weight; white \
arrows every few pixels); bottom right obstacles (dark = blocked)";

/// What the patch-graph picture shows.
pub const GRAPH_LEGEND: &str = "one square per patch, shade = requested walker density (dark \
blue = least, yellow = most, scale bar at the bottom); white arrows = requested direction (length \
= weight); pink squares = standing characters (size = density); dark rectangles = obstacles; light gray = no patch (empty), dark gray = no patch \
(blocked); red = closed part of a shared border; black lines = edges of connected components \
and of the patch graph";

/// The merged maps as four panels.
pub fn render_maps(maps: &MergedMaps) -> RgbImage {
    let (w, h) = (maps.width(), maps.height());
    let scale = (640 / w.max(h).max(1)).max(1);
    let gap = 8;
    let (pw, ph) = (w * scale, h * scale);
    let mut canvas = Canvas::new(2 * pw + 3 * gap, 2 * ph + 3 * gap, BACKGROUND);
    let max_of = |v: &[f32]| {
        v.iter()
            .copied()
            .fold(0.0f32, f32::max)
            .max(f32::MIN_POSITIVE)
    };
    let (wmax, smax) = (
        max_of(maps.walkers.as_slice()),
        max_of(maps.standers.as_slice()),
    );
    let fmax = max_of(maps.flow_weight.as_slice());
    let origins = [
        (gap, gap),
        (2 * gap + pw, gap),
        (gap, 2 * gap + ph),
        (2 * gap + pw, 2 * gap + ph),
    ];
    for y in 0..h {
        for x in 0..w {
            let blocked = *maps.blocked.get(x, y);
            let colours = [
                colormap(*maps.walkers.get(x, y) / wmax),
                colormap(*maps.standers.get(x, y) / smax),
                draw::heading_colour(*maps.flow.get(x, y), *maps.flow_weight.get(x, y) / fmax),
                if blocked {
                    OBSTACLE
                } else {
                    Rgb([245, 245, 245])
                },
            ];
            for ((ox, oy), colour) in origins.iter().zip(colours) {
                // Obstacles on the density panels too: densities are cleared under them.
                let c = if blocked && *oy == gap {
                    OBSTACLE
                } else {
                    colour
                };
                canvas.fill(ox + x * scale, oy + y * scale, scale, scale, c);
            }
        }
    }
    // Direction arrows, from the mean flow of blocks of pixels.
    let step = (w.max(h) / 24).max(4);
    for by in (0..h).step_by(step as usize) {
        for bx in (0..w).step_by(step as usize) {
            let (mut sum, mut weight, mut n) = (Vec2::ZERO, 0.0, 0.0);
            for y in by..(by + step).min(h) {
                for x in bx..(bx + step).min(w) {
                    sum += *maps.flow.get(x, y);
                    weight += *maps.flow_weight.get(x, y);
                    n += 1.0;
                }
            }
            if let Some(dir) = sum.try_normalize()
                && weight / n > 0.05 * fmax
            {
                let centre = Vec2::new(
                    (origins[2].0 + bx * scale) as f32 + step as f32 * scale as f32 / 2.0,
                    (origins[2].1 + by * scale) as f32 + step as f32 * scale as f32 / 2.0,
                );
                // World y is north, image y is south.
                let d = Vec2::new(dir.x, -dir.y) * 0.4 * (step * scale) as f32;
                canvas.arrow(centre - d, centre + d, ARROW);
            }
        }
    }
    canvas.into_image()
}

/// The patch graph: requested density, direction, obstacles, closed borders and components.
pub fn render_graph(graph: &PatchGraph) -> RgbImage {
    let w = &graph.world;
    let (px, margin) = graph_layout(w);
    let bar = 14;
    let (width, height) = (w.cols * px + 2 * margin, w.rows * px + 3 * margin + bar);
    let mut canvas = Canvas::new(width, height, BACKGROUND);
    let side = w.patch_side_m;
    // Top-left pixel of a cell (world rows grow north, image rows south).
    let origin = |cell: Cell| {
        (
            margin + cell.col * px,
            margin + (w.rows - 1 - cell.row) * px,
        )
    };
    let max_density = graph
        .patches
        .iter()
        .map(|p| p.walker_density)
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let max_standers = graph
        .patches
        .iter()
        .map(|p| p.stander_density)
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);

    for row in 0..w.rows {
        for col in 0..w.cols {
            let cell = Cell { col, row };
            let (x, y) = origin(cell);
            let colour = match graph.patch_at(cell) {
                Some(i) => colormap((graph.patches[i].walker_density / max_density) as f32),
                None => EMPTY,
            };
            canvas.fill(x, y, px, px, colour);
            if px >= 8 {
                // A faint outline so single patches can be told apart.
                canvas.thick_line((x as f64, y as f64), ((x + px) as f64, y as f64), 1, GRID);
                canvas.thick_line((x as f64, y as f64), (x as f64, (y + px) as f64), 1, GRID);
            }
        }
    }
    let to_px = |cell: Cell, local: DVec2| {
        let (x, y) = origin(cell);
        let s = px as f64 / side;
        (x as f64 + local.x * s, y as f64 + (side - local.y) * s)
    };
    for p in &graph.patches {
        for r in &p.obstacles {
            let (x0, y1) = to_px(p.cell, r.min);
            let (x1, y0) = to_px(p.cell, r.max);
            canvas.fill_f(x0, y0, x1, y1, OBSTACLE);
        }
    }
    for &cell in &graph.dropped.blocked {
        let (x, y) = origin(cell);
        canvas.fill(x, y, px, px, OBSTACLE);
    }
    // Borders: red where a shared border is closed, black between components and at the edge.
    let s = px as f64 / side;
    for b in &graph.borders {
        let (pa, pb) = (graph.patch(b.a), graph.patch(b.b));
        let (x, y) = origin(pa.cell);
        let (x, y) = (x as f64, y as f64);
        let segment = |from: f64, to: f64| match b.axis {
            BorderAxis::Vertical => (
                (x + px as f64, y + px as f64 - from * s),
                (x + px as f64, y + px as f64 - to * s),
            ),
            BorderAxis::Horizontal => ((x + from * s, y), (x + to * s, y)),
        };
        let mut closed_from = 0.0;
        for iv in b.open.iter().chain(std::iter::once(&crowd_core::Interval {
            start: side,
            end: side,
        })) {
            if iv.start > closed_from + 1e-9 {
                let (a, c) = segment(closed_from, iv.start);
                canvas.thick_line(a, c, 1, CLOSED);
            }
            closed_from = iv.end;
        }
        if pa.component != pb.component {
            let (a, c) = segment(0.0, side);
            canvas.thick_line(a, c, 2, COMPONENT_EDGE);
        }
    }
    for p in &graph.patches {
        let (x, y) = origin(p.cell);
        let (x, y, e) = (x as f64, y as f64, px as f64);
        let neighbours = [
            (1i64, 0i64, ((x + e, y), (x + e, y + e))),
            (-1, 0, ((x, y), (x, y + e))),
            (0, 1, ((x, y), (x + e, y))),
            (0, -1, ((x, y + e), (x + e, y + e))),
        ];
        for (dc, dr, (a, c)) in neighbours {
            let (nc, nr) = (p.cell.col as i64 + dc, p.cell.row as i64 + dr);
            let kept = nc >= 0
                && nr >= 0
                && graph
                    .patch_at(Cell {
                        col: nc as u32,
                        row: nr as u32,
                    })
                    .is_some();
            if !kept {
                canvas.thick_line(a, c, 2, COMPONENT_EDGE);
            }
        }
        if p.stander_density > 0.0 {
            let r = (0.3 * e * (p.stander_density / max_standers).sqrt()).max(1.0);
            canvas.fill_f(
                x + e / 2.0 - r,
                y + e / 2.0 - r,
                x + e / 2.0 + r,
                y + e / 2.0 + r,
                STANDERS,
            );
        }
        if let Some(d) = p.direction {
            let centre = Vec2::new((x + e / 2.0) as f32, (y + e / 2.0) as f32);
            let len = (0.42 * e * d.weight.clamp(0.35, 1.0)) as f32;
            let v = Vec2::new(d.dir.x as f32, -d.dir.y as f32) * len;
            canvas.arrow(centre - v, centre + v, ARROW);
        }
    }
    // Scale bar: density 0 (left) to the largest requested (right).
    let y = w.rows * px + 2 * margin;
    let bar_w = width - 2 * margin;
    for i in 0..bar_w {
        canvas.fill(
            margin + i,
            y,
            1,
            bar,
            colormap(i as f32 / (bar_w - 1).max(1) as f32),
        );
    }
    canvas.into_image()
}

/// Encodes a picture as PNG and writes it atomically.
/// Pixels per patch and the margin of [`render_graph`]'s picture.
fn graph_layout(w: &crowd_core::patch_graph::World) -> (u32, u32) {
    ((1400 / w.cols.max(w.rows)).clamp(4, 48), 12)
}

/// [`render_graph`] with the patches `marked` filled red: where a build's warnings are.
pub fn render_marked(graph: &PatchGraph, marked: &[u32]) -> RgbImage {
    let mut image = render_graph(graph);
    let w = &graph.world;
    let (px, margin) = graph_layout(w);
    for &p in marked {
        let Some(patch) = graph.patches.get(p as usize) else {
            continue;
        };
        let (x0, y0) = (
            margin + patch.cell.col * px,
            margin + (w.rows - 1 - patch.cell.row) * px,
        );
        for y in y0..y0 + px {
            for x in x0..x0 + px {
                image.put_pixel(x, y, image::Rgb([230, 20, 20]));
            }
        }
    }
    image
}

/// What [`render_marked`] shows.
pub const MARKED_LEGEND: &str = "the patch graph as in the stage 2 picture, with every patch a \
warning names filled red";

pub fn save_png(image: &RgbImage, path: &std::path::Path) -> crowd_core::Result<()> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| crowd_core::Error::Image {
            path: path.to_path_buf(),
            message: format!("cannot encode the picture: {e}"),
        })?;
    crowd_core::files::write_atomic(path, &bytes)
}
