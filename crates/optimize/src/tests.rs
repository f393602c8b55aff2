//! Properties of the optimiser on small synthetic scenes, for any seed.

use super::*;
use crowd_core::patterns::parity;
use crowd_core::{Grid, Hash, MergedMaps};
use glam::Vec2;
use proptest::prelude::*;

/// A 48 m x 32 m scene of 8 m patches: a dense blob, a wall with a door, an eastward flow on
/// the top row.
fn scene(walkers: u64) -> PatchGraph {
    let (w, h) = (48, 32);
    let mut maps = MergedMaps::empty(w, h, 1.0);
    maps.walkers = Grid::filled(w, h, 0.2);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if (8..20).contains(&x) && (12..24).contains(&y) {
                maps.walkers.as_mut_slice()[i] = 1.0;
            }
            if x == 24 && !(14..18).contains(&y) {
                maps.blocked.as_mut_slice()[i] = true;
                maps.walkers.as_mut_slice()[i] = 0.0;
            }
            if y < 8 {
                maps.flow.as_mut_slice()[i] = Vec2::X;
                maps.flow_weight.as_mut_slice()[i] = 1.0;
            }
        }
    }
    let inputs = crowd_graph::GraphInputs::counted(walkers, 8.0);
    crowd_graph::build_graph(&maps, &inputs, Hash::of(b"t"), &()).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(6))]

    /// Whatever the seed: parity in every patch, spacing on every border, nothing above rho_max,
    /// and a better E than at the start.
    #[test]
    fn any_seed_keeps_the_patch_constraints(seed in any::<u64>(), walkers in 100u64..500) {
        let graph = scene(walkers);
        let settings = OptimizeSettings { max_iterations: 60, ..OptimizeSettings::default() };
        let matching = MatchSettings::default();
        let out = optimize(&graph, &settings, &matching, 20.0, seed, &());
        prop_assert!(parity(&graph, &out.crossings).iter().all(|&b| b == 0));
        let spacing = spacing::Spacing::new(&graph);
        let mut per_border = vec![Vec::new(); graph.borders.len()];
        for c in &out.crossings {
            per_border[c.border as usize].push(*c);
        }
        prop_assert!(spacing::all_spaced(&spacing, &per_border, 20.0));
        prop_assert!(out.measured.iter().all(|m| m.density <= settings.rho_max + 1e-9));
        prop_assert!(out.error.e <= out.log[0].e + 1e-12);
    }
}

#[test]
fn the_same_seed_gives_the_same_crossings() {
    let graph = scene(300);
    let settings = OptimizeSettings {
        max_iterations: 30,
        ..OptimizeSettings::default()
    };
    let run = || optimize(&graph, &settings, &MatchSettings::default(), 20.0, 7, &()).crossings;
    assert_eq!(run(), run());
}

/// The optimiser's start on `graph` (regression and balanced crossings), for seed `seed`.
fn started<'a>(graph: &'a PatchGraph, matching: &'a MatchSettings, seed: u64) -> State<'a> {
    let regression = regression::fit(8.0, 20.0, matching, 60, seed);
    let mut state = State::new(graph, matching, 20.0, stander_counts(graph));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    start(&mut state, &regression, 0.35, &mut rng);
    state
}

/// The polish keeps its own running totals of the error: after it, they must agree with a
/// scene measured from scratch, and no round may raise E.
#[test]
fn the_polish_never_raises_e_and_its_figures_match_a_fresh_measurement() {
    let graph = scene(300);
    let matching = MatchSettings::default();
    let mut state = started(&graph, &matching, 3);
    let e = |state: &State| scene_error(&graph, &state.requested, &state.measured, 0.35).e;
    let mut rounds = vec![e(&state)];
    let done = polish::polish(&mut state, 0.35, 10, 0.0, 3, |s| rounds.push(e(s)));
    assert!(done.kept > 0, "{done:?}");
    assert!(
        rounds.windows(2).all(|w| w[1] <= w[0] + 1e-12),
        "{rounds:?}"
    );
    let polished = state.measured.clone();
    state.remeasure_all();
    assert_eq!(polished, state.measured);
    assert!(parity_holds(&state));
    assert!(state.measured.iter().all(|m| m.density <= 0.35 + 1e-9));
}

fn parity_holds(state: &State) -> bool {
    let all: Vec<Crossing> = state.crossings.iter().flatten().copied().collect();
    parity(state.graph, &all).iter().all(|&b| b == 0)
}

