//! The rules every stage file follows.
//!
//! - RON, so a person can read it; bulky arrays go to a binary side file that the RON names with
//!   its size and hash.
//! - A [`Header`] with the stage kind, its format version and the hash of everything the file was
//!   built from, so the build driver reruns only stale stages.
//! - Written to a temporary name in the same folder and renamed, so an interrupted build never
//!   leaves a half-written file where a good one was.

use crate::error::{Error, LineCol, Result};
use crate::hash::Hash;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The first field of every stage file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// Which stage wrote the file (`"merge"`, `"graph"`, ...).
    pub stage: String,
    /// The stage's format version; a file of another version is rebuilt, never misread.
    pub version: u32,
    /// Hash of the stage's inputs and settings.
    pub input_hash: Hash,
}

impl Header {
    pub fn new(stage: &str, version: u32, input_hash: Hash) -> Header {
        Header {
            stage: stage.to_string(),
            version,
            input_hash,
        }
    }
}

/// Fills `buf` from `file` at `offset`, from any thread (no shared cursor).
#[cfg(unix)]
pub fn read_at(file: &std::fs::File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(windows)]
pub fn read_at(file: &std::fs::File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    while !buf.is_empty() {
        match std::os::windows::fs::FileExt::seek_read(file, buf, offset)? {
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            n => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
        }
    }
    Ok(())
}

/// The bytes of a file (a stage file whose bytes the next stage's input hash covers).
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io(path, "read", e))
}

/// A side file's bytes mapped into memory ([`SideFile::map`]).
pub struct Mapped(memmap2::Mmap);

impl std::ops::Deref for Mapped {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.0
    }
}

/// A binary side file, named by the RON file that owns it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SideFile {
    /// File name, in the folder of the RON file.
    pub file: String,
    pub bytes: u64,
    pub hash: Hash,
}

impl SideFile {
    /// The side file of `owner` (the same name with `.bin`) holding `bytes`: its path and the
    /// record that names it.
    pub fn beside(owner: &Path, bytes: &[u8]) -> (std::path::PathBuf, SideFile) {
        let path = owner.with_extension("bin");
        let file = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let record = SideFile {
            file,
            bytes: bytes.len() as u64,
            hash: Hash::of(bytes),
        };
        (path, record)
    }

