//! Pictures of stage 3 (the signed-error map, Crowd Art Figure 5; the convergence, its
//! Figure 6) and of stage 4 (one patch's patterns and lines).

use crate::draw::{Canvas, diverging, line_colour};
use crowd_core::PatchGraph;
use crowd_core::patch_graph::Cell;
use crowd_core::patterns::{Crossing, IterationFigures, Patterns, Side, border_point};
use crowd_core::trajectories::{PatchMotion, PointKind};
use glam::Vec2;
use image::{Rgb, RgbImage};

const BACKGROUND: Rgb<u8> = Rgb([250, 250, 250]);
const EMPTY: Rgb<u8> = Rgb([225, 225, 225]);
const INK: Rgb<u8> = Rgb([20, 20, 20]);
const GRID: Rgb<u8> = Rgb([205, 205, 205]);

/// What the optimisation picture shows.
pub const PATTERNS_LEGEND: &str = "left: signed density error per patch, (measured - requested) \
/ rho_max, green = 0, blue = too few (full blue at -0.25), red = too many (full red at +0.25); \
white arrows = requested direction, black arrows = measured direction. Right: convergence, E \
(black), E_rho (blue), E_d (red) per iteration; gray lines every 0.05 of E, the scale's top is \
the largest value plotted";

/// What the patch picture shows.
pub const PATCH_LEGEND: &str = "left: top view of the patch, one colour per walker, filled dots \
= entry points, rings = exit points, pink squares = standers, dark = obstacles. Middle: space-time \
(x across, time up, one period; a line leaving the top comes back at the bottom). Right: the four \
patterns unrolled (west, south, east, north faces; position along the border across, time up), \
green = entries, red = exits";

/// The signed-error map beside the convergence plot.
pub fn render_patterns(graph: &PatchGraph, patterns: &Patterns) -> RgbImage {
    let map = error_map(graph, patterns);
    let plot = convergence(patterns, map.height().max(300));
    let gap = 16;
    let mut canvas = Canvas::new(
        map.width() + plot.width() + 3 * gap,
        map.height().max(plot.height()) + 2 * gap,
        BACKGROUND,
    );
    canvas.paste(&map, gap, gap);
    canvas.paste(&plot, map.width() + 2 * gap, gap);
    canvas.into_image()
}

fn error_map(graph: &PatchGraph, patterns: &Patterns) -> RgbImage {
    let w = &graph.world;
    let px = (900 / w.cols.max(w.rows)).clamp(3, 40);
    let mut canvas = Canvas::new(w.cols * px, w.rows * px, EMPTY);
    let origin = |c: Cell| (c.col * px, (w.rows - 1 - c.row) * px);
    let area = graph.patch_area();
    for (p, m) in graph.patches.iter().zip(&patterns.measured) {
        let requested = p.walker_density + m.standers as f64 / area;
        let e = (m.density - requested) / patterns.rho_max;
        let (x, y) = origin(p.cell);
        canvas.fill(x, y, px, px, diverging((e / 0.25) as f32));
    }
    if px >= 10 {
        for p in &graph.patches {
            let Some(d) = p.direction else { continue };
            let (x, y) = origin(p.cell);
            let centre = Vec2::new(x as f32 + px as f32 / 2.0, y as f32 + px as f32 / 2.0);
            let len = 0.4 * px as f32;
            let req = Vec2::new(d.dir.x as f32, -d.dir.y as f32) * len;
            canvas.arrow(centre - req, centre + req, Rgb([255, 255, 255]));
            if let Some(m) = patterns.measured[p.id.0 as usize].direction {
                let v = Vec2::new(m.x as f32, -m.y as f32) * len * 0.8;
                canvas.thick_line(
                    ((centre - v).x as f64, (centre - v).y as f64),
                    ((centre + v).x as f64, (centre + v).y as f64),
                    1,
                    INK,
                );
                canvas.disc(((centre + v).x as f64, (centre + v).y as f64), 2, INK, true);
            }
        }
    }
    canvas.into_image()
}

fn convergence(patterns: &Patterns, height: u32) -> RgbImage {
    let (width, margin) = (520u32, 10u32);
    let mut canvas = Canvas::new(width, height, Rgb([255, 255, 255]));
    let log = &patterns.log;
    let top = log.iter().map(|f| f.e).fold(0.05, f64::max);
    let n = log.len().max(2) as f64 - 1.0;
    let (w, h) = ((width - 2 * margin) as f64, (height - 2 * margin) as f64);
    let at = |i: usize, v: f64| {
        (
            margin as f64 + i as f64 / n * w,
            margin as f64 + h * (1.0 - v / top),
        )
    };
    let mut level = 0.0;
    while level <= top {
        canvas.thick_line(at(0, level), at(log.len().max(2) - 1, level), 1, GRID);
        level += 0.05;
    }
    type Figure = fn(&IterationFigures) -> f64;
    let series: [(Figure, Rgb<u8>); 3] = [
        (|f| f.e_rho, Rgb([40, 60, 200])),
        (|f| f.e_d, Rgb([215, 40, 40])),
        (|f| f.e, INK),
    ];
    for (value, colour) in series {
        for (i, pair) in log.windows(2).enumerate() {
            canvas.thick_line(
                at(i, value(&pair[0])),
                at(i + 1, value(&pair[1])),
                2,
                colour,
            );
        }
    }
    canvas.thick_line(at(0, 0.0), at(log.len().max(2) - 1, 0.0), 1, INK);
    canvas.thick_line(at(0, 0.0), at(0, top), 1, INK);
    canvas.into_image()
}