/// Turning crossing velocities towards their lines keeps who crosses where and when, and the
/// spacing of every border. (What a patch measures may change: a pair's least time depends on
/// its band pieces, so the optimiser measures again after.)
#[test]
fn aligning_velocities_keeps_the_crossings_and_spacing() {
    let graph = scene(300);
    let matching = MatchSettings::default();
    let mut state = started(&graph, &matching, 5);
    let key = |s: &State| -> Vec<(u32, u64, u64)> {
        s.crossings
            .iter()
            .flatten()
            .map(|c| (c.border, c.s.to_bits(), c.t.to_bits()))
            .collect()
    };
    let before = key(&state);
    let turned = align::align(&mut state);
    assert!(turned > 0);
    assert_eq!(before, key(&state));
    assert!(spacing::all_spaced(&state.spacing, &state.crossings, 20.0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// Adding a step's cycles in waves of cycles that share no patch leaves exactly what adding
    /// them one at a time leaves (the loop it replaced, kept here as the reference): the same
    /// crossings, the same measurements, the same random draws after, cycles taken back where
    /// a patch would pass rho_max included.
    #[test]
    fn cycles_added_in_waves_leave_what_one_at_a_time_leaves(
        seed in any::<u64>(),
        picks in proptest::collection::vec((0usize..1000, 0usize..8), 10..60),
        rho_max in 0.15f64..0.5,
    ) {
        let graph = scene(300);
        let matching = MatchSettings::default();
        let state = started(&graph, &matching, seed);
        // Back-and-forths over links of random patches: many share a patch.
        let patches = state.links.len();
        let cycles: Vec<Vec<Step>> = picks
            .iter()
            .filter_map(|&(p, l)| {
                let from = p % patches;
                let link = state.links[from].get(l % state.links[from].len().max(1))?;
                let back = state.links[link.to].iter().find(|b| b.border == link.border)?;
                Some(vec![
                    Step { from, to: link.to, border: link.border, way: link.way },
                    Step { from: link.to, to: from, border: back.border, way: back.way },
                ])
            })
            .collect();
        let (mut one, mut waves) = (state.fork(), state.fork());
        let mut rng_one = ChaCha8Rng::seed_from_u64(seed ^ 1);
        let mut rng_waves = rng_one.clone();
        for cycle in cycles.clone() {
            let before: Vec<usize> =
                cycle.iter().map(|s| one.crossings[s.border].len()).collect();
            if mutate::add_cycle(&mut one, &cycle, &mut rng_one) {
                let touched: Vec<usize> = cycle.iter().map(|s| s.to).collect();
                one.remeasure(&touched);
                if touched.iter().any(|&p| one.measured[p].density > rho_max) {
                    for (s, n) in cycle.iter().zip(before) {
                        one.crossings[s.border].truncate(n);
                    }
                    one.remeasure(&touched);
                }
            }
        }
        add_in_waves(&mut waves, cycles.into_iter(), rho_max, &mut rng_waves);
        prop_assert_eq!(&one.crossings, &waves.crossings);
        prop_assert_eq!(&one.measured, &waves.measured);
        prop_assert_eq!(rand::Rng::random::<u64>(&mut rng_one), rand::Rng::random::<u64>(&mut rng_waves));
    }
}

/// Regions (3 x 3 patches here) are optimised apart: a change inside one region moves no
/// crossing outside it, and a rebuild that takes the untouched regions from the first build
/// gives exactly the crossings of a build from scratch.
#[test]
fn a_change_inside_a_region_moves_no_crossing_outside_it_and_reuse_is_exact() {
    let graph = scene(300);
    let settings = OptimizeSettings {
        max_iterations: 40,
        region_patches: Some(3),
        ..OptimizeSettings::default()
    };
    let matching = MatchSettings::default();
    let before = optimize(&graph, &settings, &matching, 20.0, 5, &());
    assert_eq!(before.regions, 4);
    let mut changed = graph.clone();
    let inner = changed
        .patch_at(crowd_core::Cell { col: 1, row: 1 })
        .expect("the inner patch of the first region");
    changed.patches[inner].walker_density *= 2.0;
    let known: Known = before.solved.iter().map(|s| (s.hash, s.clone())).collect();
    let after = optimize_reusing(&changed, &settings, &matching, 20.0, 5, known, &());
    let scratch = optimize(&changed, &settings, &matching, 20.0, 5, &());
    assert_eq!(
        after.reused, 3,
        "only the changed region is optimised again"
    );
    assert_eq!(after.crossings, scratch.crossings);
    assert_eq!(after.measured, scratch.measured);
    assert_eq!(after.log, scratch.log);
    let first_region = |k: u32| {
        let b = &graph.borders[k as usize];
        [b.a, b.b].iter().all(|p| {
            region::block_of(graph.patch(*p).cell, 3) == crowd_core::Cell { col: 0, row: 0 }
        })
    };
    let outside = |o: &Outcome| -> Vec<Crossing> {
        o.crossings
            .iter()
            .filter(|c| !first_region(c.border))
            .copied()
            .collect()
    };
    assert_eq!(outside(&before), outside(&after));
    assert_ne!(
        before.crossings, after.crossings,
        "the changed region did change"
    );
    assert!(parity(&changed, &after.crossings).iter().all(|&b| b == 0));
}

/// Stage 3 split over shards: each solves its run of regions, its part goes through its
/// files, and the world put together from the parts solves nothing and is the world solved
/// in one process, for any count of shards (more shards than regions too).
#[test]
fn regions_solved_in_shards_and_read_from_their_files_are_the_world_solved_whole() {
    let graph = scene(300);
    let settings = OptimizeSettings {
        max_iterations: 30,
        region_patches: Some(2),
        ..OptimizeSettings::default()
    };
    let matching = MatchSettings::default();
    let whole = optimize(&graph, &settings, &matching, 20.0, 9, &());
    let costs = shard::region_costs(&graph, &settings);
    assert_eq!(costs.len(), whole.regions);
    let hash = Hash::of(b"inputs");
    for count in [1, 3, 5, whole.regions as u32 + 2] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("shards")).unwrap();
        let mut solved_here = 0;
        for i in 0..count {
            let s = crowd_core::Shard::new(i, count).unwrap();
            let run = s.run(&costs);
            let part = solve_part(
                &graph,
                &settings,
                &matching,
                (20.0, 9),
                run.clone(),
                Known::new(),
                &(),
            );
            assert_eq!(part.len(), run.len());
            solved_here += part.iter().filter(|(_, reused)| !reused).count();
            let solved: Vec<_> = part.into_iter().map(|(s, _)| s).collect();
            let writes = shard::encode_part(dir.path(), s, hash, run, &solved);
            crowd_core::files::write_all(&writes).unwrap();
        }
        assert_eq!(
            solved_here, whole.regions,
            "{count} shards: each region solved once"
        );
        let (known, parts) = shard::read_parts(dir.path(), hash).unwrap();
        assert_eq!(parts, count as usize);
        let gathered = optimize_reusing(&graph, &settings, &matching, 20.0, 9, known, &());
        assert_eq!(
            gathered.reused, whole.regions,
            "{count} shards: nothing solved again"
        );
        assert_eq!(gathered.crossings, whole.crossings);
        assert_eq!(gathered.measured, whole.measured);
        assert_eq!(gathered.log, whole.log);
        assert_eq!(
            known::encode(&gathered.solved),
            known::encode(&whole.solved)
        );
        // A part of other inputs is refused, by name.
        let other = shard::read_parts(dir.path(), Hash::of(b"other")).unwrap_err();
        assert!(other.to_string().contains("optimize-0-of-"), "{other}");
    }
}

