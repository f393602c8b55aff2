//! `export.gltf_region`: the part of the world `world.glb` shows. A character is shown while
//! it is inside the region: its node has the slot's keys over the whole clip and a scale
//! channel (STEP) that hides it (scale 0) from where it walks out to where it walks back in.
//! A slot that is never inside during the clip has no node. So the clip loops exactly: every
//! character shown at the clip's end is there at its start, in the node its slot hands over to.

use glam::DVec2;

/// An axis-aligned region of the world, `(x0, y0, x1, y1)` in world metres.
pub(super) type Region = (f64, f64, f64, f64);

/// Whether anything inside the box `lo`-`hi` may be shown in `region`: false only where the
/// box lies a millimetre or more outside it (a loop's keys are points of its pieces, rounded
/// within far less).
pub(super) fn may_show((lo, hi): (DVec2, DVec2), region: Region) -> bool {
    const SLACK_M: f64 = 1e-3;
    let (x0, y0, x1, y1) = region;
    hi.x >= x0 - SLACK_M && lo.x <= x1 + SLACK_M && hi.y >= y0 - SLACK_M && lo.y <= y1 + SLACK_M
}

/// The spans of clip time during which the walk through `keys` (times, positions, piecewise
/// linear) is inside `region`, in order, touching spans merged.
pub(super) fn shown(times: &[f64], points: &[DVec2], region: Region) -> Vec<(f64, f64)> {
    let (x0, y0, x1, y1) = region;
    let mut spans: Vec<(f64, f64)> = Vec::new();
    let mut add = |a: f64, b: f64| match spans.last_mut() {
        Some(last) if a <= last.1 + 1e-9 => last.1 = last.1.max(b),
        _ => spans.push((a, b)),
    };
    for k in 0..times.len().saturating_sub(1) {
        let (ta, tb) = (times[k], times[k + 1]);
        let (pa, pb) = (points[k], points[k + 1]);
        // Liang-Barsky: the share s of the piece inside every slab.
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let d = pb - pa;
        for (p, q) in [
            (-d.x, pa.x - x0),
            (d.x, x1 - pa.x),
            (-d.y, pa.y - y0),
            (d.y, y1 - pa.y),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    hi = -1.0;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    lo = lo.max(r);
                } else {
                    hi = hi.min(r);
                }
            }
        }
        if lo <= hi {
            add(ta + lo * (tb - ta), ta + hi * (tb - ta));
        }
    }
    spans
}

/// A STEP scale channel's keys that show the character during `spans` of a clip of `period`
/// (times, scale 1 or 0); None when it is shown all along.
pub(super) fn scale_keys(spans: &[(f64, f64)], period: f64) -> Option<(Vec<f64>, Vec<f32>)> {
    const EDGE_S: f64 = 1e-6;
    if let [(a, b)] = spans
        && *a <= EDGE_S
        && *b >= period - EDGE_S
    {
        return None;
    }
    let shown_at_0 = spans.first().is_some_and(|s| s.0 <= EDGE_S);
    let (mut times, mut scales) = (vec![0.0], vec![if shown_at_0 { 1.0 } else { 0.0 }]);
    let mut key = |t: f64, s: f32| {
        // Strictly increasing as f32; a change within a float step of the last replaces it.
        if (t as f32) > *times.last().expect("the key at 0") as f32 {
            times.push(t);
            scales.push(s);
        } else {
            *scales.last_mut().expect("the key at 0") = s;
        }
    };
    for &(a, b) in spans {
        if a > EDGE_S {
            key(a, 1.0);
        }
        if b < period - EDGE_S {
            key(b, 0.0);
        }
    }
    Some((times, scales))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_walk_through_the_region_is_shown_while_inside() {
        // Along x at 1 m/s from -5 to 15 over a 20 s clip, through x in [0, 10].
        let times = [0.0, 20.0];
        let points = [DVec2::new(-5.0, 1.0), DVec2::new(15.0, 1.0)];
        let spans = shown(&times, &points, (0.0, 0.0, 10.0, 10.0));
        assert_eq!(spans.len(), 1);
        assert!((spans[0].0 - 5.0).abs() < 1e-12 && (spans[0].1 - 15.0).abs() < 1e-12);
        let (t, s) = scale_keys(&spans, 20.0).unwrap();
        assert_eq!(s, vec![0.0, 1.0, 0.0]);
        assert!((t[1] - 5.0).abs() < 1e-12 && (t[2] - 15.0).abs() < 1e-12);
        // Never inside: nothing shown.
        assert!(shown(&times, &points, (0.0, 5.0, 10.0, 10.0)).is_empty());
        // Inside all along: no scale channel.
        let spans = shown(&times, &points, (-10.0, 0.0, 20.0, 10.0));
        assert_eq!(scale_keys(&spans, 20.0), None);
    }

    #[test]
    fn a_standing_character_is_shown_where_it_stands() {
        let times = [0.0, 5.0, 20.0];
        let p = DVec2::new(3.0, 3.0);
        let points = [p, p, p];
        assert_eq!(
            shown(&times, &points, (0.0, 0.0, 10.0, 10.0)),
            vec![(0.0, 20.0)]
        );
        assert!(shown(&times, &points, (4.0, 0.0, 10.0, 10.0)).is_empty());
    }
}