    /// The record of a side file streamed to disk beside its owner (`file`'s path is the
    /// owner's with `.bin`, as [`SideFile::beside`] names it).
    pub fn streamed(file: &StreamedFile) -> SideFile {
        SideFile {
            file: (file.path.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            bytes: file.bytes,
            hash: file.hash,
        }
    }

    /// Whether the side file next to `owner` is the one this record names (its size, then
    /// its hash), without keeping its bytes.
    pub fn holds(&self, owner: &Path) -> bool {
        let path = owner.with_file_name(&self.file);
        std::fs::metadata(&path).is_ok_and(|m| m.len() == self.bytes)
            && Hash::of_file(&path).is_ok_and(|found| found == (self.bytes, self.hash))
    }

    /// Reads the side file next to `owner` and checks its size and hash.
    pub fn read(&self, owner: &Path) -> Result<Vec<u8>> {
        let path = owner.with_file_name(&self.file);
        let bytes = read_bytes(&path)?;
        self.expect(owner, &path, (bytes.len() as u64, Hash::of(&bytes)))?;
        Ok(bytes)
    }

    /// The side file next to `owner` mapped into memory, its size and hash checked as
    /// [`SideFile::read`] checks them: read from the page cache where it is, never copied.
    /// The last build's side files, which a rebuild takes its unchanged patches from: read
    /// into fresh memory, painting's 425 MB stage 6 file took 0.22-0.52 s of a core; mapped,
    /// a few milliseconds. A build replaces a file by renaming a new one over it and never
    /// writes one in place, so the bytes mapped stay the ones checked while the map lives.
    pub fn map(&self, owner: &Path) -> Result<Mapped> {
        let path = owner.with_file_name(&self.file);
        let file = std::fs::File::open(&path).map_err(|e| Error::io(&path, "read", e))?;
        // SAFETY: the map is read only, and its bytes change only if another program writes
        // the file in place meanwhile (no build does, see above), as with any mapped file.
        let map = unsafe { memmap2::MmapOptions::new().populate().map(&file) };
        let map = map.map_err(|e| Error::io(&path, "read", e))?;
        self.expect(owner, &path, (map.len() as u64, Hash::of(&map)))?;
        Ok(Mapped(map))
    }

    /// Checks the size and hash of the side file next to `owner` as [`SideFile::read`] does,
    /// reading it through without keeping its bytes; its path.
    pub fn check(&self, owner: &Path) -> Result<std::path::PathBuf> {
        let path = owner.with_file_name(&self.file);
        let found = Hash::of_file(&path).map_err(|e| Error::io(&path, "read", e))?;
        self.expect(owner, &path, found)?;
        Ok(path)
    }

    /// Refuses a side file at `path` of `found` size and hash other than this record's.
    fn expect(&self, owner: &Path, path: &Path, found: (u64, Hash)) -> Result<()> {
        if found == (self.bytes, self.hash) {
            return Ok(());
        }
        Err(Error::stage_file(
            path,
            format!(
                "is {} bytes with hash {}, but {} expects {} bytes with hash {}; \
                 the build was interrupted or the file was changed: build again",
                found.0,
                found.1.short(),
                owner.display(),
                self.bytes,
                self.hash.short()
            ),
        ))
    }
}

/// Encoded stage files not yet written, in the order they are to be written (a side file
/// before the RON file that names it).
pub type Writes = Vec<(std::path::PathBuf, Vec<u8>)>;

/// Writes every file of `writes` atomically, in order.
pub fn write_all(writes: &[(std::path::PathBuf, Vec<u8>)]) -> Result<()> {
    for (path, bytes) in writes {
        write_atomic(path, bytes)?;
    }
    Ok(())
}

/// Writes `pieces`, one after another, to a new file at `path` and waits until they are on
/// disk, as a file must be before it is renamed over another: else a crash may leave the new
/// name with no bytes, and ext4 flushes it in the rename itself (painting's 425 MB side file:
/// 0.23 s of a stroke's rebuild, on the build's critical path rather than on the writer's
/// thread).
fn write_durably(path: &Path, pieces: &[Vec<u8>]) -> std::io::Result<()> {
    use std::io::Write;
    let mut file = std::fs::File::create(path)?;
    for bytes in pieces {
        file.write_all(bytes)?;
    }
    file.sync_data()
}

/// [`write_durably`] of what `write` writes, through a buffer.
fn write_durably_with(
    path: &Path,
    write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut file = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(path)?);
    write(&mut file)?;
    file.into_inner().map_err(|e| e.into_error())?.sync_data()
}

/// The temporary file [`write_atomic`] writes `path` through: hidden, in the same folder, named
/// with this process's id (so that [`FolderLock::acquire`] knows it for a killed build's).
fn temporary(path: &Path) -> std::path::PathBuf {
    hidden_beside(path, "tmp")
}

/// The second name a replaced file keeps until [`retire`] removes it: a temporary name of this
/// process's, so that a killed build's are cleared by the next [`FolderLock::acquire`].
fn retired_name(path: &Path) -> std::path::PathBuf {
    hidden_beside(path, "old.tmp")
}

/// `.NAME.{kind}PID` beside `path` (NAME its file name, PID this process's id).
fn hidden_beside(path: &Path, kind: &str) -> std::path::PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{kind}{}", std::process::id()))
}

/// Renames `tmp` over `path`. The file it replaces, if there was one, keeps a second name
/// ([`retired_name`]), returned for [`retire`] to remove.
fn replace(tmp: &Path, path: &Path) -> (Option<std::path::PathBuf>, std::io::Result<()>) {
    let old = retired_name(path);
    let kept = std::fs::hard_link(path, &old).is_ok().then_some(old);
    crate::Hash::forget_file(path);
    (kept, std::fs::rename(tmp, path))
}

/// Files written to their temporary names on a thread of their own while a build goes on, and
/// put in place only by [`Staging::commit`], in the order they came: a build's outputs change
/// all at once or not at all, as with [`write_all`] at its end, but the writing (painting's
/// 600 MB, two seconds of copying) runs beside the stages after the one that made them.
/// Dropped without a commit, it removes what it wrote.
pub struct Staging {
    sender: Option<std::sync::mpsc::Sender<Staged>>,
    writer: Option<std::thread::JoinHandle<Written>>,
    /// Hashes known of files staged ([`Staging::know`]).
    known: Vec<(std::path::PathBuf, crate::Hash)>,
}

