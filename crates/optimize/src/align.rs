//! Crossing velocities turned towards the walkers' lines, once the crossings are final.
//!
//! A walker walks its border band at its crossing's velocity and then turns onto its line
//! through the patch. Stage 3 plans the velocity before anyone is matched: across the border,
//! leaning only where a painted direction asks. Once the crossings are final, the matching is
//! known, so each crossing can lean towards the mean direction of the two lines that meet at
//! it (the one that leaves through it and the one that enters), by at most 0.6 as before, and
//! the turn after the band shrinks; smoothing then has less to round. A crossing keeps its
//! old velocity where the new one would break the spacing of its border. Who is matched to whom
//! does not depend on velocities, but a pair's least time does (its band pieces), so the
//! optimiser measures the patches again afterwards.

use crate::state::{State, unkey};
use crowd_core::patterns::Crossing;
use glam::DVec2;
use rayon::prelude::*;

/// Most a crossing velocity leans along its border, per unit across (as `crossing_velocity`).
const MAX_LEAN: f64 = 0.6;

/// Leans every crossing towards its lines where its border's spacing allows. Returns how many
/// crossings turned.
pub fn align(state: &mut State) -> usize {
    let st = &*state;
    let found: Vec<Vec<(u32, DVec2)>> = st
        .own_patches()
        .into_par_iter()
        .map(|p| {
            let (entries, exits) = st.endpoints(p);
            if entries.is_empty() || entries.len() != exits.len() {
                return Vec::new();
            }
            let ctx = st.context(p);
            let pairs = st.pairs(p, &entries, &exits);
            let mut out = Vec::with_capacity(2 * entries.len());
            for (e, &o) in entries.iter().zip(&pairs) {
                let x = &exits[o];
                let way = crowd_match::way::waypoints(e, x, &ctx);
                let n = way.len();
                out.push((e.crossing, (way[1].0 - way[0].0).normalize_or_zero()));
                out.push((
                    x.crossing,
                    (way[n - 1].0 - way[n - 2].0).normalize_or_zero(),
                ));
            }
            out
        })
        .collect();
    let mut want: Vec<Vec<DVec2>> = st
        .crossings
        .iter()
        .map(|l| vec![DVec2::ZERO; l.len()])
        .collect();
    for (key, d) in found.into_iter().flatten() {
        let (b, i) = unkey(key);
        want[b][i] += d;
    }
    // Borders are independent: each turns its crossings in order, on its own thread.
    let st = &*state;
    let turned_lists: Vec<Option<(Vec<Crossing>, usize)>> = want
        .par_iter()
        .enumerate()
        .map(|(b, wanted)| align_border(st, b, wanted))
        .collect();
    let mut turned = 0;
    for (b, list) in turned_lists.into_iter().enumerate() {
        if let Some((list, n)) = list {
            state.crossings[b] = list;
            turned += n;
        }
    }
    turned
}

/// Border `b`'s crossings, each leaned towards the lines wanted of it where the border's
/// spacing allows, one after another, and how many turned (`None`: none).
fn align_border(state: &State, b: usize, wanted: &[DVec2]) -> Option<(Vec<Crossing>, usize)> {
    if state.held[b] {
        return None;
    }
    let period = state.period_s;
    let mut list = state.crossings[b].clone();
    let mut turned = 0;
    for (i, &d) in wanted.iter().enumerate() {
        let c = list[i];
        if d.length_squared() < 1e-12 {
            continue;
        }
        let across = state.normal(b, c.way);
        let tangent = across.perp();
        let lean = if d.dot(across) > 1e-9 {
            (d.dot(tangent) / d.dot(across)).clamp(-MAX_LEAN, MAX_LEAN)
        } else {
            MAX_LEAN * d.dot(tangent).signum()
        };
        let velocity = (across + tangent * lean).normalize() * c.velocity.length();
        let new = Crossing { velocity, ..c };
        let fits = list
            .iter()
            .enumerate()
            .all(|(j, o)| j == i || state.spacing.compatible(&new, o, period));
        if fits {
            list[i] = new;
            turned += 1;
        }
    }
    (turned > 0).then_some((list, turned))
}
