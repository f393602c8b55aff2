//! Any bytes into `Library::from_bytes`: an error or a library, never a panic, an
//! out-of-bounds read or an unbounded allocation; a library that loads is played a few frames.
//! Opened on its file (`LibraryFile`), the same bytes are refused with the same error, or
//! give the same records and the same loops.
#![no_main]

use crowd_runtime::{Library, LibraryFile, Sampler};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let loaded = Library::from_bytes(bytes);
    let opened = LibraryFile::open(std::io::Cursor::new(bytes));
    match (&loaded, &opened) {
        (Ok(lib), Ok(file)) => {
            let all = 0..lib.characters.len();
            assert_eq!(file.loops(all.clone()).as_ref(), Ok(&lib.loops(all)));
        }
        (Err(a), Err(b)) => assert_eq!(a, b),
        _ => panic!("from_bytes and LibraryFile::open disagree"),
    }
    if let Ok(lib) = loaded {
        let mut sampler = Sampler::new(&lib);
        let mut out = Vec::new();
        for t in [0.0, 0.4, 13.0, -2.0, 1e7] {
            sampler.sample(t, [-1e9, -1e9, 1e9, 1e9], &mut out);
        }
    }
});