/// Bytes a [`Staging`] writer writes: its own, or pieces shared with the build, written one
/// after another.
enum Shared {
    Own(Vec<u8>),
    Pieces(std::sync::Arc<Vec<Vec<u8>>>),
}

impl Shared {
    fn pieces(&self) -> &[Vec<u8>] {
        match self {
            Shared::Own(bytes) => std::slice::from_ref(bytes),
            Shared::Pieces(pieces) => pieces,
        }
    }
}

/// What a [`Staging`] writer wrote: (temporary, final) paths in order, and the first failure.
type Written = (Vec<(std::path::PathBuf, std::path::PathBuf)>, Option<Error>);

/// What a [`Staging`] writer is given, in order: bytes to write to a file, or a file
/// [`Streamed`] to its temporary name already (temporary, final).
enum Staged {
    Bytes(std::path::PathBuf, Vec<u8>),
    /// Pieces of a file, one after another, that the build reads on meanwhile (stage 6's side
    /// file, which export thins).
    Shared(std::path::PathBuf, std::sync::Arc<Vec<Vec<u8>>>),
    Streamed(std::path::PathBuf, std::path::PathBuf),
}

impl Staging {
    pub fn new() -> Staging {
        let (sender, receiver) = std::sync::mpsc::channel::<Staged>();
        let writer = std::thread::spawn(move || {
            let mut written = Vec::new();
            let mut failed = None;
            for staged in receiver {
                let (path, bytes) = match staged {
                    Staged::Streamed(tmp, path) if failed.is_none() => {
                        written.push((tmp, path));
                        continue;
                    }
                    Staged::Streamed(tmp, _) => {
                        let _ = std::fs::remove_file(tmp);
                        continue;
                    }
                    Staged::Bytes(path, bytes) => (path, Shared::Own(bytes)),
                    Staged::Shared(path, pieces) => (path, Shared::Pieces(pieces)),
                };
                if failed.is_some() {
                    continue; // the build fails at its commit; nothing more is written
                }
                let tmp = temporary(&path);
                match write_durably(&tmp, bytes.pieces()) {
                    Ok(()) => written.push((tmp, path)),
                    Err(e) => {
                        let _ = std::fs::remove_file(&tmp);
                        failed = Some(Error::io(&path, "write", e));
                    }
                }
            }
            (written, failed)
        });
        Staging {
            sender: Some(sender),
            writer: Some(writer),
            known: Vec::new(),
        }
    }

    /// Queues `writes` (in order) to be written now and put in place at the commit.
    pub fn stage(&mut self, writes: Writes) {
        let sender = self.sender.as_ref().expect("staging before its commit");
        for (path, bytes) in writes {
            // The writer ends only when the sender is dropped: it is there to receive.
            let _ = sender.send(Staged::Bytes(path, bytes));
        }
    }

    /// Queues `pieces` to be written now, one after another, as `path` and put in place at
    /// the commit, read by the build meanwhile.
    pub fn stage_shared(&mut self, path: std::path::PathBuf, pieces: std::sync::Arc<Vec<Vec<u8>>>) {
        let sender = self.sender.as_ref().expect("staging before its commit");
        let _ = sender.send(Staged::Shared(path, pieces));
    }

    /// Queues a file written already to its temporary name, to be put in place at the commit
    /// (after the files queued before it).
    pub fn stage_streamed(&mut self, mut file: StreamedFile) {
        let sender = self.sender.as_ref().expect("staging before its commit");
        let tmp = file.tmp.take().expect("a streamed file is staged once");
        let _ = sender.send(Staged::Streamed(tmp, file.path.clone()));
    }

    /// Says that the file staged for `path` hashes to `hash`: once it is in place,
    /// [`crate::Hash::of_file`] knows it without reading it.
    pub fn know(&mut self, path: std::path::PathBuf, hash: crate::Hash) {
        self.known.push((path, hash));
    }

    /// Waits for the writing, then renames every file into place in order. On any failure the
    /// files not yet in place are removed and the first failure returned.
    pub fn commit(mut self) -> Result<()> {
        let (written, failed) = self.finish();
        if let Some(e) = failed {
            remove_all(&written);
            return Err(e);
        }
        let mut retired = Vec::new();
        for (k, (tmp, path)) in written.iter().enumerate() {
            let (old, renamed) = replace(tmp, path);
            retired.extend(old);
            if let Err(e) = renamed {
                remove_all(&written[k..]);
                remove_retired(retired);
                return Err(Error::io(path, "write", e));
            }
        }
        retire(retired);
        for (path, hash) in std::mem::take(&mut self.known) {
            if written.iter().any(|(_, p)| *p == path) {
                crate::Hash::know_file(&path, hash);
            }
        }
        Ok(())
    }

