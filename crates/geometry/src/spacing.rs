//! How close two crossings of one border may be: the rule stage 3 keeps and stages 4-6 rely on.
//! It lives with the geometry because it is a closest approach of two band walks, measured
//! by the same [`approach`] as every encounter after it.
//!
//! Near a border every character walks its crossing's straight band piece (a radius deep on
//! either side, at the crossing velocity; see [`crowd_core::trajectories::PointKind::Band`]), so
//! what happens there is fixed once for both patches: two band pieces of one border never come
//! within `gap`, at any time modulo the period. Beyond the band, two characters crossing the
//! same spot keep a walk apart in time, so that stage 5 has room to bend their paths.

use crate::approach::approach;
use crowd_core::patterns::Crossing;
use glam::DVec2;

/// How long past each end of its band piece a character is taken to walk on straight, s: a
/// little more than the quarter second within which stage 5 never bends a path near a band
/// end.
pub const HOLD_S: f64 = 0.3;

/// The spacing rule between two crossings of one border.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossingRule {
    /// Closest distance between two characters near a border: 2r + margin.
    pub gap: f64,
    /// Depth inside the patch within which two characters crossing a border in opposite ways
    /// must not meet; deeper, the collide stage can still bend their paths.
    pub meet_depth: f64,
    /// Depth of the band on each side of a border (the character radius).
    pub band: f64,
    /// Least distance from a crossing to the end of its open interval: a band piece drifts
    /// along its border by at most 0.6 x its depth (the crossing velocity leans at most 0.6),
    /// so r + that + 0.1 keeps it a radius clear of the wall there.
    pub edge: f64,
    /// Least distance from a crossing to a patch corner, so that the band pieces of two
    /// perpendicular borders stay 2r + 0.1 apart: each ends at most 1.6r along its border from
    /// its crossing, so the corner needs 1.6r + (2r + 0.1) / sqrt 2 (rounded up to 3.1r + 0.1).
    pub corner: f64,
}

impl CrossingRule {
    pub fn new(radius: f64) -> CrossingRule {
        CrossingRule {
            gap: 2.0 * radius + 0.1,
            meet_depth: 1.5,
            band: radius,
            edge: 1.6 * radius + 0.1,
            corner: 3.1 * radius + 0.1,
        }
    }

    /// Whether two crossings of a border across `normal` (a unit world axis) keep their
    /// characters apart near it.
    pub fn compatible(&self, a: &Crossing, b: &Crossing, normal: DVec2, period: f64) -> bool {
        if !self.bands_apart(a, b, normal, period) {
            return false;
        }
        if (a.s - b.s).abs() >= self.gap {
            return true;
        }
        let dt = (a.t - b.t).abs().rem_euclid(period);
        let dt = dt.min(period - dt);
        let speed = a.velocity.length().min(b.velocity.length());
        if a.way == b.way {
            speed * dt >= self.gap
        } else {
            speed * dt / 2.0 >= self.meet_depth
        }
    }

    /// Whether the band pieces of two crossings of one border stay `gap` apart at all times
    /// (modulo the period). A piece is the character's straight walk at its crossing velocity
    /// from `band` deep on one side to `band` deep on the other, continued straight for
    /// [`HOLD_S`] beyond each end; the closest approach of two such walks is analytic.
    ///
    /// The continuation matters: stage 5 cannot bend a path within a quarter second of its
    /// band's end, so two band ends reached a few milliseconds apart (one walker leaving its
    /// band as another reaches its own) must already be apart. City patch 1251 stalled so,
    /// with two bands leaning towards each other whose ends were 0.47 m apart 5 ms apart.
    pub fn bands_apart(&self, a: &Crossing, b: &Crossing, normal: DVec2, period: f64) -> bool {
        let depth_time = |c: &Crossing| self.band / c.velocity.dot(normal).abs().max(1e-6) + HOLD_S;
        let (ta, tb) = (depth_time(a), depth_time(b));
        // s runs along the world axis the border lies on.
        let along = |c: &Crossing| DVec2::new(normal.y, normal.x) * c.s;
        for k in [-1.0, 0.0, 1.0] {
            let tb_c = b.t + k * period;
            let (lo, hi) = ((a.t - ta).max(tb_c - tb), (a.t + ta).min(tb_c + tb));
            if lo > hi {
                continue;
            }
            // a(t) - b(t) = w + dv (t - lo)
            let pa = along(a) + a.velocity * (lo - a.t);
            let pb = along(b) + b.velocity * (lo - tb_c);
            let (w, dv) = (pa - pb, a.velocity - b.velocity);
            if approach(w, dv, hi - lo).0 < self.gap {
                return false;
            }
        }
        true
    }
}
