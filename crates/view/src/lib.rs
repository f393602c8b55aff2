//! `crowd view DIR`: serves a build folder and the viewer page on 127.0.0.1, so that a person
//! can watch the crowd in a browser over what was painted.
//!
//! The page is static files kept in the repository (`page/`: `index.html`, `style.css` and
//! `viewer.js`, the page's code bundled with three.js by `viewer/bundle.mjs`), compiled into the
//! binary: it works offline, with no CDN. The server answers only:
//! - the page's own files;
//! - `/files/NAME`: a file directly inside the build folder (nothing above it, nothing below
//!   it: a name with a separator, `..` or a link out of the folder is refused);
//! - `/scene.json` and `/ground.png`, made from the folder's own stage files (`scene.rs`).
//!
//! The page reads `library.crowd` itself, with its own reader of FORMAT.md.
//!
//! - `serve.rs`: the HTTP loop and the routes;
//! - `scene.rs`: what the page draws besides the characters (the patch grid, densities,
//!   directions, obstacles, the check's findings, the edits) and the painted ground.

mod scene;
mod serve;

pub use serve::{Server, route};

/// Opens `address` in the system's browser; false where there is none (a headless machine).
pub fn open_browser(address: &str) -> bool {
    webbrowser::open(address).is_ok()
}