    fn finish(&mut self) -> Written {
        self.sender = None;
        match self.writer.take().map(std::thread::JoinHandle::join) {
            Some(Ok(written)) => written,
            Some(Err(panic)) => std::panic::resume_unwind(panic),
            None => (Vec::new(), None),
        }
    }
}

impl Default for Staging {
    fn default() -> Self {
        Staging::new()
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if self.writer.is_some() {
            let (written, _) = self.finish();
            remove_all(&written);
        }
    }
}

/// The removals of replaced files still running; [`wait_for_retired`] waits for them.
static RETIRING: std::sync::Mutex<Vec<std::thread::JoinHandle<()>>> =
    std::sync::Mutex::new(Vec::new());

/// Removes the files a commit replaced on a thread of its own. Dropping a file's last name
/// frees its cached pages in the call: painting's 425 MB side file and the rest it replaced
/// held a stroke's rebuild for 0.37 s before its check could start.
fn retire(paths: Vec<std::path::PathBuf>) {
    if paths.is_empty() {
        return;
    }
    let here = paths.clone();
    match std::thread::Builder::new().spawn(move || remove_retired(paths)) {
        Ok(handle) => RETIRING
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(handle),
        // No thread to spare: removed here and now.
        Err(_) => remove_retired(here),
    }
}

fn remove_retired(paths: Vec<std::path::PathBuf>) {
    for path in paths {
        let _ = std::fs::remove_file(path);
    }
}

/// Waits until the files every commit replaced are removed: a process that committed calls it
/// before it ends, so that none is left behind.
pub fn wait_for_retired() {
    let handles = std::mem::take(
        &mut *RETIRING
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner),
    );
    for handle in handles {
        let _ = handle.join();
    }
}

fn remove_all(written: &[(std::path::PathBuf, std::path::PathBuf)]) {
    for (tmp, _) in written {
        let _ = std::fs::remove_file(tmp);
    }
}

/// A file written a piece at a time to its temporary name, hashed as it goes, for a file too
/// large to hold (a gathering build's side file: the million's is 4.2 GB), then put in place
/// by a [`Staging`] commit like any staged file. Dropped unfinished, it removes what it wrote.
pub struct Streamed {
    path: std::path::PathBuf,
    tmp: std::path::PathBuf,
    file: Option<std::io::BufWriter<std::fs::File>>,
    hash: crate::hash::Pieces,
}

impl Streamed {
    /// Starts the file that will be `path`.
    pub fn create(path: &Path) -> Result<Streamed> {
        let tmp = temporary(path);
        crate::Hash::forget_file(path);
        let file = std::fs::File::create(&tmp).map_err(|e| Error::io(path, "write", e))?;
        Ok(Streamed {
            path: path.to_path_buf(),
            tmp,
            file: Some(std::io::BufWriter::with_capacity(1 << 20, file)),
            hash: crate::Hash::pieces(),
        })
    }

    /// The file `path` will be, written by `write` to its temporary name and finished: through
    /// a buffer, so that a writer of small records (stage 3's crossings, 37 bytes each) hashes
    /// large pieces, not a record at a time.
    pub fn written_by(
        path: &Path,
        write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    ) -> Result<StreamedFile> {
        let mut file = Streamed::create(path)?;
        let mut buffered = std::io::BufWriter::with_capacity(1 << 16, &mut file);
        write(&mut buffered)
            .and_then(|()| std::io::Write::flush(&mut buffered))
            .map_err(|e| Error::io(path, "write", e))?;
        drop(buffered);
        file.finish()
    }

    pub fn write(&mut self, bytes: &[u8]) -> Result<()> {
        use std::io::Write;
        self.hash.update(bytes);
        let file = self.file.as_mut().expect("writing before finishing");
        file.write_all(bytes)
            .map_err(|e| Error::io(&self.path, "write", e))
    }

    /// The file written and on disk, as a file must be before it is renamed over another.
    pub fn finish(mut self) -> Result<StreamedFile> {
        let file = self.file.take().expect("finished once");
        let (bytes, hash) = self.hash.finish();
        let synced = file
            .into_inner()
            .map_err(|e| e.into_error())
            .and_then(|f| f.sync_data());
        let tmp = std::mem::take(&mut self.tmp);
        if let Err(e) = synced {
            let _ = std::fs::remove_file(&tmp);
            return Err(Error::io(&self.path, "write", e));
        }
        Ok(StreamedFile {
            path: std::mem::take(&mut self.path),
            tmp: Some(tmp),
            bytes,
            hash,
        })
    }
}