/// A 200 m x 96 m scene of 8 m patches cut in two by a wall without a door: two components.
fn two_rooms() -> PatchGraph {
    let (w, h) = (200, 96);
    let mut maps = MergedMaps::empty(w, h, 1.0);
    maps.walkers = Grid::filled(w, h, 0.3);
    for y in 0..h {
        let i = (y * w + 100) as usize;
        maps.blocked.as_mut_slice()[i] = true;
        maps.walkers.as_mut_slice()[i] = 0.0;
    }
    let inputs = crowd_graph::GraphInputs::counted(2000, 8.0);
    crowd_graph::build_graph(&maps, &inputs, Hash::of(b"t"), &()).unwrap()
}

/// The groups as first written: every later optimum of the component measured, every group
/// made, then each component's first `budget` kept.
fn groups_by_every_pair(
    state: &State,
    optima: &[usize],
    (radius, size): (u32, usize),
    budget: impl Fn(u32) -> usize,
) -> Vec<Vec<usize>> {
    let component = |u: usize| state.graph.patches[u].component;
    let mut taken = vec![false; optima.len()];
    let mut out = Vec::new();
    for i in 0..optima.len() {
        if taken[i] {
            continue;
        }
        taken[i] = true;
        let mut group = vec![optima[i]];
        let mut near: Vec<(u32, usize)> = (i + 1..optima.len())
            .filter(|&j| !taken[j] && component(optima[j]) == component(optima[i]))
            .map(|j| (search::cells_apart(state, optima[i], optima[j]), j))
            .filter(|&(d, _)| d <= radius)
            .collect();
        near.sort();
        for &(_, j) in near.iter().take(size - 1) {
            taken[j] = true;
            group.push(optima[j]);
        }
        out.push(group);
    }
    let mut used = std::collections::HashMap::new();
    out.retain(|g| {
        let used = used.entry(component(g[0])).or_insert(0);
        *used += 1;
        *used <= budget(component(g[0]))
    });
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Optima looked up by squares of cells, with each component's budget, make the groups
    /// that measuring every later optimum and dropping the groups past the budget makes.
    #[test]
    fn groups_by_squares_are_the_groups_of_every_pair(
        picks in proptest::collection::vec(0usize..10_000, 0..200),
        radius in 0u32..7,
        size in 1usize..5,
        budgets in (0usize..40, 0usize..40),
    ) {
        let graph = two_rooms();
        prop_assume!(graph.components.len() == 2);
        let matching = MatchSettings::default();
        let state = State::new(&graph, &matching, 20.0, stander_counts(&graph));
        let mut optima: Vec<usize> = picks.iter().map(|p| p % graph.patches.len()).collect();
        let mut seen = std::collections::HashSet::new();
        optima.retain(|u| seen.insert(*u));
        let budget = |c: u32| if c == 0 { budgets.0 } else { budgets.1 };
        prop_assert_eq!(
            search::groups(&state, &optima, (radius, size), budget),
            groups_by_every_pair(&state, &optima, (radius, size), budget)
        );
    }
}

