//! Fields on a grid of nodes, read with bilinear interpolation and its exact gradient, and the
//! Eikonal distances (fast marching) the model's will and obstacle forces come from (Allain
//! section 5.1: "W(x) is computed on a grid using the Eikonal equation", and so are D_obs and
//! e_obs).

use glam::DVec2;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A regular grid of nodes: node (i, j) sits at `origin + (i, j) * spacing`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    pub origin: DVec2,
    pub spacing: f64,
    pub nx: usize,
    pub ny: usize,
}

impl Lattice {
    /// The lattice covering `[min, max]` with nodes `spacing` apart (at least 2 x 2 nodes).
    pub fn covering(min: DVec2, max: DVec2, spacing: f64) -> Lattice {
        let n = |extent: f64| ((extent / spacing).ceil() as usize + 1).max(2);
        Lattice {
            origin: min,
            spacing,
            nx: n(max.x - min.x),
            ny: n(max.y - min.y),
        }
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn node(&self, i: usize, j: usize) -> DVec2 {
        self.origin + DVec2::new(i as f64, j as f64) * self.spacing
    }

    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    /// The far corner.
    pub fn max(&self) -> DVec2 {
        self.node(self.nx - 1, self.ny - 1)
    }

    /// The cell holding `p` (clamped to the lattice) and the position inside it in [0, 1]^2;
    /// `inside` says per axis whether `p` was inside (outside, the field is held constant, so
    /// its derivative along that axis is zero).
    fn locate(&self, p: DVec2) -> (usize, usize, DVec2, [bool; 2]) {
        let f = (p - self.origin) / self.spacing;
        let axis = |v: f64, n: usize| {
            let top = (n - 2) as f64;
            let cell = v.floor().clamp(0.0, top);
            let t = v - cell;
            let inside = (0.0..=1.0).contains(&t);
            (cell as usize, t.clamp(0.0, 1.0), inside)
        };
        let (i, tx, ix) = axis(f.x, self.nx);
        let (j, ty, iy) = axis(f.y, self.ny);
        (i, j, DVec2::new(tx, ty), [ix, iy])
    }
}

/// A scalar field given at the nodes of a lattice.
#[derive(Clone, Debug)]
pub struct NodeField {
    pub lattice: Lattice,
    pub values: Vec<f64>,
}

impl NodeField {
    pub fn constant(lattice: Lattice, value: f64) -> NodeField {
        NodeField {
            lattice,
            values: vec![value; lattice.len()],
        }
    }

    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.values[self.lattice.index(i, j)]
    }

    /// The bilinear interpolation at `p` and its gradient (exact for this interpolant, so the
    /// model's Jacobian is the derivative of the forces it integrates).
    pub fn sample(&self, p: DVec2) -> (f64, DVec2) {
        self.at_stencil(&self.lattice.stencil(p))
    }

    fn at_stencil(&self, s: &Stencil) -> (f64, DVec2) {
        let v = |k: usize| self.values[k];
        let (v00, v10, v01, v11) = (
            v(s.corner),
            v(s.corner + 1),
            v(s.corner + s.row),
            v(s.corner + s.row + 1),
        );
        let t = s.t;
        let bottom = v00 + (v10 - v00) * t.x;
        let top = v01 + (v11 - v01) * t.x;
        let value = bottom + (top - bottom) * t.y;
        let grad = DVec2::new(
            ((v10 - v00) * (1.0 - t.y) + (v11 - v01) * t.y) * s.scale.x,
            (top - bottom) * s.scale.y,
        );
        (value, grad)
    }
}

/// Where a point falls in a lattice: its cell's first node, the row stride, the position in
/// the cell, and per axis 1 / spacing (0 outside the lattice, where fields are held constant).
struct Stencil {
    corner: usize,
    row: usize,
    t: DVec2,
    scale: DVec2,
}

impl Lattice {
    fn stencil(&self, p: DVec2) -> Stencil {
        let (i, j, t, inside) = self.locate(p);
        let per = |inside: bool| if inside { 1.0 / self.spacing } else { 0.0 };
        Stencil {
            corner: self.index(i, j),
            row: self.nx,
            t,
            scale: DVec2::new(per(inside[0]), per(inside[1])),
        }
    }
}

/// A vector field as two node fields; `sample` gives the value and its Jacobian (rows: the
/// components, columns: d/dx, d/dy).
#[derive(Clone, Debug)]
pub struct VectorField {
    pub x: NodeField,
    pub y: NodeField,
}

impl VectorField {
    pub fn sample(&self, p: DVec2) -> (DVec2, [DVec2; 2]) {
        let s = self.x.lattice.stencil(p);
        let (vx, gx) = self.x.at_stencil(&s);
        let (vy, gy) = self.y.at_stencil(&s);
        (DVec2::new(vx, vy), [gx, gy])
    }
}