/// A memo or report written a piece at a time by code that writes to any `std::io::Write`.
impl std::io::Write for Streamed {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.hash.update(bytes);
        let file = self.file.as_mut().expect("writing before finishing");
        std::io::Write::write_all(file, bytes)?;
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.as_mut().map_or(Ok(()), std::io::Write::flush)
    }
}

impl Drop for Streamed {
    fn drop(&mut self) {
        if self.file.is_some() {
            self.file = None;
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// A [`Streamed`] file, finished: its size and hash. Dropped before it is staged
/// ([`Staging::stage_streamed`]), it removes its temporary file.
pub struct StreamedFile {
    pub path: std::path::PathBuf,
    tmp: Option<std::path::PathBuf>,
    pub bytes: u64,
    pub hash: crate::Hash,
}

impl StreamedFile {
    /// Where its bytes are now: at the temporary name until the build puts it in place.
    pub fn on_disk(&self) -> &Path {
        self.tmp.as_deref().unwrap_or(&self.path)
    }

    /// Puts it in place now, renamed over `path` (a file written outside a build's
    /// [`Staging`]: `crowd check`'s memo).
    pub fn put_in_place(mut self) -> Result<()> {
        let tmp = self.tmp.take().expect("put in place once");
        let (old, renamed) = replace(&tmp, &self.path);
        retire(old.into_iter().collect());
        renamed.map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::io(&self.path, "write", e)
        })
    }
}

impl Drop for StreamedFile {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// A file's bytes written to its temporary name on a thread of their own, while the caller
/// goes on, and then staged as a [`Streamed`] file is; [`Writing::finish`] waits for them.
pub struct Writing {
    path: std::path::PathBuf,
    thread: std::io::Result<std::thread::JoinHandle<Result<StreamedFile>>>,
}

impl Writing {
    /// Starts writing `bytes`, which hash to `hash` (the maker hashed them already), as the
    /// file that will be `path`.
    pub fn start(path: &Path, (bytes, hash): (Vec<u8>, crate::Hash)) -> Writing {
        let to = path.to_path_buf();
        crate::Hash::forget_file(path);
        let thread = std::thread::Builder::new().spawn(move || {
            let tmp = temporary(&to);
            if let Err(e) = write_durably(&tmp, std::slice::from_ref(&bytes)) {
                let _ = std::fs::remove_file(&tmp);
                return Err(Error::io(&to, "write", e));
            }
            Ok(StreamedFile {
                path: to,
                tmp: Some(tmp),
                bytes: bytes.len() as u64,
                hash,
            })
        });
        Writing {
            path: path.to_path_buf(),
            thread,
        }
    }

    /// The file written and on disk, at its temporary name.
    pub fn finish(self) -> Result<StreamedFile> {
        match self.thread {
            Ok(thread) => thread
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            Err(e) => Err(Error::io(&self.path, "write", e)),
        }
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// [`write_atomic`] of what `write` writes (through a buffer), for a file too large to hold
/// whole beside what it is made from (the million's `check.memo`: 0.3 GB).
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temporary(path);
    let result = write_durably_with(&tmp, write).and_then(|_| {
        let (old, renamed) = replace(&tmp, path);
        retire(old.into_iter().collect());
        renamed
    });
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, "write", e));
    }
    Ok(())
}

/// An exclusive lock on a build folder, held while a build or a check writes in it, so that the
/// folder always holds one build's files. Released when dropped (or when the process dies: the
/// operating system's file lock, not a marker file a kill would leave behind).
#[derive(Debug)]
pub struct FolderLock {
    _file: std::fs::File,
}

impl FolderLock {
    /// The lock file, in the folder.
    pub const FILE: &'static str = ".crowd.lock";

