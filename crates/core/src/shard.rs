//! Shards: one of `count` processes doing its part of the stages that split by patch
//! (`crowd build --shard I/N`), whose files `crowd build --gather` puts together into the
//! bytes one process would have written (DESIGN.md, "Beyond one machine").

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Shard `index` of `count` (`index < count`, `count >= 1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Shard {
    index: u32,
    count: u32,
}

impl Shard {
    /// Shard `index` of `count`; `None` unless `index < count`.
    pub fn new(index: u32, count: u32) -> Option<Shard> {
        (index < count).then_some(Shard { index, count })
    }

    pub fn index(self) -> u32 {
        self.index
    }

    pub fn count(self) -> u32 {
        self.count
    }

    /// Whether the item at `position` in a list dealt round the shards (the first to shard 0,
    /// the next to shard 1, ...) is this shard's. Dealt from a list sorted costliest first,
    /// every shard gets a like share of the work.
    pub fn deals(self, position: usize) -> bool {
        position % self.count as usize == self.index as usize
    }

    /// The name its files carry: `2-of-8` (0-based, as `--shard 2/8` says).
    pub fn tag(self) -> String {
        format!("{}-of-{}", self.index, self.count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    /// `I/N`: shard I (counted from 0) of N.
    fn from_str(s: &str) -> Result<Shard, String> {
        let wrong = || format!("expected I/N with 0 <= I < N (as in 0/4 ... 3/4), not {s:?}");
        let (i, n) = s.split_once('/').ok_or_else(wrong)?;
        let (i, n) = (i.trim().parse::<u32>(), n.trim().parse::<u32>());
        match (i, n) {
            (Ok(i), Ok(n)) => Shard::new(i, n).ok_or_else(wrong),
            _ => Err(wrong()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_read_as_written_and_refuse_what_is_not_one() {
        let s: Shard = "2/8".parse().unwrap();
        assert_eq!(
            (s.index(), s.count(), s.to_string()),
            (2, 8, "2/8".to_string())
        );
        assert_eq!(s.tag(), "2-of-8");
        for bad in ["8/8", "1/0", "-1/4", "a/4", "3", "1/4/2", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn every_position_is_dealt_to_exactly_one_shard() {
        for count in 1..6 {
            for position in 0..40 {
                let owners = (0..count)
                    .filter(|&i| Shard::new(i, count).unwrap().deals(position))
                    .count();
                assert_eq!(owners, 1);
            }
        }
    }
}
