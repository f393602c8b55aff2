//! Content hashes that tie every stage file to what it was built from.

use serde::{Deserialize, Serialize};
use std::fmt;

/// [`Hash::pieces`]: bytes hashed as they come, for a file too large to hold.
pub struct Pieces(blake3::Hasher);

impl Pieces {
    pub fn update(&mut self, bytes: &[u8]) {
        if bytes.len() < PARALLEL_BYTES {
            self.0.update(bytes);
        } else {
            self.0.update_rayon(bytes);
        }
    }

    /// The bytes hashed so far, and their hash.
    pub fn finish(&self) -> (u64, Hash) {
        (self.0.count(), Hash(*self.0.finalize().as_bytes()))
    }
}

/// Bytes from which [`Hash::of`] hashes on every core (blake3's `update_rayon` pays from
/// about 128 KiB).
const PARALLEL_BYTES: usize = 1 << 20;
/// The pieces [`Hash::of_file`] reads: long enough for every core, short enough to hold.
const FILE_PIECE_BYTES: usize = 8 << 20;

/// What tells a file apart from the one it was (the file itself, not its name: a rename in
/// place of it is another), where the system says: device, inode, length, and the times of its
/// last write and last change. `None` where it does not: such files are always read.
///
/// Files this process writes are forgotten before they are written ([`Hash::forget_file`]), so
/// a timestamp's granularity does not matter for them; a file another process rewrites in
/// place, to the same length, within the same tick while this one holds the build folder's
/// lock is not told apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileStamp([i64; 7]);

impl FileStamp {
    #[cfg(unix)]
    fn of(m: &std::fs::Metadata) -> Option<FileStamp> {
        use std::os::unix::fs::MetadataExt;
        Some(FileStamp([
            m.dev() as i64,
            m.ino() as i64,
            m.len() as i64,
            m.mtime(),
            m.mtime_nsec(),
            m.ctime(),
            m.ctime_nsec(),
        ]))
    }

    #[cfg(not(unix))]
    fn of(_: &std::fs::Metadata) -> Option<FileStamp> {
        None
    }
}

type FileHashes = std::collections::HashMap<std::path::PathBuf, (FileStamp, (u64, Hash))>;

/// The hashes [`Hash::of_file`] read in this process.
fn file_hashes() -> std::sync::MutexGuard<'static, FileHashes> {
    static HASHES: std::sync::OnceLock<std::sync::Mutex<FileHashes>> = std::sync::OnceLock::new();
    HASHES
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

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
    ///
    /// A file hashed before in this process, unchanged since, is not read again (a build's
    /// check and report read the 425 MB side file and the library two and three times):
    /// see [`FileStamp`].
    pub fn of_file(path: &std::path::Path) -> std::io::Result<(u64, Hash)> {
        let file = std::fs::File::open(path)?;
        let stamp = FileStamp::of(&file.metadata()?);
        let known = |stamp| {
            let cache = file_hashes();
            cache.get(path).filter(|k| k.0 == stamp).map(|k| k.1)
        };
        if let Some(found) = stamp.and_then(known) {
            return Ok(found);
        }
        let found = Self::read_file(file)?;
        if let Some(stamp) = stamp {
            file_hashes().insert(path.to_path_buf(), (stamp, found));
        }
        Ok(found)
    }

    /// Tells [`Hash::of_file`] that the file now at `path` hashes to `hash`: this process has
    /// just put it there and hashed its bytes before writing them.
    pub fn know_file(path: &std::path::Path, hash: Hash) {
        let Ok(m) = std::fs::metadata(path) else {
            return;
        };
        if let Some(stamp) = FileStamp::of(&m) {
            file_hashes().insert(path.to_path_buf(), (stamp, (m.len(), hash)));
        }
    }

    /// Forgets what [`Hash::of_file`] knows of `path`: this process is about to write it.
    pub fn forget_file(path: &std::path::Path) {
        file_hashes().remove(path);
    }

    fn read_file(mut file: std::fs::File) -> std::io::Result<(u64, Hash)> {
        use std::io::Read;
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

    /// A hash made a piece at a time: [`Hash::of`] of the pieces one after another.
    pub fn pieces() -> Pieces {
        Pieces(blake3::Hasher::new())
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
        self.file_hash(label, &Hash::of(bytes))
    }

    /// [`Hasher::file`] of a file whose bytes hash to `hash`: a build keeps its stage files'
    /// hashes, not their bytes (the million's `graph.ron` and `patterns.ron`, 75 MB, were held
    /// through every stage for its input hashes).
    pub fn file_hash(&mut self, label: &str, hash: &Hash) -> &mut Hasher {
        self.part(label, hash.to_string().as_bytes())
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

    /// A file hashed before and changed since, however it changed, is read again.
    #[test]
    fn a_file_changed_since_it_was_hashed_is_read_again() {
        let dir = tempfile::tempdir().unwrap();
        let (path, other) = (dir.path().join("a.bin"), dir.path().join("b.bin"));
        let of_file = || Hash::of_file(&path).unwrap();
        std::fs::write(&path, b"first").unwrap();
        assert_eq!(of_file(), (5, Hash::of(b"first")));
        assert_eq!(of_file(), (5, Hash::of(b"first")), "the same, known");
        // Written in place, to another length.
        std::fs::write(&path, b"second!").unwrap();
        assert_eq!(of_file(), (7, Hash::of(b"second!")));
        // Another file of the same length renamed in its place.
        std::fs::write(&other, b"third!!").unwrap();
        std::fs::rename(&other, &path).unwrap();
        assert_eq!(of_file(), (7, Hash::of(b"third!!")));
        // Written in place to the same length: its times of change tell it apart.
        std::thread::sleep(std::time::Duration::from_millis(20));
        std::fs::write(&path, b"fourth!").unwrap();
        assert_eq!(of_file(), (7, Hash::of(b"fourth!")));
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