    /// Locks `dir` (which exists), calling `waiting` first if another process holds it, then
    /// removes the temporary files a killed build left there: whoever holds the lock is the
    /// only writer, so any temporary file is stale.
    pub fn acquire(dir: &Path, waiting: impl FnOnce()) -> Result<FolderLock> {
        let path = dir.join(Self::FILE);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            // A read-only folder with the lock file in it can still be locked.
            .or_else(|_| std::fs::File::open(&path))
            .map_err(|e| Error::io(&path, "open the build folder's lock", e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                waiting();
                file.lock()
                    .map_err(|e| Error::io(&path, "lock the build folder", e))?;
            }
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(Error::io(&path, "lock the build folder", e));
            }
        }
        remove_stale_temporaries(dir);
        Ok(FolderLock { _file: file })
    }
}

/// Whether `name` is one of [`write_atomic`]'s or [`ensure_writable_dir`]'s temporary files.
pub fn is_temporary(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('.') else {
        return false;
    };
    let pid_after = |marker: &str| {
        rest.rsplit_once(marker)
            .is_some_and(|(_, pid)| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
    };
    pid_after(".tmp") || rest.starts_with("write-probe") && pid_after("write-probe")
}

/// Removes the temporary files in `dir` (best effort: one that cannot be removed is left).
fn remove_stale_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        if entry.file_name().to_str().is_some_and(is_temporary) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Creates `dir` if needed and proves that files can be written in it, before any work is done.
pub fn ensure_writable_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "create the output folder", e))?;
    let probe = dir.join(format!(".write-probe{}", std::process::id()));
    std::fs::write(&probe, b"")
        .and_then(|_| match std::fs::remove_file(&probe) {
            // The folder's lock holder clears temporaries: it may have taken this one.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            other => other,
        })
        .map_err(|e| Error::io(dir, "write in the output folder", e))
}

/// The last line of a stage file: the hash of every byte before it.
const SEAL: &str = "// sealed: ";

/// A stage file's RON text ([`to_ron`]) sealed with the hash of its body as written, so that a
/// file cut short or edited by hand is told from the one its stage wrote ([`seal_holds`]).
pub fn to_stage_ron<T: Serialize>(value: &T) -> String {
    use std::fmt::Write;
    let mut text = to_ron_with_room(value, SEAL.len() + 65);
    let seal = Hash::of(text.as_bytes());
    writeln!(text, "{SEAL}{seal}").expect("writing to memory");
    text
}

/// Whether the stage file at `path` is exactly as its stage wrote it: its last line holds the
/// hash of every byte before it. A file cut short loses the line; an edit breaks the hash.
pub fn seal_holds(path: &Path) -> bool {
    let Ok(bytes) = std::fs::read(path) else {
        return false;
    };
    let Some(body) = bytes.strip_suffix(b"\n") else {
        return false;
    };
    let start = body.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    let (text, last) = body.split_at(start);
    std::str::from_utf8(last)
        .ok()
        .and_then(|l| l.strip_prefix(SEAL))
        .is_some_and(|hash| hash == Hash::of(text).to_string())
}

/// RON text of a stage file: one item of a list per line, so files stay readable and diffable.
pub fn to_ron<T: Serialize>(value: &T) -> String {
    to_ron_with_room(value, 0)
}

/// [`to_ron`] in a string made at its size, with room for `room` bytes more: the text is
/// measured first, then written (grown by doubling and copied whole to add the seal, the
/// million's 56 MB `graph.ron` took three times its size at its stage's peak).
fn to_ron_with_room<T: Serialize>(value: &T, room: usize) -> String {
    let config = ron::ser::PrettyConfig::new()
        .depth_limit(2)
        .indentor("  ".to_string())
        .separate_tuple_members(false)
        .struct_names(false);
    let mut size = Counted(0);
    ron::ser::to_writer_pretty(&mut size, value, config.clone()).expect("stage files serialise");
    let mut text = String::with_capacity(size.0 + 1 + room);
    ron::ser::to_writer_pretty(&mut text, value, config).expect("stage files serialise");
    text.push('\n');
    text
}

/// A writer that only counts the bytes written to it.
struct Counted(usize);

impl std::fmt::Write for Counted {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0 += s.len();
        Ok(())
    }
}

/// Reads and parses a RON stage file.
pub fn read_ron<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "read", e))?;
    parse_ron(path, &text)
}

/// Parses RON text read from `path`.
pub fn parse_ron<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    ron::Options::default()
        .from_str(text)
        .map_err(|e| Error::Syntax {
            path: path.to_path_buf(),
            place: LineCol {
                line: e.span.start.line,
                col: e.span.start.col,
            },
            message: e.code.to_string(),
        })
}

