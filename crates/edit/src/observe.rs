//! Observation operators H (Allain eq. 5) with their tangent-linear and adjoint: positions of
//! chosen characters (eq. 31), and the Eulerian density, velocity and vorticity on a grid
//! (section 6.2, after Allain, Courty and Corpetti 2012, "Particle swarm control").
//!
//! Eulerian quantities come from a Gaussian kernel G(x_c - y_i) = exp(-|x_c - y_i|^2 / 2 s^2) /
//! (2 pi s^2) centred on each character (so the density is in people per m^2):
//! - density  rho(c) = sum_i G(x_c - y_i);
//! - velocity v(c)   = sum_i G(x_c - y_i) u_i / (rho(c) + rho_0), a kernel-weighted mean
//!   velocity that fades to zero where nobody is (rho_0 keeps it defined there; the paper's
//!   Figure 5 notes the error that empty cells always leave);
//! - vorticity w(c)  = d v_y / dx - d v_x / dy by central differences on the grid (one-sided at
//!   its edge): a linear map of the velocity field, so its linearisation is the velocity's
//!   followed by the same differences, and its adjoint their transpose before the velocity's.

use crate::Rect;
use crate::model::{position, velocity};
use glam::DVec2;

/// An observation operator: what a constraint measures on a state.
pub trait Observe: Send + Sync {
    /// How many numbers it observes.
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// H(X).
    fn observe(&self, x: &[f64], out: &mut [f64]);
    /// H'(X) dx.
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]);
    /// out += H'(X)^T dy.
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]);
    /// out += H'(X)^T (scale (H(X) - y)): a constraint's forcing of the adjoint at one step.
    /// Operators whose H and H'^T share work (the kernel moments) do it once.
    fn misfit_adjoint(&self, x: &[f64], y: &[f64], scale: f64, out: &mut [f64]) {
        let mut h = vec![0.0; self.len()];
        self.observe(x, &mut h);
        for (h, y) in h.iter_mut().zip(y) {
            *h = scale * (*h - y);
        }
        self.adjoint_add(x, &h, out);
    }
}

/// The positions of chosen characters (eq. 31): two numbers each.
#[derive(Clone, Debug)]
pub struct Positions {
    pub who: Vec<usize>,
}

impl Observe for Positions {
    fn len(&self) -> usize {
        2 * self.who.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        for (o, &i) in out.chunks_exact_mut(2).zip(&self.who) {
            o.copy_from_slice(&x[4 * i..4 * i + 2]);
        }
    }
    fn tangent(&self, _: &[f64], dx: &[f64], out: &mut [f64]) {
        self.observe(dx, out);
    }
    fn adjoint_add(&self, _: &[f64], dy: &[f64], out: &mut [f64]) {
        for (d, &i) in dy.chunks_exact(2).zip(&self.who) {
            out[4 * i] += d[0];
            out[4 * i + 1] += d[1];
        }
    }
}

/// How far each chosen character walks faster than its limit, m/s (0 at or below it): as a
/// constraint with target 0, a soft speed limit whose square is C1 (stage 7 keeps edited
/// walkers to `match.max_speed` with it).
#[derive(Clone, Debug)]
pub struct SpeedLimit {
    pub who: Vec<Limited>,
}

/// One character under a [`SpeedLimit`].
#[derive(Clone, Copy, Debug)]
pub struct Limited {
    pub character: usize,
    /// m/s.
    pub limit: f64,
    /// The walk whose speed is limited: the model's own (`None`), or a blend of it with a plan.
    pub blend: Option<Blend>,
}

/// A walk shipped as its plan plus the model's displacement from it times a mask `w(t)`:
/// `plan + w (y - plan)`, whose velocity is `plan velocity + w (u - plan velocity) +
/// w' (y - plan)`. Where the mask falls while the model is still away from the plan, that
/// last term is what makes a shipped walk run (stage 7: 3.6 m/s on a 1.87 m/s limit).
#[derive(Clone, Copy, Debug)]
pub struct Blend {
    pub mask: f64,
    /// The mask's rate of change, 1/s.
    pub slope: f64,
    pub plan_pos: DVec2,
    pub plan_vel: DVec2,
}

