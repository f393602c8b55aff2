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

/// A point on a coarse grid of places and times, so that many pairs score the same.
fn grid_point(entry: bool) -> impl Strategy<Value = Endpoint> {
    (0usize..4, 1u32..4, 0u32..5).prop_map(move |(s, a, t)| {
        let side = [Side::West, Side::East, Side::South, Side::North][s];
        point(side, a as f64 / 4.0, t as f64 * 4.0, 0, entry)
    })
}

/// The sets a patch goes through: the points of a pool that each step keeps (in the pool's
/// order, or reversed now and then), as many entries as exits.
fn subsets(pool: usize) -> impl Strategy<Value = Vec<(Vec<bool>, Vec<bool>, bool)>> {
    let mask = proptest::collection::vec(any::<bool>(), pool);
    proptest::collection::vec((mask.clone(), mask, proptest::bool::weighted(0.1)), 1..30)
}

fn pick(pool: &[Endpoint], mask: &[bool], n: usize, reversed: bool) -> Vec<Endpoint> {
    let mut set: Vec<Endpoint> = pool
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .map(|(p, _)| *p)
        .chain(pool.iter().copied())
        .take(n)
        .collect();
    if reversed {
        set.reverse();
    }
    set
}

proptest! {
    /// Sets with points coming, going and coming back, ties among scores and now and then an
    /// order turned around: the cached matching is Gale-Shapley's, the figures the plain ones.
    #[test]
    fn cached_matching_is_gale_shapleys(
        entries in proptest::collection::vec(grid_point(true), 14),
        exits in proptest::collection::vec(grid_point(false), 14),
        steps in subsets(14),
    ) {
        let settings = MatchSettings::default();
        let ctx = context(&settings);
        let mut cache = ScoreCache::default();
        for (entry_mask, exit_mask, reversed) in steps {
            let n = entry_mask.iter().filter(|m| **m).count().max(1);
            let e = pick(&entries, &entry_mask, n, reversed);
            let x = pick(&exits, &exit_mask, n, false);
            prop_assert_eq!(
                match_points_cached(&e, &x, &ctx, &mut cache),
                match_points(&e, &x, &ctx)
            );
            let cached = measure_patch_cached(&e, &x, 1, &ctx, &mut cache);
            prop_assert_eq!(cached, measure_patch(&e, &x, 1, &ctx));
        }
    }
}
