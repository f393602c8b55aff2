//! Where a new crossing may go: on an open interval, clear of the patch corners, and far enough
//! in space or time from the other crossings of its border that the two characters never come
//! closer than the sum of their radii near the border.
//!
//! The rule between two crossings is `crowd_geometry::spacing::CrossingRule` (band pieces apart).

use crowd_core::patterns::{Crossing, Way};
use crowd_core::{Interval, PatchGraph};

#[derive(Clone)]
pub struct Spacing {
    /// Per border, the stretches where a crossing may be (open intervals shrunk by a radius
    /// and a margin, and kept clear of the corners).
    pub usable: Vec<Vec<Interval>>,
    /// The rule between two crossings of one border.
    pub rule: crowd_geometry::spacing::CrossingRule,
    /// Per border, the unit vector across it.
    pub normals: Vec<glam::DVec2>,
}

impl Spacing {
    pub fn new(graph: &PatchGraph) -> Spacing {
        let r = graph.radius_m;
        let side = graph.world.patch_side_m;
        let rule = crowd_geometry::spacing::CrossingRule::new(r);
        let (edge, corner) = (rule.edge, rule.corner);
        let usable = graph
            .borders
            .iter()
            .map(|b| {
                b.open
                    .iter()
                    .map(|i| Interval {
                        start: (i.start + edge).max(corner),
                        end: (i.end - edge).min(side - corner),
                    })
                    .filter(|i| i.len() > 0.0)
                    .collect()
            })
            .collect();
        Spacing {
            usable,
            rule,
            normals: graph.borders.iter().map(|b| b.across()).collect(),
        }
    }

    /// The nearest usable position to `s` on `border`.
    pub fn clamp(&self, border: usize, s: f64) -> Option<f64> {
        self.usable[border]
            .iter()
            .map(|i| s.clamp(i.start, i.end))
            .min_by(|a, b| (a - s).abs().total_cmp(&(b - s).abs()))
    }

    /// Whether two crossings of one border keep their characters apart near it.
    pub fn compatible(&self, a: &Crossing, b: &Crossing, period: f64) -> bool {
        let normal = self.normals[a.border as usize];
        // Band pieces that stay further apart along the border than the gap, with a margin
        // far above rounding, pass the rule: no need to measure their approach.
        let (reach_a, reach_b) = (self.reach(a, normal), self.reach(b, normal));
        if (a.s - b.s).abs() >= self.rule.gap + reach_a + reach_b + 1e-6 {
            return true;
        }
        self.rule.compatible(a, b, normal, period)
    }

    /// How far along its border a crossing's band piece (with its straight continuations)
    /// drifts from the crossing, at most.
    fn reach(&self, c: &Crossing, normal: glam::DVec2) -> f64 {
        let across = c.velocity.dot(normal).abs().max(1e-6);
        let along = c.velocity.dot(glam::DVec2::new(normal.y, normal.x)).abs();
        along * (self.rule.band / across + crowd_geometry::spacing::HOLD_S)
    }

    /// Whether `c` fits among `others`.
    pub fn fits(&self, c: &Crossing, others: &[Crossing], period: f64) -> bool {
        others.iter().all(|o| self.compatible(c, o, period))
    }
}

/// Whether every crossing of every border keeps its spacing (for tests and reports).
pub fn all_spaced(spacing: &Spacing, crossings: &[Vec<Crossing>], period: f64) -> bool {
    crossings.iter().enumerate().all(|(b, list)| {
        list.iter().enumerate().all(|(i, c)| {
            spacing.usable[b]
                .iter()
                .any(|u| c.s >= u.start - 1e-9 && c.s <= u.end + 1e-9)
                && list[i + 1..]
                    .iter()
                    .all(|o| spacing.compatible(c, o, period))
        })
    })
}

/// Mirror of a way.
pub fn reverse(way: Way) -> Way {
    match way {
        Way::AToB => Way::BToA,
        Way::BToA => Way::AToB,
    }
}
