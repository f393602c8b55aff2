//! Limited-memory BFGS directions for the global descent (Nocedal and Wright, Algorithm 7.4),
//! started from the paper's metric: the inverse Hessian's first guess is diag(Q / dt, B / T),
//! so with no memory the direction is the paper's d eps = Q lambda (eq. 9-10), and each step's
//! change of gradient then corrects it for the curvature steepest descent ignores (the paper's
//! slow convergence, "a few minutes" for a hint of the result).

use std::collections::VecDeque;

/// Pairs kept.
const MEMORY: usize = 8;

/// The last steps s = x_{k+1} - x_k and gradient changes y = g_{k+1} - g_k.
#[derive(Default)]
pub struct Memory {
    pairs: VecDeque<(Vec<f64>, Vec<f64>, f64)>,
    last: Option<(Vec<f64>, Vec<f64>)>,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

impl Memory {
    /// Forgets everything (after the trajectory changed by other means than a global step).
    pub fn clear(&mut self) {
        self.pairs.clear();
        self.last = None;
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The direction at `x` with gradient `g`, given the metric `h0` (the diagonal first
    /// guess); records (x, g) for the next call. Pairs without positive curvature are skipped.
    pub fn direction(&mut self, x: &[f64], g: &[f64], h0: &[f64]) -> Vec<f64> {
        if let Some((px, pg)) = self.last.take() {
            let s: Vec<f64> = x.iter().zip(&px).map(|(a, b)| a - b).collect();
            let y: Vec<f64> = g.iter().zip(&pg).map(|(a, b)| a - b).collect();
            let sy = dot(&s, &y);
            if sy > 1e-300 && sy.is_finite() {
                if self.pairs.len() == MEMORY {
                    self.pairs.pop_front();
                }
                self.pairs.push_back((s, y, 1.0 / sy));
            }
        }
        self.last = Some((x.to_vec(), g.to_vec()));
        let mut q = g.to_vec();
        let mut alphas = Vec::with_capacity(self.pairs.len());
        for (s, y, rho) in self.pairs.iter().rev() {
            let a = rho * dot(s, &q);
            for (q, y) in q.iter_mut().zip(y) {
                *q -= a * y;
            }
            alphas.push(a);
        }
        let gamma = match self.pairs.back() {
            Some((s, y, _)) => {
                let hy: f64 = y.iter().zip(h0).map(|(y, h)| y * h * y).sum();
                if hy > 0.0 { dot(s, y) / hy } else { 1.0 }
            }
            None => 1.0,
        };
        let mut r: Vec<f64> = q.iter().zip(h0).map(|(q, h)| gamma * h * q).collect();
        for ((s, y, rho), a) in self.pairs.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &r);
            for (r, s) in r.iter_mut().zip(s) {
                *r += s * (a - b);
            }
        }
        r.iter_mut().for_each(|r| *r = -*r);
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a quadratic 1/2 x^T A x with a badly scaled A, L-BFGS reaches the minimum in a few
    /// exact line-searched steps where steepest descent would crawl.
    #[test]
    fn it_minimises_a_badly_scaled_quadratic() {
        let a = [1.0, 10.0, 100.0, 1000.0];
        let mut x = vec![1.0, 1.0, 1.0, 1.0];
        let mut memory = Memory::default();
        let h0 = vec![1.0; 4];
        for _ in 0..12 {
            let g: Vec<f64> = x.iter().zip(&a).map(|(x, a)| a * x).collect();
            let d = memory.direction(&x, &g, &h0);
            // Exact line search on the quadratic.
            let num = -dot(&g, &d);
            let den: f64 = d.iter().zip(&a).map(|(d, a)| a * d * d).sum();
            if den <= 0.0 {
                break;
            }
            let t = num / den;
            x.iter_mut().zip(&d).for_each(|(x, d)| *x += t * d);
        }
        let value: f64 = x.iter().zip(&a).map(|(x, a)| 0.5 * a * x * x).sum();
        assert!(value < 1e-12, "{value}");
    }
}
