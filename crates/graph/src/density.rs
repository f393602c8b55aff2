//! Painted intensities to requested densities under a cap.
//!
//! The artist paints *relative* intensities and states how many people the scene holds; the
//! pipeline also caps every patch at `rho_max` (Crowd Art section 4). Scaling the painting
//! linearly can ask more than the cap where the paint is brightest (the `ring` scene asks
//! 0.47 characters per m2 on its ring), a request no optimiser can meet. Instead the people are
//! poured in like water: every patch gets `k * intensity`, except that no patch rises above its
//! cap, and `k` is the one value for which the total is exactly the requested number. Where the
//! cap is never reached this is the plain linear scaling.

/// Densities `min(cap_i, k * weight_i)` whose sum is `total`, or `Err(capacity)` (the largest
/// total the caps allow on the painted patches) when `total` does not fit.
///
/// Exact, and deterministic: patches saturate in order of `cap / weight` (ties by index).
pub fn fill_under_caps(weights: &[f64], caps: &[f64], total: f64) -> Result<Vec<f64>, f64> {
    debug_assert_eq!(weights.len(), caps.len());
    if total <= 0.0 {
        return Ok(vec![0.0; weights.len()]);
    }
    let cap = |i: usize| caps[i].max(0.0);
    let mut order: Vec<usize> = (0..weights.len()).filter(|&i| weights[i] > 0.0).collect();
    let capacity: f64 = order.iter().map(|&i| cap(i)).sum();
    if total > capacity * (1.0 + 1e-12) {
        return Err(capacity);
    }
    order.sort_by(|&a, &b| {
        (cap(a) / weights[a])
            .total_cmp(&(cap(b) / weights[b]))
            .then(a.cmp(&b))
    });
    // Walk the saturation order: with the patches before `i` at their caps, the rest share
    // what is left in proportion to their weights. If every patch saturates, total equals the
    // capacity and k stays infinite (every patch at its cap).
    let mut saturated = 0.0;
    let mut free_weight: f64 = order.iter().map(|&i| weights[i]).sum();
    let mut k = f64::INFINITY;
    for &i in &order {
        let candidate = (total - saturated) / free_weight;
        if candidate * weights[i] <= cap(i) {
            k = candidate;
            break;
        }
        saturated += cap(i);
        free_weight -= weights[i];
    }
    Ok((0..weights.len())
        .map(|i| {
            if weights[i] > 0.0 {
                (k * weights[i]).min(cap(i))
            } else {
                0.0
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn below_the_cap_it_is_linear_scaling() {
        let d = fill_under_caps(&[1.0, 2.0, 3.0], &[10.0; 3], 12.0).unwrap();
        assert_eq!(d, vec![2.0, 4.0, 6.0]);
    }

    #[test]
    fn the_brightest_patch_is_capped_and_the_rest_take_the_overflow() {
        let d = fill_under_caps(&[1.0, 1.0, 4.0], &[1.0; 3], 2.0).unwrap();
        assert_eq!(d, vec![0.5, 0.5, 1.0]);
    }

    #[test]
    fn more_than_the_caps_allow_is_refused_with_the_capacity() {
        assert_eq!(fill_under_caps(&[1.0, 0.0, 1.0], &[1.0; 3], 2.5), Err(2.0));
    }

    proptest! {
        #[test]
        fn the_total_is_kept_no_cap_is_exceeded_and_order_is_kept(
            weights in proptest::collection::vec(0.0f64..5.0, 1..40),
            cap in 0.1f64..2.0,
            share in 0.01f64..1.0,
        ) {
            let caps = vec![cap; weights.len()];
            let painted = weights.iter().filter(|&&w| w > 0.0).count() as f64;
            prop_assume!(painted > 0.0);
            let total = share * painted * cap;
            let d = fill_under_caps(&weights, &caps, total).unwrap();
            let sum: f64 = d.iter().sum();
            prop_assert!((sum - total).abs() <= 1e-9 * total.max(1.0));
            for i in 0..weights.len() {
                prop_assert!(d[i] <= cap + 1e-12);
                for j in 0..weights.len() {
                    if weights[i] <= weights[j] {
                        prop_assert!(d[i] <= d[j] + 1e-12);
                    }
                }
            }
        }
    }
}
