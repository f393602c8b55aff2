//! Random patches in the shape of Ramirez et al.'s Figure 6: entry and exit points at random
//! places and times on the four borders of an empty patch, matched by stage 4. For stage 5's
//! benchmark of that figure and its property test that every such patch converges; here
//! because the lines that figure measures are this stage's.
//!
//! The points are drawn under the rule stage 3 keeps on every border
//! (`crowd_geometry::spacing::CrossingRule`: clear of the corners, band pieces apart): two
//! characters asked to cross one spot at one moment could not be separated by anyone, and our
//! own patterns never ask for it.

use crate::{Endpoint, PatchContext};
use crowd_core::config::MatchSettings;
use crowd_core::patterns::{Crossing, Side, Way};
use crowd_core::trajectories::Trajectory;
use crowd_geometry::spacing::CrossingRule;
use glam::DVec2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The shape of a random patch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shape {
    pub side_m: f64,
    pub period_s: f64,
    pub radius_m: f64,
}

/// `pairs` walkers through a random empty patch of `shape`, as stage 4 draws them.
pub fn walkers(pairs: usize, shape: Shape, rng: &mut ChaCha8Rng) -> Vec<Trajectory> {
    let Shape {
        side_m: side,
        period_s: period,
        radius_m: radius,
    } = shape;
    let settings = MatchSettings::default();
    let ctx = PatchContext {
        side_m: side,
        period_s: period,
        comfort_speed: settings.comfort_speed,
        direction: None,
        obstacles: &[],
        radius_m: radius,
        settings: &settings,
    };
    let sides = [Side::West, Side::East, Side::South, Side::North];
    let rule = CrossingRule::new(radius);
    // Crossings drawn so far, per side, as stage 3 would see them on that border.
    let mut placed: [Vec<Crossing>; 4] = Default::default();
    let mut point = |rng: &mut ChaCha8Rng, entering: bool| loop {
        let k = rng.random_range(0..4);
        let side_of = sides[k];
        let s = rng.random_range(rule.corner..side - rule.corner);
        let t = rng.random_range(0.0..period);
        let inward = side_of.inward();
        let velocity = if entering { inward } else { -inward } * settings.comfort_speed;
        let c = Crossing {
            border: k as u32,
            way: if entering { Way::AToB } else { Way::BToA },
            s,
            t,
            velocity,
        };
        if placed[k]
            .iter()
            .all(|o| rule.compatible(&c, o, inward.abs(), period))
        {
            placed[k].push(c);
            let pos = match side_of {
                Side::West => DVec2::new(0.0, s),
                Side::East => DVec2::new(side, s),
                Side::South => DVec2::new(s, 0.0),
                Side::North => DVec2::new(s, side),
            };
            break Endpoint {
                crossing: 0,
                pos,
                t,
                side: side_of,
                velocity,
            };
        }
    };
    let entries: Vec<_> = (0..pairs).map(|_| point(rng, true)).collect();
    let exits: Vec<_> = (0..pairs).map(|_| point(rng, false)).collect();
    crate::trajectories(&entries, &exits, &ctx)
}
