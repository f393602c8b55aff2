//! The matching score of an entry-exit pair (Ramirez et al. eq. 4 plus a direction term).

use crate::way::{path_length, wrapped_dt};
use crate::{Endpoint, PatchContext};

/// Walking speed at a density, by Weidmann's fundamental diagram (1993; the form Seyfried et al.
/// 2005 fit, which Crowd Art cites): v = v0 (1 - exp(-gamma (1/rho - 1/rho_jam))), with
/// gamma = 1.913 m-2 and rho_jam = 5.4 m-2. Below 1 person per m2 it hardly slows.
pub fn comfort_speed(free_speed: f64, density: f64) -> f64 {
    const GAMMA: f64 = 1.913;
    const RHO_JAM: f64 = 5.4;
    if density <= 1e-9 {
        return free_speed;
    }
    let v = free_speed * (1.0 - (-GAMMA * (1.0 / density - 1.0 / RHO_JAM)).exp());
    v.max(0.1 * free_speed)
}

/// Lower is better: arctan(|u_comfort - u|) + side penalty (0 opposite, 2 neighbouring, 4 same
/// border) + gain x weight x (1 - cos(angle to the requested direction)) / 2.
pub fn score(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> f64 {
    let length = path_length(entry, exit, ctx);
    let u = length / wrapped_dt(entry.t, exit.t, ctx.period_s);
    let mut s = (ctx.comfort_speed - u).abs().atan() + entry.side.penalty(exit.side);
    if let Some(d) = ctx.direction {
        let along = (exit.pos - entry.pos).normalize_or_zero();
        s += ctx.settings.direction_gain * d.weight.min(1.0) * (1.0 - d.dir.dot(along)) / 2.0;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fundamental_diagram_slows_with_density() {
        assert_eq!(comfort_speed(1.33, 0.0), 1.33);
        assert!((comfort_speed(1.33, 0.35) - 1.33).abs() < 0.02);
        assert!(comfort_speed(1.33, 2.0) < 1.0);
        assert!(comfort_speed(1.33, 4.0) < comfort_speed(1.33, 2.0));
    }
}
