//! A patch's motion worked on in its side file's bytes ([`super::encode_motion`]'s), without
//! decoding it: a brush stroke's stage 6 takes nearly every patch from the last build's side
//! file, and decoding them (17 million points on painting, 0.54 GB of fresh memory) only to
//! encode them again was a tenth of the stroke.

use super::{POINT_BYTES, PointKind, STANDER_BYTES, Summing, TRAJECTORY_BYTES};

/// A u32 of `bytes` at `at`, little-endian, if it is there.
fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(b.try_into().ok()?))
}

/// Each trajectory of one patch's bytes: where its record (entry, exit, point count) starts
/// and where its points do, with how many there are; `None` once the bytes do not hold what
/// their counts say.
fn trajectories(bytes: &[u8]) -> Option<Vec<(usize, usize, usize)>> {
    let standers = u32_at(bytes, 0)? as usize;
    let mut at = 4usize.checked_add(standers.checked_mul(STANDER_BYTES)?)?;
    let n = u32_at(bytes, at)? as usize;
    at += 4;
    let mut out = Vec::with_capacity(n.min(bytes.len() / TRAJECTORY_BYTES));
    for _ in 0..n {
        let points = u32_at(bytes, at + 8)? as usize;
        let first = at + TRAJECTORY_BYTES;
        let end = first.checked_add(points.checked_mul(POINT_BYTES)?)?;
        (end <= bytes.len()).then_some(())?;
        out.push((at, first, points));
        at = end;
    }
    (at == bytes.len()).then_some(out)
}

/// Renumbers the crossings one patch's bytes enter and leave by, in place, as `to` maps them
/// (the bytes of the motion decoded, renumbered and encoded again); `None`, the bytes left as
/// they were, where they are not a patch's.
pub fn renumber_encoded(bytes: &mut [u8], to: impl Fn(u32) -> u32) -> Option<()> {
    for (at, _, _) in trajectories(bytes)? {
        for field in [at, at + 4] {
            let number = to(u32_at(bytes, field)?);
            bytes[field..field + 4].copy_from_slice(&number.to_le_bytes());
        }
    }
    Some(())
}

/// What [`Summing`] adds up of one patch, read from its bytes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PatchSums {
    standers: u64,
    pausing: u64,
    turning: u64,
    /// Each trajectory's duration, in order ([`super::Trajectory::duration`]).
    durations: Vec<f64>,
}

impl PatchSums {
    /// How many trajectories the patch holds.
    pub fn trajectories(&self) -> u32 {
        self.durations.len() as u32
    }
}

/// One patch's [`PatchSums`] from its bytes, or `None` where they are not a patch's.
pub fn sums_of_encoded(bytes: &[u8]) -> Option<PatchSums> {
    let list = trajectories(bytes)?;
    let mut sums = PatchSums {
        standers: u64::from(u32_at(bytes, 0)?),
        durations: Vec::with_capacity(list.len()),
        ..PatchSums::default()
    };
    let t = |at: usize| Some(f64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?));
    for (_, first, points) in list {
        let kinds = (0..points).map(|k| bytes[first + k * POINT_BYTES + POINT_BYTES - 1]);
        let (mut pause, mut turn) = (false, false);
        for kind in kinds {
            pause |= kind == PointKind::Pause.code();
            turn |= kind == PointKind::Turn.code();
        }
        sums.pausing += u64::from(pause);
        sums.turning += u64::from(turn);
        let duration = match points {
            0 => 0.0,
            n => t(first + (n - 1) * POINT_BYTES + 16)? - t(first + 16)?,
        };
        sums.durations.push(duration);
    }
    Some(sums)
}

impl Summing {
    /// The next patch's motion, as [`sums_of_encoded`] read it from its bytes: the same sums,
    /// to the bit, as [`Summing::add`] of the motion.
    pub fn add_sums(&mut self, sums: &PatchSums) {
        let s = &mut self.summary;
        s.standers += sums.standers;
        s.walkers_trajectories += sums.durations.len() as u64;
        s.pausing += sums.pausing;
        s.same_border += sums.turning;
        for &d in &sums.durations {
            s.multi_period += u64::from(d > self.period_s + 1e-9);
            self.walked_s += d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectories::{
        ControlPoint, PatchMotion, Trajectory, encode_patch_bytes, summarize,
    };
    use glam::DVec2;
    use proptest::prelude::*;

    fn motion() -> impl Strategy<Value = PatchMotion> {
        let point = (
            0.0f64..8.0,
            0.0f64..8.0,
            0.0f64..40.0,
            0usize..PointKind::ALL.len(),
        );
        let trajectory = (0u32..50, 0u32..50, prop::collection::vec(point, 0..12));
        let standers = prop::collection::vec((0.0f64..8.0, 0.0f64..8.0), 0..3);
        (standers, prop::collection::vec(trajectory, 0..6)).prop_map(|(s, t)| PatchMotion {
            standers: s.into_iter().map(|(x, y)| DVec2::new(x, y)).collect(),
            trajectories: t
                .into_iter()
                .map(|(entry, exit, points)| Trajectory {
                    entry,
                    exit,
                    points: points
                        .into_iter()
                        .map(|(x, y, t, k)| ControlPoint {
                            pos: DVec2::new(x, y),
                            t,
                            kind: PointKind::ALL[k],
                        })
                        .collect(),
                })
                .collect(),
        })
    }

    proptest! {
        #[test]
        fn renumbered_in_its_bytes_a_patch_is_the_bytes_of_its_motion_renumbered(
            m in motion(), shift in 0u32..1000
        ) {
            let mut bytes = encode_patch_bytes(&m);
            renumber_encoded(&mut bytes, |c| c * 3 + shift).unwrap();
            let mut renumbered = m.clone();
            for t in &mut renumbered.trajectories {
                (t.entry, t.exit) = (t.entry * 3 + shift, t.exit * 3 + shift);
            }
            prop_assert_eq!(bytes, encode_patch_bytes(&renumbered));
        }

        #[test]
        fn summed_from_their_bytes_patches_sum_to_the_bit_as_their_motion(
            patches in prop::collection::vec(motion(), 0..6), period in 1.0f64..30.0
        ) {
            let mut summing = Summing::new(period);
            for m in &patches {
                summing.add_sums(&sums_of_encoded(&encode_patch_bytes(m)).unwrap());
            }
            let (held, read) = (summarize(&patches, period), summing.finish());
            prop_assert_eq!(held.walkers_measured.to_bits(), read.walkers_measured.to_bits());
            prop_assert_eq!(held, read);
        }

        #[test]
        fn bytes_that_are_no_patch_are_refused_and_left_alone(m in motion(), cut in 1usize..40) {
            let mut bytes = encode_patch_bytes(&m);
            bytes.truncate(bytes.len().saturating_sub(cut));
            let before = bytes.clone();
            prop_assert!(renumber_encoded(&mut bytes, |c| c + 1).is_none());
            prop_assert_eq!(&bytes, &before);
            prop_assert!(sums_of_encoded(&bytes).is_none());
        }
    }
}
