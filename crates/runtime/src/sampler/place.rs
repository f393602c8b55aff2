//! The two loops over every walker, every frame: finding the walkers whose piece has ended,
//! and placing each walker at the frame's time (its position and heading, appended to the
//! frame's samples if it is in view).
//!
//! The compiler leaves both scalar (it will not interleave lanes into 16-byte samples, nor
//! turn a compare into a list of indices), so on x86-64 they are written with SSE2, a
//! [`Four`] at a time: packed loads of its fields, packed arithmetic, a 4 x 4 transpose into
//! samples, and a mask that keeps those in view without a branch. The scalar loops are the
//! same arithmetic, operation for operation, so both give the same bits (a test holds them to
//! it).

use super::Sample;
use super::walker::{Four, Walkers, radians};
use std::ops::Range;

/// Appends the walkers `range` of `w` inside `view`, placed `whole` ticks and `frac` of a tick
/// after the epoch. `range` starts at a multiple of 4.
pub(super) fn place(
    w: &Walkers,
    range: Range<usize>,
    whole: u32,
    frac: f32,
    view: [f32; 4],
    out: &mut Vec<Sample>,
) {
    let whole_fours = range.start / 4..range.end / 4;
    let fours = &w.fours[whole_fours.clone()];
    let first_id = range.start as u32;
    // SAFETY: SSE2 is part of every x86-64 processor.
    #[cfg(target_arch = "x86_64")]
    unsafe {
        sse2::place(fours, first_id, whole, frac, view, out)
    };
    #[cfg(not(target_arch = "x86_64"))]
    scalar(fours, first_id, 0..4, whole, frac, view, out);
    // The walkers of a last, partial four.
    if !range.end.is_multiple_of(4) {
        let f = &w.fours[range.end / 4];
        let id = 4 * whole_fours.end as u32;
        scalar(
            std::slice::from_ref(f),
            id,
            0..range.end % 4,
            whole,
            frac,
            view,
            out,
        );
    }
}

/// Appends to `ended` the ids of the walkers `range` whose piece ends at or before tick
/// `whole`, in order. `range` starts at a multiple of 4.
pub(super) fn ended(w: &Walkers, range: Range<usize>, whole: u32, ended: &mut Vec<u32>) {
    let fours = &w.fours[range.start / 4..range.end.div_ceil(4)];
    let (first_id, before) = (range.start as u32, ended.len());
    // SAFETY: SSE2 is part of every x86-64 processor.
    #[cfg(target_arch = "x86_64")]
    unsafe {
        sse2::ended(fours, first_id, whole, ended)
    };
    #[cfg(not(target_arch = "x86_64"))]
    scalar_ended(fours, first_id, whole, ended);
    // Lanes after the last walker never end (`Walkers`), but say so here too.
    while ended.len() > before && ended.last().is_some_and(|&id| id as usize >= range.end) {
        ended.pop();
    }
}

/// Lane `l`'s sample of four `f`, whose first walker is `first_id`.
#[inline(always)]
fn sample(f: &Four, first_id: u32, l: usize, whole: u32, frac: f32) -> Sample {
    // Whole ticks in i32 (a piece ends less than 2^31 ticks ahead), exact in f32.
    let dt = whole.wrapping_sub(f.end[l]) as i32 as f32 + frac;
    Sample {
        id: first_id + l as u32,
        x: f.x[l] + f.vx[l] * dt,
        y: f.y[l] + f.vy[l] * dt,
        heading: radians(f.heading[l]),
    }
}

#[inline(always)]
fn inside(s: &Sample, view: [f32; 4]) -> bool {
    s.x >= view[0] && s.x < view[2] && s.y >= view[1] && s.y < view[3]
}

/// Places lanes `lanes` of every four of `fours`, whose first walker is `first_id`.
fn scalar(
    fours: &[Four],
    first_id: u32,
    lanes: Range<usize>,
    whole: u32,
    frac: f32,
    view: [f32; 4],
    out: &mut Vec<Sample>,
) {
    for (k, f) in fours.iter().enumerate() {
        let id = first_id + 4 * k as u32;
        let samples = lanes.clone().map(|l| sample(f, id, l, whole, frac));
        out.extend(samples.filter(|s| inside(s, view)));
    }
}

