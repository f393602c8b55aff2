//! Any bytes into `Library::from_bytes`: an error or a library, never a panic, an
//! out-of-bounds read or an unbounded allocation; a library that loads is played a few frames.
#![no_main]

use crowd_runtime::{Library, Sampler};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    if let Ok(lib) = Library::from_bytes(bytes) {
        let mut sampler = Sampler::new(&lib);
        let mut out = Vec::new();
        for t in [0.0, 0.4, 13.0, -2.0, 1e7] {
            sampler.sample(t, [-1e9, -1e9, 1e9, 1e9], &mut out);
        }
    }
});