/// The Eikonal solution |grad T| = 1 from `sources` (T = 0 there), with `blocked` nodes
/// unreachable (T = infinity): Sethian's fast marching with the first-order upwind update.
pub fn fast_marching(lattice: Lattice, sources: &[bool], blocked: &[bool]) -> NodeField {
    let (nx, ny, h) = (lattice.nx, lattice.ny, lattice.spacing);
    let mut t = vec![f64::INFINITY; lattice.len()];
    let mut done = vec![false; lattice.len()];
    let mut heap = BinaryHeap::new();
    for (k, _) in sources
        .iter()
        .enumerate()
        .filter(|(k, s)| **s && !blocked[*k])
    {
        t[k] = 0.0;
        heap.push(Front(0.0, k));
    }
    while let Some(Front(value, k)) = heap.pop() {
        if done[k] || value > t[k] {
            continue;
        }
        done[k] = true;
        let (i, j) = (k % nx, k / nx);
        let neighbours = [
            (i > 0).then(|| k - 1),
            (i + 1 < nx).then(|| k + 1),
            (j > 0).then(|| k - nx),
            (j + 1 < ny).then(|| k + nx),
        ];
        for n in neighbours.into_iter().flatten() {
            if done[n] || blocked[n] {
                continue;
            }
            let (ni, nj) = (n % nx, n / nx);
            let along = |a: Option<usize>, b: Option<usize>| {
                let pick =
                    |m: Option<usize>| m.filter(|m| done[*m]).map_or(f64::INFINITY, |m| t[m]);
                pick(a).min(pick(b))
            };
            let a = along((ni > 0).then(|| n - 1), (ni + 1 < nx).then(|| n + 1));
            let b = along((nj > 0).then(|| n - nx), (nj + 1 < ny).then(|| n + nx));
            let update = upwind(a, b, h);
            if update < t[n] {
                t[n] = update;
                heap.push(Front(update, n));
            }
        }
    }
    NodeField { lattice, values: t }
}

/// The first-order upwind solution at a node whose smallest known neighbours along x and y
/// are `a` and `b`.
fn upwind(a: f64, b: f64, h: f64) -> f64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    if hi - lo >= h {
        return lo + h;
    }
    let sum = a + b;
    (sum + (2.0 * h * h - (a - b) * (a - b)).sqrt()) / 2.0
}

/// A heap entry ordered so that the smallest time pops first.
struct Front(f64, usize);

impl PartialEq for Front {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Front {}
impl PartialOrd for Front {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Front {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

/// The unit field along the gradient of `t` (central differences, one-sided next to unreachable
/// nodes); `sign` -1 gives the descent direction (towards the sources). Zero where `t` is flat
/// or unreachable.
pub fn unit_gradient(t: &NodeField, sign: f64) -> VectorField {
    let l = t.lattice;
    let mut gx = NodeField::constant(l, 0.0);
    let mut gy = NodeField::constant(l, 0.0);
    for j in 0..l.ny {
        for i in 0..l.nx {
            let here = t.at(i, j);
            if !here.is_finite() {
                continue;
            }
            let diff = |lo: Option<f64>, hi: Option<f64>| {
                let lo = lo.filter(|v| v.is_finite());
                let hi = hi.filter(|v| v.is_finite());
                match (lo, hi) {
                    (Some(a), Some(b)) => (b - a) / 2.0,
                    (Some(a), None) => here - a,
                    (None, Some(b)) => b - here,
                    (None, None) => 0.0,
                }
            };
            let dx = diff(
                (i > 0).then(|| t.at(i - 1, j)),
                (i + 1 < l.nx).then(|| t.at(i + 1, j)),
            );
            let dy = diff(
                (j > 0).then(|| t.at(i, j - 1)),
                (j + 1 < l.ny).then(|| t.at(i, j + 1)),
            );
            let g = DVec2::new(dx, dy).normalize_or_zero() * sign;
            let k = l.index(i, j);
            gx.values[k] = g.x;
            gy.values[k] = g.y;
        }
    }
    VectorField { x: gx, y: gy }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_gradient_is_the_derivative_of_the_interpolant() {
        let l = Lattice::covering(DVec2::ZERO, DVec2::new(3.0, 2.0), 0.5);
        let mut f = NodeField::constant(l, 0.0);
        for (k, v) in f.values.iter_mut().enumerate() {
            *v = ((k * 7919) % 13) as f64 * 0.37;
        }
        let p = DVec2::new(1.13, 0.71);
        let (_, g) = f.sample(p);
        let h = 1e-6;
        let fd = DVec2::new(
            (f.sample(p + DVec2::X * h).0 - f.sample(p - DVec2::X * h).0) / (2.0 * h),
            (f.sample(p + DVec2::Y * h).0 - f.sample(p - DVec2::Y * h).0) / (2.0 * h),
        );
        assert!((g - fd).length() < 1e-8, "{g} vs {fd}");
    }

    #[test]
    fn fast_marching_finds_the_distance_to_a_line_and_goes_round_a_wall() {
        let l = Lattice::covering(DVec2::ZERO, DVec2::new(10.0, 10.0), 0.25);
        let sources: Vec<bool> = (0..l.len()).map(|k| k % l.nx == l.nx - 1).collect();
        let open = vec![false; l.len()];
        let t = fast_marching(l, &sources, &open);
        // Distance to the line x = 10 is exact for a plane front.
        assert!((t.sample(DVec2::new(2.0, 5.0)).0 - 8.0).abs() < 1e-9);
        // A wall at x = 5 from y = 0 to 8: the way round is longer than straight.
        let wall: Vec<bool> = (0..l.len())
            .map(|k| {
                let p = l.node(k % l.nx, k / l.nx);
                (p.x - 5.0).abs() < 0.3 && p.y < 8.0
            })
            .collect();
        let t = fast_marching(l, &sources, &wall);
        let (behind, _) = t.sample(DVec2::new(4.0, 1.0));
        assert!(behind > 10.0, "{behind}");
        let w = unit_gradient(&t, -1.0);
        let (dir, _) = w.sample(DVec2::new(4.0, 1.0));
        assert!(
            dir.y > 0.5,
            "walkers behind the wall head up round it: {dir}"
        );
    }
}