/// Just the header of a stage file, for staleness checks and `crowd inspect`.
pub fn read_header(path: &Path) -> Result<Header> {
    #[derive(Deserialize)]
    struct Peek {
        header: Header,
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "read", e))?;
    let text = String::from_utf8(bytes).map_err(|_| {
        Error::stage_file(
            path,
            "is not a stage file of this pipeline: it is binary, and stage files are RON text \
             starting with `header: (stage: ..., version: ..., input_hash: ...)`"
                .to_string(),
        )
    })?;
    // The header is the first field: parse only up to its end, not the whole (large) file.
    let end = text
        .find("\n  header:")
        .and_then(|start| text[start..].find("),\n").map(|close| start + close + 2));
    let parsed: Result<Peek> = match end {
        Some(end) => {
            parse_ron(path, &format!("{}\n)", &text[..end])).or_else(|_| parse_ron(path, &text))
        }
        None => parse_ron(path, &text),
    };
    let peek = parsed.map_err(|e| {
        Error::stage_file(
            path,
            format!(
                "is not a stage file of this pipeline (expected RON starting with \
                 `header: (stage: ..., version: ..., input_hash: ...)`): {e}"
            ),
        )
    })?;
    Ok(peek.header)
}

/// Checks that a stage file is of the expected stage and version.
pub fn expect_stage(path: &Path, header: &Header, stage: &str, version: u32) -> Result<()> {
    if header.stage != stage {
        return Err(Error::stage_file(
            path,
            format!("is a `{}` file; expected a `{stage}` file", header.stage),
        ));
    }
    if header.version != version {
        return Err(Error::stage_file(
            path,
            format!(
                "is `{stage}` format version {}; this build reads version {version}: build again",
                header.version
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staged_files_change_nothing_until_the_commit_and_nothing_at_all_without_it() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.bin"), dir.path().join("a.ron"));
        std::fs::write(&a, b"old").unwrap();
        let names = || {
            let mut n: Vec<String> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect();
            n.sort();
            n
        };
        let mut staging = Staging::new();
        staging.stage(vec![
            (a.clone(), b"new".to_vec()),
            (b.clone(), b"ron".to_vec()),
        ]);
        drop(staging);
        assert_eq!(std::fs::read(&a).unwrap(), b"old");
        assert_eq!(names(), ["a.bin"], "nothing left behind");

        let mut staging = Staging::new();
        staging.stage(vec![(a.clone(), b"new".to_vec())]);
        staging.stage(vec![(b.clone(), b"ron".to_vec())]);
        assert_eq!(std::fs::read(&a).unwrap(), b"old", "not before the commit");
        staging.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"new");
        assert_eq!(std::fs::read(&b).unwrap(), b"ron");
        // The replaced `a.bin` is removed in the background, and gone once waited for.
        wait_for_retired();
        assert_eq!(names(), ["a.bin", "a.ron"]);
    }

    /// A hash told at the commit is what `Hash::of_file` gives, without reading, until the
    /// file is written again; then the bytes are read.
    #[test]
    fn a_hash_told_at_the_commit_holds_until_the_file_is_written_again() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.bin");
        std::fs::write(&a, b"old").unwrap();
        let told = crate::Hash::of(b"not what is in the file");
        let mut staging = Staging::new();
        staging.stage(vec![(a.clone(), b"new".to_vec())]);
        staging.know(a.clone(), told);
        staging.commit().unwrap();
        assert_eq!(
            crate::Hash::of_file(&a).unwrap(),
            (3, told),
            "trusted, not read"
        );
        write_atomic(&a, b"newer").unwrap();
        assert_eq!(
            crate::Hash::of_file(&a).unwrap(),
            (5, crate::Hash::of(b"newer"))
        );
        wait_for_retired();
    }

    #[test]
    fn a_staged_file_that_cannot_be_written_fails_the_commit_and_puts_nothing_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.bin");
        let missing = dir.path().join("no such folder").join("b.ron");
        let mut staging = Staging::new();
        staging.stage(vec![(a.clone(), b"new".to_vec()), (missing, b"x".to_vec())]);
        let err = staging.commit().unwrap_err().to_string();
        assert!(err.contains("b.ron"), "{err}");
        assert!(!a.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    /// A file streamed piece by piece is the bytes of its pieces, hashed as one, and is put in
    /// place in its order among the staged files; unfinished or unstaged, it leaves nothing.
    #[test]
    fn a_streamed_file_is_its_pieces_in_place_at_the_commit_and_nothing_without_it() {
        let dir = tempfile::tempdir().unwrap();
        let (side, ron) = (dir.path().join("s.bin"), dir.path().join("s.ron"));
        let count = || std::fs::read_dir(dir.path()).unwrap().count();
        let mut cut = Streamed::create(&side).unwrap();
        cut.write(b"half").unwrap();
        drop(cut);
        assert_eq!(count(), 0, "an unfinished file is removed");
        let mut unstaged = Streamed::create(&side).unwrap();
        unstaged.write(b"all").unwrap();
        drop(unstaged.finish().unwrap());
        assert_eq!(count(), 0, "a file finished but never staged is removed");

        let big = vec![7u8; 3 << 20];
        let mut streamed = Streamed::create(&side).unwrap();
        for piece in [&b"head"[..], &big, b"tail"] {
            streamed.write(piece).unwrap();
        }
        let file = streamed.finish().unwrap();
        let whole = [&b"head"[..], &big, b"tail"].concat();
        assert_eq!(
            (file.bytes, file.hash),
            (whole.len() as u64, Hash::of(&whole))
        );
        let mut staging = Staging::new();
        staging.stage_streamed(file);
        staging.stage(vec![(ron.clone(), b"names s.bin".to_vec())]);
        assert!(!side.exists(), "not before the commit");
        staging.commit().unwrap();
        assert_eq!(std::fs::read(&side).unwrap(), whole);
        assert_eq!(std::fs::read(&ron).unwrap(), b"names s.bin");
        assert_eq!(count(), 2);

        let mut again = Streamed::create(&side).unwrap();
        again.write(b"new").unwrap();
        let mut staging = Staging::new();
        staging.stage_streamed(again.finish().unwrap());
        drop(staging);
        assert_eq!(
            std::fs::read(&side).unwrap(),
            whole,
            "a staging dropped changes nothing"
        );
        assert_eq!(count(), 2, "and leaves nothing behind");
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Demo {
        header: Header,
        items: Vec<(u32, f64)>,
    }

    #[test]
    fn header_is_read_without_the_rest() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("demo.ron");
        let demo = Demo {
            header: Header::new("demo", 3, Hash::of(b"x")),
            items: vec![(1, 0.5), (2, 1.5)],
        };
        write_atomic(&path, to_ron(&demo).as_bytes()).unwrap();
        assert_eq!(read_header(&path).unwrap(), demo.header);
        assert_eq!(read_ron::<Demo>(&path).unwrap(), demo);
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "no temporary file is left behind");
    }

    #[test]
    fn temporary_files_are_told_from_outputs() {
        for name in [
            ".graph.ron.tmp4242",
            ".world.glb.tmp1",
            ".write-probe77",
            ".library.crowd.old.tmp42",
        ] {
            assert!(is_temporary(name), "{name}");
        }
        for name in [
            "graph.ron",
            ".crowd.lock",
            ".tmpx",
            ".graph.ron.tmp",
            "a.tmp12",
        ] {
            assert!(!is_temporary(name), "{name}");
        }
    }

    #[test]
    fn the_lock_holder_clears_stale_temporaries_and_a_second_waits() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(".graph.ron.tmp999999"), b"cut").unwrap();
        std::fs::write(dir.path().join("graph.ron"), b"kept").unwrap();
        let lock = FolderLock::acquire(dir.path(), || panic!("no one holds it")).unwrap();
        let names: Vec<_> = (std::fs::read_dir(dir.path()).unwrap())
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert!(names.contains(&"graph.ron".to_string()), "{names:?}");
        assert!(!names.iter().any(|n| is_temporary(n)), "{names:?}");
        // A second holder (another open file, as another process would have) waits.
        let waited = std::sync::atomic::AtomicBool::new(false);
        std::thread::scope(|scope| {
            let second = scope.spawn(|| {
                FolderLock::acquire(dir.path(), || {
                    waited.store(true, std::sync::atomic::Ordering::SeqCst)
                })
            });
            while !waited.load(std::sync::atomic::Ordering::SeqCst) {
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            drop(lock);
            second.join().unwrap().unwrap();
        });
    }

    #[test]
    fn a_folder_under_a_file_is_not_writable() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("plain-file");
        std::fs::write(&file, b"x").unwrap();
        let err = ensure_writable_dir(&file.join("out")).unwrap_err();
        assert!(
            err.to_string().contains("cannot create the output folder"),
            "{err}"
        );
    }
}
