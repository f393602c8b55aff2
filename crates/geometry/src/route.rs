//! Shortest paths round the static obstacles of a patch: a straight line when it is clear,
//! otherwise the shortest way through the corners of the obstacles grown by a character's
//! radius (a visibility graph; Lozano-Perez and Wesley 1979).

use crowd_core::Rect;
use glam::DVec2;

/// Whether the segment a-b passes through the inside of `r` (Liang-Barsky clipping).
fn crosses(a: DVec2, b: DVec2, r: &Rect) -> bool {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d.x, a.x - r.min.x),
        (d.x, r.max.x - a.x),
        (-d.y, a.y - r.min.y),
        (d.y, r.max.y - a.y),
    ] {
        if p.abs() < 1e-12 {
            if q <= 0.0 {
                return false;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
            if t0 >= t1 {
                return false;
            }
        }
    }
    true
}

fn grown(r: &Rect, by: f64) -> Rect {
    Rect {
        min: r.min - DVec2::splat(by),
        max: r.max + DVec2::splat(by),
    }
}

/// The shortest path from `from` to `to` keeping `clearance` from every obstacle, as its
/// corner points (both ends included); the straight line when no obstacle is in the way or no
/// way round exists.
pub fn route(from: DVec2, to: DVec2, obstacles: &[Rect], clearance: f64, side: f64) -> Vec<DVec2> {
    let walls: Vec<Rect> = obstacles
        .iter()
        .map(|o| grown(o, clearance * 0.999))
        .collect();
    let blocked = |a: DVec2, b: DVec2| walls.iter().any(|w| crosses(a, b, w));
    if !blocked(from, to) {
        return vec![from, to];
    }
    // Corners stay out of the border bands (a clearance deep), where only the walkers
    // crossing that border go.
    let (lo, hi) = (clearance, side - clearance);
    let inside = |p: DVec2| p.x >= lo && p.y >= lo && p.x <= hi && p.y <= hi;
    let mut nodes = vec![from, to];
    for o in obstacles {
        let g = grown(o, clearance + 0.05);
        for c in [
            g.min,
            DVec2::new(g.max.x, g.min.y),
            g.max,
            DVec2::new(g.min.x, g.max.y),
        ] {
            let buried = walls
                .iter()
                .any(|w| c.x > w.min.x && c.x < w.max.x && c.y > w.min.y && c.y < w.max.y);
            if inside(c) && !buried {
                nodes.push(c);
            }
        }
    }
    // Dijkstra over the visibility graph (a few dozen nodes at most).
    let n = nodes.len();
    let mut dist = vec![f64::INFINITY; n];
    let mut prev = vec![usize::MAX; n];
    let mut done = vec![false; n];
    dist[0] = 0.0;
    for _ in 0..n {
        let Some(u) = (0..n)
            .filter(|&i| !done[i] && dist[i].is_finite())
            .min_by(|&a, &b| dist[a].total_cmp(&dist[b]))
        else {
            break;
        };
        if u == 1 {
            break;
        }
        done[u] = true;
        for v in 0..n {
            if !done[v] && !blocked(nodes[u], nodes[v]) {
                let d = dist[u] + nodes[u].distance(nodes[v]);
                if d < dist[v] {
                    dist[v] = d;
                    prev[v] = u;
                }
            }
        }
    }
    if !dist[1].is_finite() {
        return vec![from, to];
    }
    let mut path = vec![to];
    let mut at = 1;
    while prev[at] != usize::MAX {
        at = prev[at];
        path.push(nodes[at]);
    }
    path.reverse();
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clear_line_stays_straight() {
        let p = route(DVec2::new(0.0, 1.0), DVec2::new(8.0, 1.0), &[], 0.3, 8.0);
        assert_eq!(p.len(), 2);
    }

    #[test]
    fn a_box_in_the_way_is_walked_round_with_clearance() {
        let wall = Rect {
            min: DVec2::new(3.0, 2.0),
            max: DVec2::new(5.0, 6.0),
        };
        let p = route(
            DVec2::new(0.0, 4.0),
            DVec2::new(8.0, 4.0),
            &[wall],
            0.3,
            8.0,
        );
        assert!(p.len() > 2, "{p:?}");
        for w in p.windows(2) {
            assert!(!crosses(w[0], w[1], &grown(&wall, 0.299)), "{p:?}");
        }
        let length: f64 = p.windows(2).map(|w| w[0].distance(w[1])).sum();
        assert!(length < 8.0 + 2.0 * 2.4, "{length}");
    }
}
