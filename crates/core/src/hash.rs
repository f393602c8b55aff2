//! Content hashes that tie every stage file to what it was built from.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Bytes from which [`Hash::of`] hashes on every core (blake3's `update_rayon` pays from
/// about 128 KiB).
const PARALLEL_BYTES: usize = 1 << 20;
/// The pieces [`Hash::of_file`] reads: long enough for every core, short enough to hold.
const FILE_PIECE_BYTES: usize = 8 << 20;

/// A BLAKE3 hash, written as 64 hex digits in stage files.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Hash([u8; 32]);

impl Hash {
    /// Hash of a byte string: on every core when it is long (the same hash; painting's
    /// 426 MB side file took 0.12 s on one).
    pub fn of(bytes: &[u8]) -> Hash {
        if bytes.len() < PARALLEL_BYTES {
            return Hash(*blake3::hash(bytes).as_bytes());
        }
        let mut hasher = blake3::Hasher::new();
        hasher.update_rayon(bytes);
        Hash(*hasher.finalize().as_bytes())
    }

    /// Hash and length of a file's bytes, read in pieces (a 400 MB side file is checked
    /// without holding it), each hashed on every core.
    pub fn of_file(path: &std::path::Path) -> std::io::Result<(u64, Hash)> {
        use std::io::Read;
        let mut file = std::fs::File::open(path)?;
        let mut hasher = blake3::Hasher::new();
        // No larger than the file (most hashed files are a few kilobytes of RON).
        let len = file.metadata().map_or(FILE_PIECE_BYTES as u64, |m| m.len());
        let mut piece = vec![0u8; (len as usize).clamp(1, FILE_PIECE_BYTES)];
        loop {
            let n = match file.read(&mut piece) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if n < PARALLEL_BYTES {
                hasher.update(&piece[..n]);
            } else {
                hasher.update_rayon(&piece[..n]);
            }
        }
        Ok((hasher.count(), Hash(*hasher.finalize().as_bytes())))
    }

    /// The 32 bytes.
    pub fn as_bytes(&self) -> &[u8; 32] {
        &self.0
    }

    /// The hash whose bytes these are (as [`Hash::as_bytes`] gave them).
    pub fn from_bytes(bytes: [u8; 32]) -> Hash {
        Hash(bytes)
    }

    /// The first 16 hex digits, for messages.
    pub fn short(&self) -> String {
        self.to_string()[..16].to_string()
    }

    fn from_hex(text: &str) -> Option<Hash> {
        if text.len() != 64 {
            return None;
        }
        let mut out = [0u8; 32];
        for (i, byte) in out.iter_mut().enumerate() {
            *byte = u8::from_str_radix(text.get(2 * i..2 * i + 2)?, 16).ok()?;
        }
        Some(Hash(out))
    }
}

impl fmt::Display for Hash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for byte in self.0 {
            write!(f, "{byte:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for Hash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Hash({})", self.short())
    }
}

impl Serialize for Hash {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> Deserialize<'de> for Hash {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Hash, D::Error> {
        let text = String::deserialize(d)?;
        Hash::from_hex(&text)
            .ok_or_else(|| serde::de::Error::custom("expected a hash of 64 hex digits"))
    }
}

/// Builds the input hash of a stage from labelled parts, so that two different inputs can never
/// be confused by concatenation.
pub struct Hasher(blake3::Hasher);

impl Hasher {
    /// A hasher for the stage `stage` at format `version`.
    pub fn new(stage: &str, version: u32) -> Hasher {
        let mut h = Hasher(blake3::Hasher::new());
        h.part("stage", stage.as_bytes());
        h.part("version", &version.to_le_bytes());
        h
    }

    /// Adds a labelled part.
    pub fn part(&mut self, label: &str, bytes: &[u8]) -> &mut Hasher {
        for piece in [label.as_bytes(), bytes] {
            self.0.update(&(piece.len() as u64).to_le_bytes());
            self.0.update(piece);
        }
        self
    }

    /// Adds an input file by the hash of its bytes.
    pub fn file(&mut self, label: &str, bytes: &[u8]) -> &mut Hasher {
        let hash = Hash::of(bytes).to_string();
        self.part(label, hash.as_bytes())
    }

    /// Adds a labelled value through its RON text (settings structs).
    pub fn value<T: Serialize>(&mut self, label: &str, value: &T) -> &mut Hasher {
        let text = ron::to_string(value).expect("settings always serialise to RON");
        self.part(label, text.as_bytes())
    }

    /// Adds a labelled value through its CBOR bytes (`ciborium`), for values hashed many times
    /// over: RON text of every patch's surroundings was a tenth of a rebuild's time (its
    /// floats' shortest decimal forms), CBOR writes their bits.
    pub fn binary<T: Serialize>(&mut self, label: &str, value: &T) -> &mut Hasher {
        let mut bytes = Vec::new();
        ciborium::into_writer(value, &mut bytes).expect("values always serialise to CBOR");
        self.part(label, &bytes)
    }

    pub fn finish(&self) -> Hash {
        Hash(*self.0.finalize().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On every core or on one, in pieces or whole: the same hash.
    #[test]
    fn a_long_input_hashes_the_same_on_every_core_and_from_its_file() {
        let bytes: Vec<u8> = (0..FILE_PIECE_BYTES + 3 * PARALLEL_BYTES + 12_345)
            .map(|i| (i * 7 + i / 4099) as u8)
            .collect();
        let one = Hash(*blake3::hash(&bytes).as_bytes());
        assert_eq!(Hash::of(&bytes), one);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("long.bin");
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(Hash::of_file(&path).unwrap(), (bytes.len() as u64, one));
    }

    #[test]
    fn hex_round_trips() {
        let h = Hash::of(b"crowd");
        assert_eq!(Hash::from_hex(&h.to_string()), Some(h));
        assert_eq!(Hash::from_hex("zz"), None);
    }

    #[test]
    fn parts_are_not_confused_by_concatenation() {
        let a = Hasher::new("s", 1)
            .part("x", b"ab")
            .part("y", b"c")
            .finish();
        let b = Hasher::new("s", 1)
            .part("x", b"a")
            .part("y", b"bc")
            .finish();
        assert_ne!(a, b);
    }
}