#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn scalar_ended(fours: &[Four], first_id: u32, whole: u32, ended: &mut Vec<u32>) {
    for (k, f) in fours.iter().enumerate() {
        let id = first_id + 4 * k as u32;
        ended.extend((0..4).filter(|&l| whole >= f.end[l]).map(|l| id + l as u32));
    }
}

#[cfg(target_arch = "x86_64")]
mod sse2 {
    use super::{Four, Sample};
    use std::arch::x86_64::*;

    /// [`super::place`] for every walker of `fours`, whose first walker is `first_id`.
    #[target_feature(enable = "sse2")]
    pub fn place(
        fours: &[Four],
        first_id: u32,
        whole: u32,
        frac: f32,
        view: [f32; 4],
        out: &mut Vec<Sample>,
    ) {
        out.reserve(4 * fours.len());
        let start = out.len();
        let dst = out.spare_capacity_mut().as_mut_ptr().cast::<f32>();
        let mut kept = 0usize;
        // The intrinsics are safe to call in a function that enables SSE2; only the loads and
        // stores need care.
        let (whole, frac) = (_mm_set1_epi32(whole as i32), _mm_set1_ps(frac));
        let (x0, y0) = (_mm_set1_ps(view[0]), _mm_set1_ps(view[1]));
        let (x1, y1) = (_mm_set1_ps(view[2]), _mm_set1_ps(view[3]));
        let turn = _mm_set1_ps(std::f32::consts::TAU / 65536.0);
        let mut id = _mm_add_epi32(_mm_set1_epi32(first_id as i32), _mm_set_epi32(3, 2, 1, 0));
        for f in fours {
            // SAFETY: each field of `f` is 16 bytes (`heading`: 8).
            let (end, x, y, vx, vy, turns) = unsafe {
                (
                    _mm_loadu_si128(f.end.as_ptr().cast()),
                    _mm_loadu_ps(f.x.as_ptr()),
                    _mm_loadu_ps(f.y.as_ptr()),
                    _mm_loadu_ps(f.vx.as_ptr()),
                    _mm_loadu_ps(f.vy.as_ptr()),
                    _mm_loadl_epi64(f.heading.as_ptr().cast()),
                )
            };
            // Each heading twice in a 32-bit lane, shifted down with its sign: an i16 in i32.
            let turns = _mm_srai_epi32::<16>(_mm_unpacklo_epi16(turns, turns));

            let dt = _mm_add_ps(_mm_cvtepi32_ps(_mm_sub_epi32(whole, end)), frac);
            let x = _mm_add_ps(x, _mm_mul_ps(vx, dt));
            let y = _mm_add_ps(y, _mm_mul_ps(vy, dt));
            let heading = _mm_mul_ps(_mm_cvtepi32_ps(turns), turn);
            let ids = _mm_castsi128_ps(id);
            id = _mm_add_epi32(id, _mm_set1_epi32(4));

            let seen = _mm_and_ps(
                _mm_and_ps(_mm_cmpge_ps(x, x0), _mm_cmplt_ps(x, x1)),
                _mm_and_ps(_mm_cmpge_ps(y, y0), _mm_cmplt_ps(y, y1)),
            );
            let seen = _mm_movemask_ps(seen) as usize;

            let (a, b) = (_mm_unpacklo_ps(ids, x), _mm_unpacklo_ps(y, heading));
            let (c, d) = (_mm_unpackhi_ps(ids, x), _mm_unpackhi_ps(y, heading));
            let samples = [
                _mm_movelh_ps(a, b),
                _mm_movehl_ps(b, a),
                _mm_movelh_ps(c, d),
                _mm_movehl_ps(d, c),
            ];
            // SAFETY (both ways): after `n` fours, `kept <= 4 n`, so every store is within the
            // capacity reserved above; `Sample` is `repr(C)`, four 4-byte fields.
            if seen == 0b1111 {
                // All four in view, as every four is when the whole world is.
                for (lane, s) in samples.into_iter().enumerate() {
                    unsafe { _mm_storeu_ps(dst.add(4 * (kept + lane)), s) };
                }
                kept += 4;
            } else if seen != 0 {
                // Partly in view: every sample stored at the next free place, which moves on
                // only past those in view, with no branch per sample. (None in view: nothing.)
                for (lane, s) in samples.into_iter().enumerate() {
                    unsafe { _mm_storeu_ps(dst.add(4 * kept), s) };
                    kept += (seen >> lane) & 1;
                }
            }
        }
        // SAFETY: the first `kept` samples after `start` were written above.
        unsafe { out.set_len(start + kept) };
    }

