//! Placing a block of walkers: each one's position at the frame's time and its heading,
//! appended to the frame's samples if it is in view.
//!
//! This is a frame's largest part: every walker, every frame. The compiler leaves the loop
//! scalar (it will not interleave four columns into 16-byte samples on baseline x86-64), so on
//! x86-64 it is written with SSE2, four walkers at once: two 4 x 4 transposes gather their
//! records into columns, the arithmetic is packed, a third transpose makes the samples, and a
//! mask keeps those in view without a branch. The scalar loop is the same arithmetic,
//! operation for operation, so both give the same bits (a test holds them to it).

use super::Sample;
use super::walker::{Hot, radians};

/// Appends the walkers of `hot` (ids from `first_id`) inside `view`, placed `whole` ticks and
/// `frac` of a tick after the epoch.
pub(super) fn place(
    hot: &[Hot],
    first_id: u32,
    whole: u32,
    frac: f32,
    view: [f32; 4],
    out: &mut Vec<Sample>,
) {
    // SAFETY: SSE2 is part of every x86-64 processor.
    #[cfg(target_arch = "x86_64")]
    let done = unsafe { sse2::place(hot, first_id, whole, frac, view, out) };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    scalar(&hot[done..], first_id + done as u32, whole, frac, view, out);
}

/// One walker's sample.
#[inline(always)]
fn sample(h: &Hot, id: u32, whole: u32, frac: f32) -> Sample {
    // Whole ticks in i32 (a piece ends less than 2^31 ticks ahead), exact in f32.
    let dt = whole.wrapping_sub(h.end) as i32 as f32 + frac;
    Sample {
        id,
        x: h.x + h.vx * dt,
        y: h.y + h.vy * dt,
        heading: radians(h.heading),
    }
}

#[inline(always)]
fn inside(s: &Sample, view: [f32; 4]) -> bool {
    s.x >= view[0] && s.x < view[2] && s.y >= view[1] && s.y < view[3]
}

fn scalar(
    hot: &[Hot],
    first_id: u32,
    whole: u32,
    frac: f32,
    view: [f32; 4],
    out: &mut Vec<Sample>,
) {
    let samples = hot
        .iter()
        .zip(first_id..)
        .map(|(h, id)| sample(h, id, whole, frac));
    out.extend(samples.filter(|s| inside(s, view)));
}

#[cfg(target_arch = "x86_64")]
mod sse2 {
    use super::{Hot, Sample};
    use std::arch::x86_64::*;

