//! The walkable world of an editing problem: its bounds, its obstacles (rectangles) and the
//! goals characters head for, turned into the fields the model reads (Allain eq. 19, 23-25).

use crate::field::{Lattice, NodeField, VectorField, fast_marching, unit_gradient};
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// An axis-aligned rectangle in metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    pub min: DVec2,
    pub max: DVec2,
}

impl Rect {
    pub fn new(min: DVec2, max: DVec2) -> Rect {
        Rect { min, max }
    }

    /// The `w` x `h` rectangle centred on `c`.
    pub fn centred(c: DVec2, w: f64, h: f64) -> Rect {
        let half = DVec2::new(w, h) / 2.0;
        Rect::new(c - half, c + half)
    }

    pub fn contains(&self, p: DVec2) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    pub fn area(&self) -> f64 {
        let s = self.max - self.min;
        s.x * s.y
    }

    pub fn centre(&self) -> DVec2 {
        (self.min + self.max) / 2.0
    }
}

/// The grid the world's fields live on: fine enough that a field changes little across a
/// character (radius 0.25-0.35 m).
pub const FIELD_SPACING: f64 = 0.25;

/// Where characters walk and what they head for.
#[derive(Clone, Debug)]
pub struct World {
    pub bounds: Rect,
    pub obstacles: Vec<Rect>,
    pub goals: Vec<Rect>,
    /// Distance to the nearest obstacle surface (huge when there are none).
    pub obstacle_distance: NodeField,
    /// The unit direction away from the nearest obstacle.
    pub obstacle_away: VectorField,
    /// Per goal, the walking direction W (unit, along the shortest way round obstacles).
    pub will: Vec<VectorField>,
}

impl World {
    /// The world inside `bounds` with `obstacles`, each goal a rectangle whose nodes are the
    /// Eikonal sources of its walking direction.
    pub fn new(bounds: Rect, obstacles: Vec<Rect>, goals: Vec<Rect>) -> World {
        let lattice = Lattice::covering(bounds.min, bounds.max, FIELD_SPACING);
        let mask = |rects: &[Rect]| -> Vec<bool> {
            (0..lattice.len())
                .map(|k| {
                    let p = lattice.node(k % lattice.nx, k / lattice.nx);
                    rects.iter().any(|r| r.contains(p))
                })
                .collect()
        };
        let blocked = mask(&obstacles);
        let (obstacle_distance, obstacle_away) = if obstacles.is_empty() {
            let far = NodeField::constant(lattice, 1e3);
            let zero = NodeField::constant(lattice, 0.0);
            (
                far,
                VectorField {
                    x: zero.clone(),
                    y: zero,
                },
            )
        } else {
            let mut d = fast_marching(lattice, &blocked, &vec![false; lattice.len()]);
            let away = unit_gradient(&d, 1.0);
            // The obstacle's surface lies half a node spacing in front of its last node.
            for v in &mut d.values {
                *v = (*v - FIELD_SPACING / 2.0).max(0.0);
            }
            (d, away)
        };
        let will = goals
            .iter()
            .map(|g| unit_gradient(&fast_marching(lattice, &mask(&[*g]), &blocked), -1.0))
            .collect();
        World {
            bounds,
            obstacles,
            goals,
            obstacle_distance,
            obstacle_away,
            will,
        }
    }

    /// Inside the bounds and out of every obstacle.
    pub fn is_free(&self, p: DVec2) -> bool {
        self.bounds.contains(p) && !self.obstacles.iter().any(|o| o.contains(p))
    }
}