impl Limited {
    /// The velocity limited, and its derivatives by the position and by the model's velocity
    /// (both multiples of the identity).
    fn walk(&self, x: &[f64]) -> (DVec2, f64, f64) {
        let (y, u) = (position(x, self.character), velocity(x, self.character));
        match self.blend {
            None => (u, 0.0, 1.0),
            Some(b) => (
                b.plan_vel + (u - b.plan_vel) * b.mask + (y - b.plan_pos) * b.slope,
                b.slope,
                b.mask,
            ),
        }
    }

    /// The excess over the limit and the unit direction of the velocity limited (zero where
    /// there is no excess), with the derivatives of [`Limited::walk`].
    fn excess(&self, x: &[f64]) -> (f64, DVec2, f64, f64) {
        let (v, by_pos, by_vel) = self.walk(x);
        let speed = v.length();
        if speed > self.limit {
            (speed - self.limit, v / speed, by_pos, by_vel)
        } else {
            (0.0, DVec2::ZERO, 0.0, 0.0)
        }
    }
}

impl Observe for SpeedLimit {
    fn len(&self) -> usize {
        self.who.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        for (o, l) in out.iter_mut().zip(&self.who) {
            *o = l.excess(x).0;
        }
    }
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        for (o, l) in out.iter_mut().zip(&self.who) {
            let (_, e, by_pos, by_vel) = l.excess(x);
            let i = l.character;
            *o = e.dot(position(dx, i) * by_pos + velocity(dx, i) * by_vel);
        }
    }
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]) {
        for (d, l) in dy.iter().zip(&self.who) {
            let (_, e, by_pos, by_vel) = l.excess(x);
            let (g, i) = (e * *d, l.character);
            out[4 * i] += g.x * by_pos;
            out[4 * i + 1] += g.y * by_pos;
            out[4 * i + 2] += g.x * by_vel;
            out[4 * i + 3] += g.y * by_vel;
        }
    }
}

/// How far each chosen character stands outside a rectangle, m (0 inside): as a constraint
/// with target 0, a soft "be in there" whose square is C1. Stage 7 gathers walkers into a
/// density edit's rectangle with it: the density's kernel pulls only those within a couple of
/// its widths, and a square fills from farther than that.
#[derive(Clone, Debug)]
pub struct Within {
    pub rect: Rect,
    pub who: Vec<usize>,
}

impl Within {
    /// How far character `i` is outside, and the unit direction away from the rectangle.
    fn outside(&self, x: &[f64], i: usize) -> (f64, DVec2) {
        let p = position(x, i);
        let d = p - p.clamp(self.rect.min, self.rect.max);
        let n = d.length();
        if n > 0.0 {
            (n, d / n)
        } else {
            (0.0, DVec2::ZERO)
        }
    }
}

impl Observe for Within {
    fn len(&self) -> usize {
        self.who.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        for (o, &i) in out.iter_mut().zip(&self.who) {
            *o = self.outside(x, i).0;
        }
    }
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        for (o, &i) in out.iter_mut().zip(&self.who) {
            *o = self.outside(x, i).1.dot(position(dx, i));
        }
    }
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]) {
        for (d, &i) in dy.iter().zip(&self.who) {
            let e = self.outside(x, i).1 * *d;
            out[4 * i] += e.x;
            out[4 * i + 1] += e.y;
        }
    }
}

/// How far each counted character stands inside the clearance of the others, summed, m: per
/// character i, sum_j max(0, `clearance` - |y_j - y_i|). As a constraint with target 0, a soft
/// collision rule whose square is C1 (stage 7 keeps its edits apart with it, as the exact
/// check of what it ships will).
#[derive(Clone, Debug)]
pub struct Apart {
    /// The distance two centres keep, m.
    pub clearance: f64,
    /// The characters counted (and observed), in the order of the output.
    pub who: Vec<usize>,
}

