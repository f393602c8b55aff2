//! The cached measurement is the plain one: whatever the order and repeats of the endpoint sets
//! a patch is measured with, [`measure_patch_cached`] gives [`measure_patch`]'s figures.

use super::*;
use proptest::prelude::*;

fn context(settings: &MatchSettings) -> PatchContext<'_> {
    PatchContext {
        side_m: 8.0,
        period_s: 20.0,
        comfort_speed: 1.3,
        direction: None,
        obstacles: &[],
        radius_m: 0.3,
        settings,
    }
}

/// A point on `side` of an 8 m patch, `along` of the way, at `t`.
fn point(side: Side, along: f64, t: f64, crossing: u32, entry: bool) -> Endpoint {
    let (pos, inward) = match side {
        Side::West => (DVec2::new(0.0, 8.0 * along), DVec2::X),
        Side::East => (DVec2::new(8.0, 8.0 * along), -DVec2::X),
        Side::South => (DVec2::new(8.0 * along, 0.0), DVec2::Y),
        Side::North => (DVec2::new(8.0 * along, 8.0), -DVec2::Y),
    };
    let velocity = if entry { inward } else { -inward } * 1.3;
    Endpoint {
        crossing,
        pos,
        t,
        side,
        velocity,
    }
}

fn any_point(entry: bool) -> impl Strategy<Value = Endpoint> {
    (0usize..4, 0.05f64..0.95, 0.0f64..20.0, 0u32..1000).prop_map(move |(s, a, t, c)| {
        let side = [Side::West, Side::East, Side::South, Side::North][s];
        point(side, a, t, c, entry)
    })
}

proptest! {
    /// A patch measured again and again as pairs of endpoints come and go (and sets come back,
    /// as stage 3's tries bring them back) keeps the uncached figures, bit for bit.
    #[test]
    fn cached_figures_are_the_plain_ones(
        entries in proptest::collection::vec(any_point(true), 12),
        exits in proptest::collection::vec(any_point(false), 12),
        steps in proptest::collection::vec((2usize..12, any::<bool>(), 0u32..3), 1..20),
    ) {
        let settings = MatchSettings::default();
        let ctx = context(&settings);
        let mut cache = ScoreCache::default();
        for (n, from_the_end, standers) in steps {
            let (e, x) = if from_the_end {
                (&entries[12 - n..], &exits[12 - n..])
            } else {
                (&entries[..n], &exits[..n])
            };
            let cached = measure_patch_cached(e, x, standers, &ctx, &mut cache);
            prop_assert_eq!(cached, measure_patch(e, x, standers, &ctx));
        }
    }
}
