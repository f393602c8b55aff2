//! A flow map painted for a flow edit (`EditKind::FlowMap`): a velocity at every pixel, in the
//! layers' convention (R = east, G = north, 128 = zero, A = weight; row 0 is the north edge),
//! scaled so that a full-strength pixel is the edit's speed.

use glam::DVec2;

/// A velocity per pixel (world frame: x east, y north, m/s) and how much each pixel counts
/// (its alpha, 0-1), over the painted maps (`meters_per_pixel` each).
#[derive(Debug, Clone, PartialEq)]
pub struct VelocityMap {
    pub width: u32,
    pub height: u32,
    pub meters_per_pixel: f64,
    /// Row by row from the north edge, as painted.
    pub velocity: Vec<DVec2>,
    pub weight: Vec<f64>,
}

impl VelocityMap {
    /// The weighted mean velocity of the pixels whose centres lie in the world rectangle
    /// `[min, max)`, and their mean weight; `None` where no pixel centre does.
    pub fn mean_over(&self, min: DVec2, max: DVec2) -> Option<(DVec2, f64)> {
        let m = self.meters_per_pixel;
        let h = f64::from(self.height);
        // Pixel (px, py) has its centre at ((px + 0.5) m, (h - py - 0.5) m).
        let cols = (min.x / m - 0.5).ceil().max(0.0)..(max.x / m - 0.5).ceil().max(0.0);
        let rows = (h - max.y / m - 0.5).ceil().max(0.0)..(h - min.y / m - 0.5).ceil().max(0.0);
        let (cols, rows) = (
            cols.start as u32..(cols.end as u32).min(self.width),
            rows.start as u32..(rows.end as u32).min(self.height),
        );
        let (mut sum, mut weight, mut count) = (DVec2::ZERO, 0.0, 0usize);
        for py in rows {
            for px in cols.clone() {
                let i = (py * self.width + px) as usize;
                sum += self.velocity[i] * self.weight[i];
                weight += self.weight[i];
                count += 1;
            }
        }
        (count > 0).then(|| {
            let mean = if weight > 0.0 {
                sum / weight
            } else {
                DVec2::ZERO
            };
            (mean, weight / count as f64)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 x 2 map of 1 m pixels: the west half eastwards, the east half northwards at half
    /// weight; the top-right pixel unpainted.
    fn map() -> VelocityMap {
        let (e, n) = (DVec2::X, DVec2::Y);
        VelocityMap {
            width: 4,
            height: 2,
            meters_per_pixel: 1.0,
            velocity: vec![e, e, n, n, e, e, n, n],
            weight: vec![1.0, 1.0, 0.5, 0.0, 1.0, 1.0, 0.5, 0.5],
        }
    }

    #[test]
    fn a_rectangle_takes_the_pixels_whose_centres_it_holds() {
        let m = map();
        // The west half: eastwards, full weight.
        assert_eq!(
            m.mean_over(DVec2::ZERO, DVec2::new(2.0, 2.0)),
            Some((DVec2::X, 1.0))
        );
        // The north-east pixel (row 0, column 3) is unpainted: weight 0, no velocity.
        assert_eq!(
            m.mean_over(DVec2::new(3.0, 1.0), DVec2::new(4.0, 2.0)),
            Some((DVec2::ZERO, 0.0))
        );
        // The south-east quarter: northwards at half weight.
        assert_eq!(
            m.mean_over(DVec2::new(2.0, 0.0), DVec2::new(4.0, 1.0)),
            Some((DVec2::Y, 0.5))
        );
        // No pixel centre inside, or off the map.
        assert_eq!(
            m.mean_over(DVec2::new(0.1, 0.1), DVec2::new(0.4, 0.4)),
            None
        );
        assert_eq!(
            m.mean_over(DVec2::new(5.0, 0.0), DVec2::new(6.0, 1.0)),
            None
        );
    }
}