    /// [`super::ended`] for every lane of `fours`, whose first walker is `first_id`.
    #[target_feature(enable = "sse2")]
    pub fn ended(fours: &[Four], first_id: u32, whole: u32, ended: &mut Vec<u32>) {
        // `whole >= end` unsigned, as signed after flipping both top bits.
        let top = _mm_set1_epi32(i32::MIN);
        let whole = _mm_xor_si128(_mm_set1_epi32(whole as i32), top);
        for (k, f) in fours.iter().enumerate() {
            // SAFETY: `f.end` is 16 bytes.
            let e = unsafe { _mm_loadu_si128(f.end.as_ptr().cast()) };
            let later = _mm_cmpgt_epi32(_mm_xor_si128(e, top), whole);
            let mut bits = !_mm_movemask_ps(_mm_castsi128_ps(later)) & 0xf;
            while bits != 0 {
                ended.push(first_id + (4 * k) as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::walker::Hot;
    use proptest::prelude::*;

    fn hot() -> impl Strategy<Value = Hot> {
        (
            any::<u32>(),
            -1e4f32..1e4,
            -1e4f32..1e4,
            -1e-3f32..1e-3,
            -1e-3f32..1e-3,
            any::<u16>(),
        )
            .prop_map(|(end, x, y, vx, vy, heading)| Hot {
                end,
                x,
                y,
                vx,
                vy,
                heading,
                ..Hot::default()
            })
    }

    fn walkers(hot: &[Hot]) -> Walkers {
        let mut w = Walkers::new(hot.len());
        for (i, h) in hot.iter().enumerate() {
            w.set(i, h);
        }
        w
    }

    proptest! {
        #[test]
        fn the_packed_and_the_scalar_placing_give_the_same_samples_bit_for_bit(
            hot in prop::collection::vec(hot(), 0..40),
            fours_skipped in 0usize..3,
            whole in any::<u32>(),
            frac in 0f32..1.0,
            view in (-2e4f32..2e4, -2e4f32..2e4, 0f32..3e4, 0f32..3e4),
        ) {
            let view = [view.0, view.1, view.0 + view.2, view.1 + view.3];
            let w = walkers(&hot);
            let range = (4 * fours_skipped).min(hot.len() / 4 * 4)..hot.len();
            let mut packed = vec![Sample::default(); 3];
            place(&w, range.clone(), whole, frac, view, &mut packed);
            let mut plain = vec![Sample::default(); 3];
            for i in range {
                let (f, l) = (&w.fours[i / 4], i % 4);
                let s = sample(f, (i - l) as u32, l, whole, frac);
                if inside(&s, view) {
                    plain.push(s);
                }
            }
            let bits = |s: &[Sample]| -> Vec<[u32; 4]> {
                let bits = |s: &Sample| [s.id, s.x.to_bits(), s.y.to_bits(), s.heading.to_bits()];
                s.iter().map(bits).collect()
            };
            prop_assert_eq!(bits(&packed), bits(&plain));
        }

        #[test]
        fn the_packed_and_the_scalar_search_find_the_same_ended_walkers(
            hot in prop::collection::vec(hot(), 0..40),
            whole in any::<u32>(),
        ) {
            let w = walkers(&hot);
            let (mut packed, mut plain) = (vec![7], vec![7]);
            ended(&w, 0..hot.len(), whole, &mut packed);
            scalar_ended(&w.fours, 0, whole, &mut plain);
            plain.retain(|&id| id == 7 || (id as usize) < hot.len());
            prop_assert_eq!(&packed, &plain);
            let expected: Vec<u32> = std::iter::once(7)
                .chain((0..hot.len() as u32).filter(|&i| whole >= hot[i as usize].end))
                .collect();
            prop_assert_eq!(packed, expected);
        }
    }
}