impl Apart {
    /// Every counted pair (a, b) (indices into `who`) closer than the clearance, with their
    /// unit offset from a to b and its length.
    fn pressed(&self, x: &[f64]) -> Vec<(usize, usize, DVec2, f64)> {
        let mut out = Vec::new();
        for (a, &i) in self.who.iter().enumerate() {
            for (b, &j) in self.who.iter().enumerate().skip(a + 1) {
                let d = position(x, j) - position(x, i);
                let n = d.length();
                if n < self.clearance && n > 0.0 {
                    out.push((a, b, d / n, n));
                }
            }
        }
        out
    }
}

impl Observe for Apart {
    fn len(&self) -> usize {
        self.who.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (a, b, _, n) in self.pressed(x) {
            out[a] += self.clearance - n;
            out[b] += self.clearance - n;
        }
    }
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (a, b, e, _) in self.pressed(x) {
            let (i, j) = (self.who[a], self.who[b]);
            let dn = e.dot(position(dx, j) - position(dx, i));
            out[a] -= dn;
            out[b] -= dn;
        }
    }
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]) {
        for (a, b, e, _) in self.pressed(x) {
            let (i, j) = (self.who[a], self.who[b]);
            let g = e * -(dy[a] + dy[b]);
            out[4 * j] += g.x;
            out[4 * j + 1] += g.y;
            out[4 * i] -= g.x;
            out[4 * i + 1] -= g.y;
        }
    }
}

/// Which characters an Eulerian operator counts: everyone, or those listed (stage 7: the
/// walkers in the patch at the observed step; one operator per step).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Counted {
    #[default]
    All,
    Only(Vec<usize>),
}

impl Counted {
    /// The characters counted among `n`.
    fn each(&self, n: usize) -> Box<dyn Iterator<Item = usize> + '_> {
        match self {
            Counted::All => Box::new(0..n),
            Counted::Only(who) => Box::new(who.iter().copied().filter(move |&i| i < n)),
        }
    }
}

/// Kernel contributions below exp(-18) of the peak are skipped: the jump this leaves is
/// 1.5e-8 of a character's weight, far below what any constraint or test resolves.
const KERNEL_REACH: f64 = 18.0;

/// A grid of square cells over which Eulerian quantities are measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EulerGrid {
    pub origin: DVec2,
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    /// The kernel's standard deviation, m.
    pub sigma: f64,
}

/// The cells an operator reads, as a box of columns and rows (end exclusive): the moments are
/// only made there.
#[derive(Clone, Copy, Debug)]
struct Window {
    cols: (usize, usize),
    rows: (usize, usize),
}

impl Window {
    /// The box around `cells`, widened by `margin` cells (clamped to the grid).
    fn around(grid: &EulerGrid, cells: &[usize], margin: usize) -> Window {
        let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
        for &c in cells {
            let (i, j) = (c % grid.nx, c / grid.nx);
            c0 = c0.min(i.saturating_sub(margin));
            c1 = c1.max((i + margin + 1).min(grid.nx));
            r0 = r0.min(j.saturating_sub(margin));
            r1 = r1.max((j + margin + 1).min(grid.ny));
        }
        Window {
            cols: (c0.min(c1), c1),
            rows: (r0.min(r1), r1),
        }
    }
}

/// Per cell, the kernel density and momentum (sum of G u).
struct Moments {
    rho: Vec<f64>,
    momentum: Vec<DVec2>,
}

impl EulerGrid {
    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    pub fn centre(&self, c: usize) -> DVec2 {
        let (i, j) = (c % self.nx, c / self.nx);
        self.origin + (DVec2::new(i as f64, j as f64) + 0.5) * self.cell
    }

    /// The cells whose centre lies in the rectangle `[min, max]`.
    pub fn cells_in(&self, min: DVec2, max: DVec2) -> Vec<usize> {
        (0..self.cells())
            .filter(|&c| {
                let p = self.centre(c);
                p.cmpge(min).all() && p.cmple(max).all()
            })
            .collect()
    }

