//! `regions.bin`: every region's result of the last build, by its hash, so that the next
//! build optimises again only the regions whose inputs changed ([`crate::optimize_reusing`]).
//!
//! A cache, not a stage file: nothing reads it but stage 3, and a damaged or foreign one is
//! only a missed reuse (every region is optimised again), never an error. Its bytes are the
//! same for the same build, whatever the thread count.

use crate::Known;
use crate::region::{Solved, Sums};
use crowd_core::Hash;
use crowd_core::patterns::{Measured, crossings_file_bytes, decode_crossings, write_crossings};
use glam::DVec2;

const MAGIC: &[u8; 8] = b"CRWDRGN1";

/// The bytes of `regions.bin` for these results.
pub fn encode(solved: &[Solved]) -> Vec<u8> {
    let mut out = Vec::new();
    write(&mut out, solved).expect("writing to memory");
    out
}

/// [`encode`]'s bytes written to `out` as they are made: the million's `regions.bin` is
/// 86 MB, held beside the world's crossings at stage 3's peak when it was encoded whole.
pub fn write<W: std::io::Write + ?Sized>(out: &mut W, solved: &[Solved]) -> std::io::Result<()> {
    let u32s = |v: usize| (v as u32).to_le_bytes();
    out.write_all(MAGIC)?;
    out.write_all(&u32s(solved.len()))?;
    for s in solved {
        out.write_all(s.hash.as_bytes())?;
        out.write_all(&u32s(s.iterations as usize))?;
        out.write_all(&[u8::from(s.converged)])?;
        out.write_all(&u32s(crossings_file_bytes(s.crossings.len())))?;
        write_crossings(out, &s.crossings)?;
        out.write_all(&u32s(s.measured.len()))?;
        for m in &s.measured {
            let d = m.direction.unwrap_or(DVec2::ZERO);
            for v in [m.density, d.x, d.y] {
                out.write_all(&v.to_le_bytes())?;
            }
            out.write_all(&[u8::from(m.direction.is_some())])?;
            out.write_all(&u32s(m.standers as usize))?;
        }
        out.write_all(&u32s(s.log.len()))?;
        for l in &s.log {
            out.write_all(&l.squares.to_le_bytes())?;
            out.write_all(&l.direction.to_le_bytes())?;
            for v in [l.patches, l.directed, l.crossings] {
                out.write_all(&v.to_le_bytes())?;
            }
        }
    }
    Ok(())
}

/// The results in `bytes`, or `None` if they are not a whole `regions.bin`.
pub fn decode(bytes: &[u8]) -> Option<Known> {
    let mut r = Reader(bytes);
    if r.take(8)? != MAGIC {
        return None;
    }
    let count = r.u32()?;
    let mut known = Known::new();
    for _ in 0..count {
        let hash = Hash::from_bytes(r.take(32)?.try_into().ok()?);
        let iterations = r.u32()? as u32;
        let converged = r.take(1)?[0] == 1;
        let len = r.u32()?;
        let crossings = decode_crossings(std::path::Path::new("regions.bin"), r.take(len)?).ok()?;
        let measured = (0..r.u32()?)
            .map(|_| {
                let (density, x, y) = (r.f64()?, r.f64()?, r.f64()?);
                let directed = r.take(1)?[0] == 1;
                Some(Measured {
                    density,
                    direction: directed.then_some(DVec2::new(x, y)),
                    standers: r.u32()? as u32,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let log = (0..r.u32()?)
            .map(|_| {
                Some(Sums {
                    squares: r.f64()?,
                    direction: r.f64()?,
                    patches: r.u64()?,
                    directed: r.u64()?,
                    crossings: r.u64()?,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let solved = Solved {
            hash,
            crossings,
            measured,
            log,
            iterations,
            converged,
        };
        known.insert(hash, solved);
    }
    r.0.is_empty().then_some(known)
}

struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (head, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(head)
    }
    fn u32(&mut self) -> Option<usize> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?) as usize)
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_round_trip_and_a_cut_file_is_no_cache() {
        let solved = vec![Solved {
            hash: Hash::of(b"region"),
            crossings: Vec::new(),
            measured: vec![Measured {
                density: 0.25,
                direction: Some(DVec2::new(0.6, 0.8)),
                standers: 3,
            }],
            log: vec![Sums {
                squares: 1.5,
                patches: 9,
                direction: 0.25,
                directed: 2,
                crossings: 40,
            }],
            iterations: 12,
            converged: true,
        }];
        let bytes = encode(&solved);
        let known = decode(&bytes).expect("whole");
        assert_eq!(known.get(&solved[0].hash), Some(&solved[0]));
        assert!(decode(&bytes[..bytes.len() - 1]).is_none());
        assert!(decode(b"not a cache").is_none());
    }
}
