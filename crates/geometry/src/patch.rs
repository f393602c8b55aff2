//! One patch as the encounter test sees it: its square, its period, the characters' radius,
//! the walls and standers a walker must keep clear of. Stage 5 repairs a patch against it,
//! stage 6 re-checks its curves against it, and both gather the walls the same way
//! ([`obstacles_near`]).

use crowd_core::{PatchGraph, Rect};
use glam::DVec2;

/// What a patch holds besides its walkers.
pub struct Patch<'a> {
    pub side_m: f64,
    pub period_s: f64,
    pub radius_m: f64,
    pub obstacles: &'a [Rect],
    pub standers: &'a [DVec2],
}

impl Patch<'_> {
    /// What a walker's path is routed round (`Path::reroute`): the patch's own obstacles (off
    /// the border bands, a walker is a radius or more from any wall across a border already)
    /// and every stander as a square of half-side r (a path a radius clear of the square is a
    /// diameter clear of the stander).
    pub fn walls(&self) -> Vec<Rect> {
        let side = self.side_m;
        let r = DVec2::splat(self.radius_m);
        self.obstacles
            .iter()
            .filter(|o| o.max.x > 0.0 && o.max.y > 0.0 && o.min.x < side && o.min.y < side)
            .copied()
            .chain(self.standers.iter().map(|&s| Rect {
                min: s - r,
                max: s + r,
            }))
            .collect()
    }

    /// The nearest place to `p` out of the border bands: a walker is within a radius of a
    /// border only on its own band pieces, so two patches' walkers off their bands are always
    /// a diameter apart.
    pub fn keep_inside(&self, p: DVec2) -> DVec2 {
        let edge = self.radius_m + 1e-3;
        p.clamp(DVec2::splat(edge), DVec2::splat(self.side_m - edge))
    }
}

/// The static obstacles a walker of patch `p` can touch: its own, and those of the eight
/// neighbours that come within a diameter of its square, in `p`'s local metres (a walker near a
/// border must keep clear of a wall just across it too).
pub fn obstacles_near(graph: &PatchGraph, p: usize) -> Vec<crowd_core::Rect> {
    let side = graph.world.patch_side_m;
    let reach = 2.0 * graph.radius_m;
    let cell = graph.patches[p].cell;
    let mut out = graph.patches[p].obstacles.clone();
    for dc in -1i64..=1 {
        for dr in -1i64..=1 {
            let (c, r) = (cell.col as i64 + dc, cell.row as i64 + dr);
            if (dc, dr) == (0, 0) || c < 0 || r < 0 {
                continue;
            }
            let neighbour = crowd_core::patch_graph::Cell {
                col: c as u32,
                row: r as u32,
            };
            let Some(q) = graph.patch_at(neighbour) else {
                continue;
            };
            let offset = glam::DVec2::new(dc as f64, dr as f64) * side;
            for o in &graph.patches[q].obstacles {
                let moved = crowd_core::Rect {
                    min: o.min + offset,
                    max: o.max + offset,
                };
                let near = moved.max.x > -reach
                    && moved.max.y > -reach
                    && moved.min.x < side + reach
                    && moved.min.y < side + reach;
                if near {
                    out.push(moved);
                }
            }
        }
    }
    out
}