    /// [`super::place`] for the walkers of `hot` in whole fours; returns how many it placed.
    #[target_feature(enable = "sse2")]
    pub fn place(
        hot: &[Hot],
        first_id: u32,
        whole: u32,
        frac: f32,
        view: [f32; 4],
        out: &mut Vec<Sample>,
    ) -> usize {
        let fours = hot.len() / 4;
        out.reserve(fours * 4);
        let start = out.len();
        let dst = out.spare_capacity_mut().as_mut_ptr().cast::<f32>();
        let mut kept = 0usize;
        // The intrinsics are safe to call in a function that enables SSE2; only the loads and
        // stores need care.
        let (whole, frac) = (_mm_set1_epi32(whole as i32), _mm_set1_ps(frac));
        let (x0, y0) = (_mm_set1_ps(view[0]), _mm_set1_ps(view[1]));
        let (x1, y1) = (_mm_set1_ps(view[2]), _mm_set1_ps(view[3]));
        let turn = _mm_set1_ps(std::f32::consts::TAU / 65536.0);
        let lanes = _mm_set_epi32(3, 2, 1, 0);
        for (k, four) in hot.chunks_exact(4).enumerate() {
            // Each record as two 16-byte halves: [end, at, x, y] and [vx, vy, heading and
            // left, col and row] (`Hot` is `repr(C)`, 32 bytes).
            let half = |i: usize, h: usize| {
                let p = std::ptr::from_ref(&four[i]).cast::<f32>();
                // SAFETY: `four[i]` is a 32-byte `Hot`; this reads its bytes 16 h .. 16 h + 16.
                unsafe { _mm_loadu_ps(p.add(4 * h)) }
            };
            let (a, b) = (
                _mm_unpacklo_ps(half(0, 0), half(1, 0)),
                _mm_unpacklo_ps(half(2, 0), half(3, 0)),
            );
            let end = _mm_castps_si128(_mm_movelh_ps(a, b));
            let (a, b) = (
                _mm_unpackhi_ps(half(0, 0), half(1, 0)),
                _mm_unpackhi_ps(half(2, 0), half(3, 0)),
            );
            let (x, y) = (_mm_movelh_ps(a, b), _mm_movehl_ps(b, a));
            let (a, b) = (
                _mm_unpacklo_ps(half(0, 1), half(1, 1)),
                _mm_unpacklo_ps(half(2, 1), half(3, 1)),
            );
            let (vx, vy) = (_mm_movelh_ps(a, b), _mm_movehl_ps(b, a));
            let (a, b) = (
                _mm_unpackhi_ps(half(0, 1), half(1, 1)),
                _mm_unpackhi_ps(half(2, 1), half(3, 1)),
            );
            // The low 16 bits, sign-extended: the heading as an i16.
            let turns =
                _mm_srai_epi32::<16>(_mm_slli_epi32::<16>(_mm_castps_si128(_mm_movelh_ps(a, b))));

            let dt = _mm_add_ps(_mm_cvtepi32_ps(_mm_sub_epi32(whole, end)), frac);
            let x = _mm_add_ps(x, _mm_mul_ps(vx, dt));
            let y = _mm_add_ps(y, _mm_mul_ps(vy, dt));
            let heading = _mm_mul_ps(_mm_cvtepi32_ps(turns), turn);
            let id = _mm_add_epi32(_mm_set1_epi32((first_id as usize + 4 * k) as i32), lanes);
            let id = _mm_castsi128_ps(id);

            let seen = _mm_and_ps(
                _mm_and_ps(_mm_cmpge_ps(x, x0), _mm_cmplt_ps(x, x1)),
                _mm_and_ps(_mm_cmpge_ps(y, y0), _mm_cmplt_ps(y, y1)),
            );
            let seen = _mm_movemask_ps(seen) as usize;

            let (a, b) = (_mm_unpacklo_ps(id, x), _mm_unpacklo_ps(y, heading));
            let (c, d) = (_mm_unpackhi_ps(id, x), _mm_unpackhi_ps(y, heading));
            let samples = [
                _mm_movelh_ps(a, b),
                _mm_movehl_ps(b, a),
                _mm_movelh_ps(c, d),
                _mm_movehl_ps(d, c),
            ];
            // Every sample is stored at the next free place, which moves on only past those
            // in view: no branch, whatever the view.
            for (lane, s) in samples.into_iter().enumerate() {
                // SAFETY: `kept <= 4 k + lane < 4 fours`, within the capacity reserved above;
                // `Sample` is `repr(C)`, four 4-byte fields.
                unsafe { _mm_storeu_ps(dst.add(4 * kept), s) };
                kept += (seen >> lane) & 1;
            }
        }
        // SAFETY: the first `kept` samples after `start` were written above.
        unsafe { out.set_len(start + kept) };
        fours * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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

    proptest! {
        #[test]
        fn the_packed_and_the_scalar_placing_give_the_same_samples_bit_for_bit(
            hot in prop::collection::vec(hot(), 0..40),
            first_id in 0u32..1 << 30,
            whole in any::<u32>(),
            frac in 0f32..1.0,
            view in (-2e4f32..2e4, -2e4f32..2e4, 0f32..3e4, 0f32..3e4),
        ) {
            let view = [view.0, view.1, view.0 + view.2, view.1 + view.3];
            let mut packed = vec![Sample::default(); 3];
            place(&hot, first_id, whole, frac, view, &mut packed);
            let mut plain = vec![Sample::default(); 3];
            scalar(&hot, first_id, whole, frac, view, &mut plain);
            let bits = |s: &[Sample]| -> Vec<[u32; 4]> {
                s.iter().map(|s| [s.id, s.x.to_bits(), s.y.to_bits(), s.heading.to_bits()]).collect()
            };
            prop_assert_eq!(bits(&packed), bits(&plain));
        }
    }
}
