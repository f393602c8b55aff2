//! `crowd check`: the tiled world as an engine plays it, checked without sampling gaps.
//!
//! Every trajectory of every patch is put into world coordinates; every pair of walkers (and
//! every walker with every stander and obstacle) that come near each other in space is checked
//! with the analytic closest approach of their segments, over every copy a whole number of
//! periods apart (all measured by `crowd_geometry`). A spatial grid keeps this near linear in the number of segments. Pairs in
//! different patches are checked exactly like pairs in one patch, so collisions across borders
//! are found too.

pub mod motion;

use crowd_core::PatchGraph;
use crowd_core::trajectories::PatchMotion;
use crowd_geometry::{self as geometry, PieceGrid, Segment};
use glam::DVec2;
use rayon::prelude::*;
use std::collections::HashMap;

/// What the check found.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CheckReport {
    /// Pairs of characters that come closer than the sum of their radii at some time (walker
    /// pairs, walker-stander pairs), and walkers closer than their radius to an obstacle.
    pub collisions: u64,
    /// Of those, pairs whose two characters are in different patches when closest.
    pub across_borders: u64,
    /// Smallest distance minus the clearance needed, over everything checked.
    pub min_clearance_m: f64,
    /// Where and when the worst one happens (world metres, seconds in the period).
    pub worst_at: Option<(f64, f64, f64)>,
    pub walkers: u64,
    pub segments: u64,
    /// The stage whose trajectories were checked (`match`, `collide`, `smooth`).
    #[serde(default)]
    pub stage: String,
    /// Exactness, continuity and motion quality (when the patterns were at hand).
    #[serde(default)]
    pub motion: Option<motion::MotionFigures>,
}

struct Piece {
    seg: Segment,
    walker: u32,
    patch: u32,
    /// The crossings the walker's trajectory enters and leaves by, and when (unwrapped).
    entry: (u32, f64),
    exit: (u32, f64),
}

/// The period shifts at which `b`'s trajectory continues `a`'s or `a`'s continues `b`'s (the
/// same character going on through the crossing between them; both when it goes back and
/// forth).
fn continuations(a: &Piece, b: &Piece, period: f64) -> [Option<i64>; 2] {
    let shift = |x: f64, y: f64| Some(((x - y) / period).round() as i64);
    [
        if a.exit.0 == b.entry.0 {
            shift(a.exit.1, b.entry.1)
        } else {
            None
        },
        if b.exit.0 == a.entry.0 {
            shift(a.entry.1, b.exit.1)
        } else {
            None
        },
    ]
}