    /// Calls `visit(cell, G, dG/dy)` for each cell of `window` the kernel of a character at `p`
    /// reaches.
    fn around(&self, p: DVec2, window: Window, mut visit: impl FnMut(usize, f64, DVec2)) {
        let s2 = self.sigma * self.sigma;
        let norm = 1.0 / (2.0 * std::f64::consts::PI * s2);
        let reach = self.sigma * (2.0 * KERNEL_REACH).sqrt();
        let range = |lo: f64, (first, end): (usize, usize)| {
            let a = ((lo - reach) / self.cell - 0.5).floor().max(0.0) as usize;
            let b = (((lo + reach) / self.cell - 0.5).ceil() + 1.0).max(0.0) as usize;
            a.max(first)..b.min(end)
        };
        let local = p - self.origin;
        // The kernel is the product of one Gaussian per axis: one exponential per column and
        // per row the character reaches, rather than one per cell.
        let axis = |k: usize, at: f64| {
            let d = (k as f64 + 0.5) * self.cell - at;
            let q = d * d / (2.0 * s2);
            (d, q, (-q).exp())
        };
        let cols = range(local.x, window.cols);
        let across: Vec<(f64, f64, f64)> = cols.clone().map(|i| axis(i, local.x)).collect();
        for j in range(local.y, window.rows) {
            let (dy, qy, gy) = axis(j, local.y);
            for (i, &(dx, qx, gx)) in cols.clone().zip(&across) {
                if qx + qy > KERNEL_REACH {
                    continue;
                }
                let g = norm * gx * gy;
                // d/dy of G(x_c - y) = G (x_c - y) / s^2.
                visit(j * self.nx + i, g, DVec2::new(dx, dy) * (g / s2));
            }
        }
    }

    fn moments(&self, x: &[f64], counted: &Counted, window: Window) -> Moments {
        let mut m = Moments {
            rho: vec![0.0; self.cells()],
            momentum: vec![DVec2::ZERO; self.cells()],
        };
        for i in counted.each(x.len() / 4) {
            let u = velocity(x, i);
            self.around(position(x, i), window, |c, g, _| {
                m.rho[c] += g;
                m.momentum[c] += u * g;
            });
        }
        m
    }

    fn moments_tangent(&self, x: &[f64], dx: &[f64], counted: &Counted, window: Window) -> Moments {
        let mut m = Moments {
            rho: vec![0.0; self.cells()],
            momentum: vec![DVec2::ZERO; self.cells()],
        };
        for i in counted.each(x.len() / 4) {
            let (u, dp, du) = (velocity(x, i), position(dx, i), velocity(dx, i));
            self.around(position(x, i), window, |c, g, dg| {
                let dgi = dg.dot(dp);
                m.rho[c] += dgi;
                m.momentum[c] += u * dgi + du * g;
            });
        }
        m
    }

    /// out += the adjoint of the moments applied to (rho_bar, momentum_bar).
    fn moments_adjoint(
        &self,
        x: &[f64],
        counted: &Counted,
        rho_bar: &[f64],
        mom_bar: &[DVec2],
        window: Window,
        out: &mut [f64],
    ) {
        for i in counted.each(x.len() / 4) {
            let u = velocity(x, i);
            let (mut dp, mut du) = (DVec2::ZERO, DVec2::ZERO);
            self.around(position(x, i), window, |c, g, dg| {
                dp += dg * (rho_bar[c] + mom_bar[c].dot(u));
                du += mom_bar[c] * g;
            });
            for (k, v) in [dp.x, dp.y, du.x, du.y].into_iter().enumerate() {
                out[4 * i + k] += v;
            }
        }
    }
}

/// The kernel density at chosen cells, people per m^2.
#[derive(Clone, Debug)]
pub struct Density {
    pub grid: EulerGrid,
    pub cells: Vec<usize>,
    pub counted: Counted,
}

impl Observe for Density {
    fn len(&self) -> usize {
        self.cells.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        let m = self
            .grid
            .moments(x, &self.counted, Window::around(&self.grid, &self.cells, 0));
        for (o, &c) in out.iter_mut().zip(&self.cells) {
            *o = m.rho[c];
        }
    }
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        let window = Window::around(&self.grid, &self.cells, 0);
        let m = self.grid.moments_tangent(x, dx, &self.counted, window);
        for (o, &c) in out.iter_mut().zip(&self.cells) {
            *o = m.rho[c];
        }
    }
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]) {
        let mut rho_bar = vec![0.0; self.grid.cells()];
        for (d, &c) in dy.iter().zip(&self.cells) {
            rho_bar[c] += d;
        }
        let mom_bar = vec![DVec2::ZERO; self.grid.cells()];
        let window = Window::around(&self.grid, &self.cells, 0);
        self.grid
            .moments_adjoint(x, &self.counted, &rho_bar, &mom_bar, window, out);
    }
}

