//! Clamped cubic splines in time through 2D knots (Ramirez eq. 11-12).
//!
//! Between knots the curve is a cubic Hermite piece; the knot velocities are solved so that
//! acceleration is continuous too (C2), with the velocities at both ends given. That is one
//! tridiagonal system per trajectory, solved by the Thomas algorithm: diagonally dominant, so
//! no pivoting is needed.

use glam::DVec2;

/// A C2 curve through `(t_i, p_i)` with given end velocities.
#[derive(Debug, Clone)]
pub struct Spline {
    t: Vec<f64>,
    p: Vec<DVec2>,
    /// Velocity at each knot.
    v: Vec<DVec2>,
}

impl Spline {
    /// Knot times must increase strictly; at least two knots.
    pub fn clamped(t: Vec<f64>, p: Vec<DVec2>, v_start: DVec2, v_end: DVec2) -> Spline {
        let n = t.len();
        debug_assert!(n >= 2 && n == p.len());
        debug_assert!(t.windows(2).all(|w| w[1] > w[0]));
        let mut v = vec![DVec2::ZERO; n];
        v[0] = v_start;
        v[n - 1] = v_end;
        if n > 2 {
            // Unknowns v_1 .. v_{n-2}. Row i (1 <= i <= n-2):
            //   h_i v_{i-1} + 2 (h_{i-1} + h_i) v_i + h_{i-1} v_{i+1}
            //     = 3 (h_i d_{i-1} + h_{i-1} d_i),
            // with h_i = t_{i+1} - t_i and d_i = (p_{i+1} - p_i) / h_i.
            let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            let d: Vec<DVec2> = (0..n - 1).map(|i| (p[i + 1] - p[i]) / h[i]).collect();
            let m = n - 2;
            let mut diag = vec![0.0; m];
            let mut upper = vec![0.0; m];
            let mut lower = vec![0.0; m];
            let mut rhs = vec![DVec2::ZERO; m];
            for k in 0..m {
                let i = k + 1;
                lower[k] = h[i];
                diag[k] = 2.0 * (h[i - 1] + h[i]);
                upper[k] = h[i - 1];
                rhs[k] = 3.0 * (h[i] * d[i - 1] + h[i - 1] * d[i]);
            }
            rhs[0] -= lower[0] * v_start;
            rhs[m - 1] -= upper[m - 1] * v_end;
            // Thomas algorithm: forward elimination, back substitution.
            for k in 1..m {
                let w = lower[k] / diag[k - 1];
                diag[k] -= w * upper[k - 1];
                let r = rhs[k - 1];
                rhs[k] -= w * r;
            }
            v[m] = rhs[m - 1] / diag[m - 1];
            for k in (0..m - 1).rev() {
                v[k + 1] = (rhs[k] - upper[k] * v[k + 2]) / diag[k];
            }
        }
        Spline { t, p, v }
    }

    /// The piece holding `t` (clamped to the knots' span): its first knot, its length and
    /// where `t` is along it in [0, 1]; `Err(i)` when `t` is knot `i` itself.
    fn piece(&self, t: f64) -> Result<(usize, f64, f64), usize> {
        let n = self.t.len();
        let t = t.clamp(self.t[0], self.t[n - 1]);
        let i = match self.t.binary_search_by(|x| x.total_cmp(&t)) {
            Ok(i) => return Err(i),
            Err(i) => i.clamp(1, n - 1) - 1,
        };
        let h = self.t[i + 1] - self.t[i];
        Ok((i, h, (t - self.t[i]) / h))
    }

    /// Position at time `t` (clamped to the knots' span).
    pub fn at(&self, t: f64) -> DVec2 {
        let (i, h, s) = match self.piece(t) {
            Ok(piece) => piece,
            Err(i) => return self.p[i],
        };
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        h00 * self.p[i] + h10 * h * self.v[i] + h01 * self.p[i + 1] + h11 * h * self.v[i + 1]
    }

    /// Velocity at time `t` (clamped to the knots' span).
    pub fn velocity(&self, t: f64) -> DVec2 {
        let (i, h, s) = match self.piece(t) {
            Ok(piece) => piece,
            Err(i) => return self.v[i],
        };
        let s2 = s * s;
        let d00 = 6.0 * s2 - 6.0 * s;
        let d10 = 3.0 * s2 - 4.0 * s + 1.0;
        let d01 = -6.0 * s2 + 6.0 * s;
        let d11 = 3.0 * s2 - 2.0 * s;
        (d00 * self.p[i] + d01 * self.p[i + 1]) / h + d10 * self.v[i] + d11 * self.v[i + 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_straight_walk_stays_straight() {
        let v = DVec2::new(1.2, 0.0);
        let t = vec![0.0, 1.0, 2.5, 3.0];
        let p = t.iter().map(|&t| v * t).collect();
        let s = Spline::clamped(t, p, v, v);
        for k in 0..=30 {
            let t = k as f64 * 0.1;
            assert!(s.at(t).distance(v * t) < 1e-12);
        }
    }

    proptest! {
        #[test]
        fn passes_its_knots_with_its_end_velocities_and_continuous_acceleration(
            steps in proptest::collection::vec((0.2f64..2.0, -2.0f64..2.0, -2.0f64..2.0), 1..12),
            v0 in (-2.0f64..2.0, -2.0f64..2.0),
            v1 in (-2.0f64..2.0, -2.0f64..2.0),
        ) {
            let mut t = vec![0.0];
            let mut p = vec![DVec2::ZERO];
            for &(dt, dx, dy) in &steps {
                t.push(t.last().unwrap() + dt);
                p.push(*p.last().unwrap() + DVec2::new(dx, dy));
            }
            let (v0, v1) = (DVec2::new(v0.0, v0.1), DVec2::new(v1.0, v1.1));
            let s = Spline::clamped(t.clone(), p.clone(), v0, v1);
            for (ti, pi) in t.iter().zip(&p) {
                prop_assert!(s.at(*ti).distance(*pi) < 1e-9);
            }
            let end = *t.last().unwrap();
            let d = 1e-6;
            prop_assert!(((s.at(d) - s.at(0.0)) / d - v0).length() < 1e-2 * (1.0 + v0.length()));
            prop_assert!(
                ((s.at(end) - s.at(end - d)) / d - v1).length() < 1e-2 * (1.0 + v1.length())
            );
            let e = 1e-5;
            // Second differences on either side of each inner knot agree (C2).
            for &ti in &t[1..t.len() - 1] {
                let acc = |c: f64| (s.at(c + e) - 2.0 * s.at(c) + s.at(c - e)) / (e * e);
                let (l, r) = (acc(ti - 2.0 * e), acc(ti + 2.0 * e));
                prop_assert!((l - r).length() < 1e-2 * (1.0 + l.length()), "{l} {r}");
            }
        }
    }
}