/// Checks the whole world of `motion` (per patch, in patch order) laid out by `graph`.
pub fn check(graph: &PatchGraph, motion: &[PatchMotion], period_s: f64) -> CheckReport {
    let r = graph.radius_m;
    let mut pieces = Vec::new();
    let mut walker = 0u32;
    let mut standers = Vec::new();
    let mut walls = Vec::new();
    for (p, m) in motion.iter().enumerate() {
        let origin = graph.world_from_patch(graph.patches[p].cell);
        for tr in &m.trajectories {
            let (first, last) = (tr.points[0].t, tr.points[tr.points.len() - 1].t);
            let world = tr.points.iter().map(|p| (origin + p.pos, p.t));
            for seg in geometry::pieces(world) {
                pieces.push(Piece {
                    seg,
                    walker,
                    patch: p as u32,
                    entry: (tr.entry, first),
                    exit: (tr.exit, last),
                });
            }
            walker += 1;
        }
        standers.extend(m.standers.iter().map(|s| (origin + *s, p as u32)));
        walls.extend(
            graph.patches[p]
                .obstacles
                .iter()
                .map(|o| (origin + o.min, origin + o.max)),
        );
    }
    // Spatial grid: a piece goes in every cell its box (grown by the clearance) touches.
    let grid = PieceGrid::new(pieces.iter().map(|p| &p.seg), 4.0, 2.0 * r);
    // Closest approach of two pieces over all copies a whole number of periods apart.
    let pair = |a: &Segment, b: &Segment, skip: [Option<i64>; 2]| -> Option<(f64, f64, DVec2)> {
        geometry::copies((a.t0, a.t1), (b.t0, b.t1), period_s)
            .filter(|&k| !skip.contains(&Some(k)))
            .filter_map(|k| {
                let b = b.shifted(k as f64 * period_s);
                geometry::closest(a, &b).map(|(d, t)| (d, t, a.at(t)))
            })
            .min_by(|x, y| x.0.total_cmp(&y.0))
    };
    // Walker pairs, found once each: in the cell holding the lower corner of their overlap.
    let found: Vec<(u32, u32, f64, f64, DVec2, bool)> = grid
        .cells()
        .par_iter()
        .flat_map_iter(|(k, ids)| {
            let mut out = Vec::new();
            for (x, &i) in ids.iter().enumerate() {
                for &j in &ids[x + 1..] {
                    let (a, b) = (&pieces[i as usize], &pieces[j as usize]);
                    if !grid.owns(*k, &a.seg, &b.seg) {
                        continue;
                    }
                    // A walker meets only its own copies a period or more apart, and the
                    // trajectory that continues it across a border only at other shifts than
                    // the one where it is the same character going on.
                    let skip = if a.walker == b.walker {
                        [Some(0), None]
                    } else {
                        continuations(a, b, period_s)
                    };
                    if let Some((d, t, at)) = pair(&a.seg, &b.seg, skip)
                        && d < 2.0 * r + 1.0
                    {
                        out.push((
                            a.walker.min(b.walker),
                            a.walker.max(b.walker),
                            d,
                            t,
                            at,
                            a.patch != b.patch,
                        ));
                    }
                }
            }
            out.into_iter()
        })
        .collect();
    let mut closest: HashMap<(u32, u32), (f64, f64, DVec2, bool)> = HashMap::new();
    for (a, b, d, t, at, across) in found {
        let e = closest.entry((a, b)).or_insert((d, t, at, across));
        if d < e.0 {
            *e = (d, t, at, across);
        }
    }
    let mut report = CheckReport {
        collisions: 0,
        across_borders: 0,
        min_clearance_m: f64::INFINITY,
        worst_at: None,
        walkers: walker as u64,
        segments: pieces.len() as u64,
        stage: String::new(),
        motion: None,
    };
    let note = |margin: f64, at: DVec2, t: f64, across: bool, report: &mut CheckReport| {
        if margin < -1e-6 {
            report.collisions += 1;
            report.across_borders += across as u64;
        }
        if margin < report.min_clearance_m {
            report.min_clearance_m = margin;
            report.worst_at = Some((at.x, at.y, t.rem_euclid(period_s)));
        }
    };
    let mut pairs: Vec<_> = closest.into_iter().collect();
    pairs.sort_by_key(|(k, _)| *k);
    for (_, (d, t, at, across)) in pairs {
        note(d - 2.0 * r, at, t, across, &mut report);
    }
    // Walkers against standers and obstacles (standers and walls stand still: no copies),
    // each walker-stander and walker-wall pair counted once, at its closest, however many
    // pieces of the walker's path come near.
    let fixed: Vec<((u32, Fixed), f64, f64, DVec2)> = pieces
        .par_iter()
        .flat_map_iter(|piece| {
            let s = &piece.seg;
            let mut out = Vec::new();
            for (i, &(q, _)) in standers.iter().enumerate() {
                if let Some((d, t)) = geometry::closest(s, &Segment::standing(q, s.t0, s.t1))
                    && d < 2.0 * r + 1.0
                {
                    out.push((
                        (piece.walker, Fixed::Stander(i as u32)),
                        d - 2.0 * r,
                        t,
                        s.at(t),
                    ));
                }
            }
            for (i, &(lo, hi)) in walls.iter().enumerate() {
                if (s.p0.min(s.p1) - hi).max_element() > r + 1.0
                    || (lo - s.p0.max(s.p1)).max_element() > r + 1.0
                {
                    continue;
                }
                let (d, t, _) = geometry::to_rect(s, lo, hi);
                if d < r + 1.0 {
                    out.push(((piece.walker, Fixed::Wall(i as u32)), d - r, t, s.at(t)));
                }
            }
            out.into_iter()
        })
        .collect();
    let mut closest_fixed: HashMap<(u32, Fixed), (f64, f64, DVec2)> = HashMap::new();
    for (k, margin, t, at) in fixed {
        let e = closest_fixed.entry(k).or_insert((margin, t, at));
        if margin < e.0 {
            *e = (margin, t, at);
        }
    }
    let mut fixed: Vec<_> = closest_fixed.into_iter().collect();
    fixed.sort_by_key(|(k, _)| *k);
    for (_, (margin, t, at)) in fixed {
        note(margin, at, t, false, &mut report);
    }
    report
}