/// The regulariser rho_0 of the Eulerian velocity, people per m^2: a tenth of a sparse crowd.
pub const VELOCITY_FLOOR: f64 = 0.05;

/// The Eulerian velocity of every cell of a grid (the fields both velocity and vorticity
/// constraints read).
fn velocity_field(
    grid: &EulerGrid,
    x: &[f64],
    counted: &Counted,
    window: Window,
) -> (Vec<DVec2>, Moments) {
    let m = grid.moments(x, counted, window);
    let v = m
        .rho
        .iter()
        .zip(&m.momentum)
        .map(|(r, mo)| *mo / (r + VELOCITY_FLOOR))
        .collect();
    (v, m)
}

fn velocity_tangent(
    grid: &EulerGrid,
    x: &[f64],
    dx: &[f64],
    counted: &Counted,
    window: Window,
) -> Vec<DVec2> {
    let m = grid.moments(x, counted, window);
    let dm = grid.moments_tangent(x, dx, counted, window);
    (0..grid.cells())
        .map(|c| {
            let r = m.rho[c] + VELOCITY_FLOOR;
            dm.momentum[c] / r - m.momentum[c] * (dm.rho[c] / (r * r))
        })
        .collect()
}

fn velocity_adjoint(
    grid: &EulerGrid,
    x: &[f64],
    counted: &Counted,
    v_bar: &[DVec2],
    window: Window,
    out: &mut [f64],
) {
    let m = grid.moments(x, counted, window);
    velocity_adjoint_at(grid, x, counted, &m, v_bar, window, out);
}

/// [`velocity_adjoint`] with the moments at `x` already made.
fn velocity_adjoint_at(
    grid: &EulerGrid,
    x: &[f64],
    counted: &Counted,
    m: &Moments,
    v_bar: &[DVec2],
    window: Window,
    out: &mut [f64],
) {
    let mut rho_bar = vec![0.0; grid.cells()];
    let mut mom_bar = vec![DVec2::ZERO; grid.cells()];
    for c in 0..grid.cells() {
        let r = m.rho[c] + VELOCITY_FLOOR;
        mom_bar[c] = v_bar[c] / r;
        rho_bar[c] = -v_bar[c].dot(m.momentum[c]) / (r * r);
    }
    grid.moments_adjoint(x, counted, &rho_bar, &mom_bar, window, out);
}

/// The Eulerian velocity at chosen cells: two numbers each.
#[derive(Clone, Debug)]
pub struct Velocity {
    pub grid: EulerGrid,
    pub cells: Vec<usize>,
    pub counted: Counted,
}

impl Observe for Velocity {
    fn len(&self) -> usize {
        2 * self.cells.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        let (v, _) = velocity_field(
            &self.grid,
            x,
            &self.counted,
            Window::around(&self.grid, &self.cells, 0),
        );
        for (o, &c) in out.chunks_exact_mut(2).zip(&self.cells) {
            o.copy_from_slice(&[v[c].x, v[c].y]);
        }
    }
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        let dv = velocity_tangent(
            &self.grid,
            x,
            dx,
            &self.counted,
            Window::around(&self.grid, &self.cells, 0),
        );
        for (o, &c) in out.chunks_exact_mut(2).zip(&self.cells) {
            o.copy_from_slice(&[dv[c].x, dv[c].y]);
        }
    }
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]) {
        let mut v_bar = vec![DVec2::ZERO; self.grid.cells()];
        for (d, &c) in dy.chunks_exact(2).zip(&self.cells) {
            v_bar[c] += DVec2::new(d[0], d[1]);
        }
        let window = Window::around(&self.grid, &self.cells, 0);
        velocity_adjoint(&self.grid, x, &self.counted, &v_bar, window, out);
    }
    fn misfit_adjoint(&self, x: &[f64], y: &[f64], scale: f64, out: &mut [f64]) {
        let window = Window::around(&self.grid, &self.cells, 0);
        let (v, m) = velocity_field(&self.grid, x, &self.counted, window);
        let mut v_bar = vec![DVec2::ZERO; self.grid.cells()];
        for (y, &c) in y.chunks_exact(2).zip(&self.cells) {
            v_bar[c] += (v[c] - DVec2::new(y[0], y[1])) * scale;
        }
        velocity_adjoint_at(&self.grid, x, &self.counted, &m, &v_bar, window, out);
    }
}