/// One patch: top view, space-time view and its four patterns unrolled.
pub fn render_patch(
    graph: &PatchGraph,
    crossings: &[Crossing],
    motion: &PatchMotion,
    patch: usize,
    period: f64,
) -> RgbImage {
    let side = graph.world.patch_side_m;
    let size = 420u32;
    let gap = 16u32;
    let faces = 4 * (size / 2) + 3 * 6;
    let mut canvas = Canvas::new(2 * size + faces + 4 * gap, size + 2 * gap, BACKGROUND);
    let s = size as f64 / side;
    // Top view.
    let (ox, oy) = (gap as f64, gap as f64);
    canvas.fill(gap, gap, size, size, Rgb([255, 255, 255]));
    let top = |p: glam::DVec2| (ox + p.x * s, oy + (side - p.y) * s);
    for r in &graph.patches[patch].obstacles {
        let (x0, y1) = top(r.min);
        let (x1, y0) = top(r.max);
        canvas.fill_f(x0, y0, x1, y1, Rgb([60, 60, 66]));
    }
    for st in &motion.standers {
        let (x, y) = top(*st);
        canvas.fill_f(x - 4.0, y - 4.0, x + 4.0, y + 4.0, Rgb([255, 120, 200]));
    }
    for (i, tr) in motion.trajectories.iter().enumerate() {
        let colour = line_colour(i);
        for w in tr.points.windows(2) {
            canvas.thick_line(top(w[0].pos), top(w[1].pos), 2, colour);
        }
        let (first, last) = (tr.points[0], tr.points[tr.points.len() - 1]);
        canvas.disc(top(first.pos), 5, colour, true);
        canvas.disc(top(last.pos), 6, colour, false);
    }
    // Space-time view: x across, time up (wrapped into one period).
    let (sx, sy) = ((2 * gap + size) as f64, gap as f64);
    canvas.fill(2 * gap + size, gap, size, size, Rgb([255, 255, 255]));
    let st = |x: f64, t: f64| (sx + x * s, sy + size as f64 * (1.0 - t / period));
    for (i, tr) in motion.trajectories.iter().enumerate() {
        let colour = line_colour(i);
        for w in tr.points.windows(2) {
            let (a, b) = (w[0], w[1]);
            // Segments are split at whole periods, so each lies within one period.
            let k = ((a.t + b.t) / 2.0 / period).floor() * period;
            canvas.thick_line(st(a.pos.x, a.t - k), st(b.pos.x, b.t - k), 2, colour);
            if a.kind == PointKind::Pause && b.kind == PointKind::Pause {
                canvas.disc(st(a.pos.x, a.t - k), 3, colour, true);
            }
        }
    }
    // The four patterns.
    let face_w = size / 2;
    let fx0 = 3 * gap + 2 * size;
    let order = [Side::West, Side::South, Side::East, Side::North];
    for (k, _) in order.iter().enumerate() {
        canvas.fill(
            fx0 + k as u32 * (face_w + 6),
            gap,
            face_w,
            size,
            Rgb([255, 255, 255]),
        );
    }
    for c in crossings {
        let border = &graph.borders[c.border as usize];
        let (a, b) = border_point(border, side, c.s);
        for (view, entering) in [
            (a, c.way != crowd_core::patterns::Way::AToB),
            (b, c.way == crowd_core::patterns::Way::AToB),
        ] {
            if view.patch.0 as usize != patch {
                continue;
            }
            let k = order.iter().position(|&o| o == view.side).expect("a side");
            let along = match view.side {
                Side::West | Side::East => view.pos.y,
                Side::South | Side::North => view.pos.x,
            };
            let x = (fx0 + k as u32 * (face_w + 6)) as f64 + along / side * face_w as f64;
            let y = gap as f64 + size as f64 * (1.0 - c.t / period);
            let colour = if entering {
                Rgb([40, 160, 60])
            } else {
                Rgb([215, 40, 40])
            };
            canvas.disc((x, y), 4, colour, entering);
        }
    }
    canvas.into_image()
}