/// A shard holds only the crossings of its patches' borders and of two rings of patches round
/// them (`HeldCrossings::window`), numbered as the world numbers them: its patches and their
/// ring are matched, and seen by keys, exactly as with the world's whole list, and a crossing
/// it does not hold is never read as another.
#[test]
fn a_shards_window_of_the_crossings_matches_its_patches_as_the_whole_list_does() {
    use crowd_core::patterns::HeldCrossings;
    use crowd_core::shard::{border_window, with_neighbours};
    // 96 m x 80 m: 12 x 10 patches of 8 m, people everywhere.
    let (w, h) = (96, 80);
    let mut maps = MergedMaps::empty(w, h, 1.0);
    maps.walkers = Grid::filled(w, h, 0.3);
    let inputs = crowd_graph::GraphInputs::counted(400, 8.0);
    let graph = crowd_graph::build_graph(&maps, &inputs, Hash::of(b"w"), &()).unwrap();
    let settings = OptimizeSettings {
        max_iterations: 20,
        ..OptimizeSettings::default()
    };
    let matching = MatchSettings::default();
    let world = optimize(&graph, &settings, &matching, 20.0, 3, &()).crossings;
    // A shard's run of patches: rows 4 and 5.
    let own: Vec<usize> = (0..graph.patches.len())
        .filter(|&p| (4..6).contains(&graph.patches[p].cell.row))
        .collect();
    let ring = with_neighbours(&graph, &own);
    let reach = with_neighbours(&graph, &ring);
    let held = HeldCrossings::whole(world.clone()).window(border_window(&graph, &reach));
    let numbers = held.view().numbers();
    assert!(
        numbers.start > 0 && (numbers.end as usize) < world.len(),
        "the window is a part of the world's list ({numbers:?} of {})",
        world.len()
    );
    for (k, c) in held.view().indexed() {
        assert_eq!(*c, world[k as usize], "crossing {k} keeps its world number");
    }
    let match_inputs = crowd_match::Inputs {
        period_s: 20.0,
        seed: 3,
        settings: matching.clone(),
    };
    let standers = crowd_core::patterns::Measured {
        density: 0.0,
        direction: None,
        standers: 1,
    };
    let measured = vec![standers; graph.patches.len()];
    let by_window = crowd_match::match_patches(&graph, &held, &measured, &match_inputs, &(), &ring);
    let by_world = crowd_match::match_patches(&graph, &world, &measured, &match_inputs, &(), &ring);
    assert_eq!(by_window, by_world, "the ring's motion");
    let (seen_window, seen_world) = (
        crowd_core::patch_keys::Seen::new(&graph, &held),
        crowd_core::patch_keys::Seen::new(&graph, &world),
    );
    for &p in &ring {
        assert_eq!(
            seen_window.tables[p], seen_world.tables[p],
            "patch {p}'s table"
        );
        assert_eq!(
            seen_window.surroundings(p),
            seen_world.surroundings(p),
            "patch {p}'s surroundings"
        );
    }
    // A crossing beyond the window is not taken for another.
    assert!(held.view().get(numbers.end).is_none());
    assert!(held.view().get(numbers.start - 1).is_none());
    let beyond = std::panic::catch_unwind(|| held.view()[numbers.end as usize].t);
    assert!(beyond.is_err(), "indexing beyond the window panics");
}