/// The vorticity (curl) of the Eulerian velocity at chosen cells, 1/s.
#[derive(Clone, Debug)]
pub struct Vorticity {
    pub grid: EulerGrid,
    pub cells: Vec<usize>,
    pub counted: Counted,
}

impl Vorticity {
    /// The difference stencil of d/dx or d/dy at cell c: (lower cell, upper cell, 1 / distance).
    fn stencil(&self, c: usize, along_x: bool) -> (usize, usize, f64) {
        let g = &self.grid;
        let (i, j) = (c % g.nx, c / g.nx);
        let (pos, n) = if along_x { (i, g.nx) } else { (j, g.ny) };
        let lo = pos.saturating_sub(1);
        let hi = (pos + 1).min(n - 1);
        let at = |k: usize| if along_x { j * g.nx + k } else { k * g.nx + i };
        (at(lo), at(hi), 1.0 / ((hi - lo).max(1) as f64 * g.cell))
    }

    fn curl(&self, v: &[DVec2], out: &mut [f64]) {
        for (o, &c) in out.iter_mut().zip(&self.cells) {
            let (xl, xh, sx) = self.stencil(c, true);
            let (yl, yh, sy) = self.stencil(c, false);
            *o = (v[xh].y - v[xl].y) * sx - (v[yh].x - v[yl].x) * sy;
        }
    }
}

impl Observe for Vorticity {
    fn len(&self) -> usize {
        self.cells.len()
    }
    fn observe(&self, x: &[f64], out: &mut [f64]) {
        let window = Window::around(&self.grid, &self.cells, 1);
        self.curl(&velocity_field(&self.grid, x, &self.counted, window).0, out);
    }
    fn tangent(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        let window = Window::around(&self.grid, &self.cells, 1);
        self.curl(
            &velocity_tangent(&self.grid, x, dx, &self.counted, window),
            out,
        );
    }
    fn adjoint_add(&self, x: &[f64], dy: &[f64], out: &mut [f64]) {
        let window = Window::around(&self.grid, &self.cells, 1);
        velocity_adjoint(
            &self.grid,
            x,
            &self.counted,
            &self.curl_transpose(dy),
            window,
            out,
        );
    }
    fn misfit_adjoint(&self, x: &[f64], y: &[f64], scale: f64, out: &mut [f64]) {
        let window = Window::around(&self.grid, &self.cells, 1);
        let (v, m) = velocity_field(&self.grid, x, &self.counted, window);
        let mut w = vec![0.0; self.cells.len()];
        self.curl(&v, &mut w);
        for (w, y) in w.iter_mut().zip(y) {
            *w = scale * (*w - y);
        }
        velocity_adjoint_at(
            &self.grid,
            x,
            &self.counted,
            &m,
            &self.curl_transpose(&w),
            window,
            out,
        );
    }
}

impl Vorticity {
    /// The differences' transpose: the velocity adjoint of a vorticity adjoint `dy`.
    fn curl_transpose(&self, dy: &[f64]) -> Vec<DVec2> {
        let mut v_bar = vec![DVec2::ZERO; self.grid.cells()];
        for (d, &c) in dy.iter().zip(&self.cells) {
            let (xl, xh, sx) = self.stencil(c, true);
            let (yl, yh, sy) = self.stencil(c, false);
            v_bar[xh].y += d * sx;
            v_bar[xl].y -= d * sx;
            v_bar[yh].x -= d * sy;
            v_bar[yl].x += d * sy;
        }
        v_bar
    }
}