/// What stands still in the world: a stander or an obstacle box, by index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Fixed {
    Stander(u32),
    Wall(u32),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crowd_core::config::GraphSettings;
    use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory};
    use crowd_core::{Grid, Hash, MergedMaps};

    /// Two 8 m patches side by side.
    fn two_patches() -> PatchGraph {
        let mut maps = MergedMaps::empty(16, 8, 1.0);
        maps.walkers = Grid::filled(16, 8, 1.0);
        let inputs = crowd_graph::GraphInputs {
            walkers: 10,
            standers: 0,
            patch_side_m: 8.0,
            radius_m: 0.3,
            rho_max: 0.35,
            settings: GraphSettings::default(),
        };
        crowd_graph::build_graph(&maps, &inputs, Hash::of(b"t"), &()).unwrap()
    }

    fn walk(entry: u32, exit: u32, from: (f64, f64, f64), to: (f64, f64, f64)) -> Trajectory {
        let point = |(x, y, t): (f64, f64, f64), kind| ControlPoint {
            pos: DVec2::new(x, y),
            t,
            kind,
        };
        Trajectory {
            entry,
            exit,
            points: vec![point(from, PointKind::Entry), point(to, PointKind::Exit)],
        }
    }

    /// A patch holding one walker.
    fn alone(tr: Trajectory) -> PatchMotion {
        PatchMotion {
            standers: vec![],
            trajectories: vec![tr],
        }
    }

    #[test]
    fn a_character_crossing_a_border_does_not_collide_with_itself() {
        let graph = two_patches();
        // Crossing 1 is the shared border: the walker leaves patch 0 and enters patch 1 at t = 6.
        let motion = vec![
            alone(walk(0, 1, (0.0, 4.0, 0.0), (8.0, 4.0, 6.0))),
            alone(walk(1, 2, (0.0, 4.0, 6.0), (8.0, 4.0, 12.0))),
        ];
        let report = check(&graph, &motion, 20.0);
        assert_eq!(report.collisions, 0, "{report:?}");
    }

    #[test]
    fn two_characters_meeting_at_a_border_are_a_collision_across_it() {
        let graph = two_patches();
        // One walks east along y = 4 and leaves patch 0 at t = 6; another, in patch 1, walks
        // along the border's other side and passes the same spot at t = 6.
        let motion = vec![
            alone(walk(0, 1, (0.0, 4.0, 0.0), (8.0, 4.0, 6.0))),
            alone(walk(5, 6, (0.3, 0.0, 2.0), (0.3, 8.0, 10.0))),
        ];
        let report = check(&graph, &motion, 20.0);
        assert_eq!(
            (report.collisions, report.across_borders),
            (1, 1),
            "{report:?}"
        );
        assert!(report.min_clearance_m < -0.2);
    }

    #[test]
    fn a_walker_through_a_stander_is_one_collision_however_finely_its_path_is_cut() {
        let graph = two_patches();
        let mut tr = walk(0, 1, (0.0, 4.0, 0.0), (8.0, 4.0, 8.0));
        // Ten pieces of 0.8 m; the stander at (4, 4) is within reach of several of them.
        tr.points = (0..=10)
            .map(|i| ControlPoint {
                pos: DVec2::new(0.8 * i as f64, 4.0),
                t: 0.8 * i as f64,
                kind: PointKind::Sample,
            })
            .collect();
        let motion = vec![
            PatchMotion {
                standers: vec![DVec2::new(4.0, 4.0)],
                trajectories: vec![tr],
            },
            PatchMotion::default(),
        ];
        let report = check(&graph, &motion, 20.0);
        assert_eq!(report.collisions, 1, "{report:?}");
        assert!((report.min_clearance_m + 0.6).abs() < 1e-9);
    }
}
