//! The HTTP side of `crowd view`: a `tiny_http` server on 127.0.0.1 and the routes it answers.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// The page's files, compiled in.
const INDEX: &[u8] = include_bytes!("../page/index.html");
const STYLE: &[u8] = include_bytes!("../page/style.css");
const SCRIPT: &[u8] = include_bytes!("../page/viewer.js");

/// A build folder served on 127.0.0.1.
pub struct Server {
    http: tiny_http::Server,
    dir: PathBuf,
    /// `http://127.0.0.1:PORT/`.
    pub address: String,
}

impl Server {
    /// Binds 127.0.0.1:`port` (a free port when `None`) to serve `dir`, which must be a build
    /// folder (it has `library.crowd`).
    pub fn bind(dir: &Path, port: Option<u16>) -> Result<Server> {
        let dir = dir
            .canonicalize()
            .with_context(|| format!("{}: cannot open the build folder", dir.display()))?;
        if !dir.join("library.crowd").is_file() {
            bail!(
                "{}: no library.crowd here; expected a build folder (`crowd build` writes one)",
                dir.display()
            );
        }
        let http = tiny_http::Server::http(("127.0.0.1", port.unwrap_or(0))).map_err(|e| {
            anyhow::anyhow!("cannot listen on 127.0.0.1:{}: {e}", port.unwrap_or(0))
        })?;
        let port = http
            .server_addr()
            .to_ip()
            .map(|a| a.port())
            .context("the server has no IP address")?;
        Ok(Server {
            http,
            dir,
            address: format!("http://127.0.0.1:{port}/"),
        })
    }

    /// Answers requests until the process is stopped (Ctrl-C).
    pub fn run(&self) -> Result<()> {
        for request in self.http.incoming_requests() {
            let (status, kind, body) = match request.method() {
                tiny_http::Method::Get | tiny_http::Method::Head => route(&self.dir, request.url()),
                _ => (405, "text/plain", b"only GET and HEAD\n".to_vec()),
            };
            let header = tiny_http::Header::from_bytes(&b"Content-Type"[..], kind.as_bytes())
                .expect("a valid header");
            let no_cache = tiny_http::Header::from_bytes(&b"Cache-Control"[..], &b"no-store"[..])
                .expect("a valid header");
            let response = tiny_http::Response::from_data(body)
                .with_status_code(status)
                .with_header(header)
                .with_header(no_cache);
            // A browser that went away is not the server's failure.
            let _ = request.respond(response);
        }
        Ok(())
    }
}

/// The answer to a GET of `url` in the build folder `dir` (canonical): status, content type
/// and body.
pub fn route(dir: &Path, url: &str) -> (u16, &'static str, Vec<u8>) {
    let path = url.split(['?', '#']).next().unwrap_or("");
    let text =
        |status: u16, message: String| (status, "text/plain; charset=utf-8", message.into_bytes());
    match path {
        "/" | "/index.html" => (200, "text/html; charset=utf-8", INDEX.to_vec()),
        "/style.css" => (200, "text/css; charset=utf-8", STYLE.to_vec()),
        "/viewer.js" => (200, "text/javascript; charset=utf-8", SCRIPT.to_vec()),
        // Browsers ask for it; there is none.
        "/favicon.ico" => (204, "image/x-icon", Vec::new()),
        "/scene.json" => match crate::scene::scene_json(dir) {
            Ok(json) => (200, "application/json", json.into_bytes()),
            Err(e) => text(500, format!("{e:#}\n")),
        },
        "/ground.png" => match crate::scene::ground_png(dir) {
            Ok(Some(png)) => (200, "image/png", png),
            Ok(None) => text(404, "no merge.bin in the build folder\n".into()),
            Err(e) => text(500, format!("{e:#}\n")),
        },
        _ => match path
            .strip_prefix("/files/")
            .and_then(|name| inside(dir, name))
        {
            Some(file) => match std::fs::read(&file) {
                Ok(bytes) => (200, content_type(&file), bytes),
                Err(e) => text(404, format!("{}: {e}\n", file.display())),
            },
            None => text(404, format!("{path}: not a file of the build folder\n")),
        },
    }
}

/// The file `name` directly inside `dir`, if it is one: a plain name (no separator, not `.`
/// or `..`, no percent-escapes) of a regular file whose real path is in `dir` itself.
fn inside(dir: &Path, name: &str) -> Option<PathBuf> {
    let plain =
        !name.is_empty() && name != "." && name != ".." && !name.contains(['/', '\\', '%', '\0']);
    if !plain {
        return None;
    }
    let file = dir.join(name).canonicalize().ok()?;
    (file.parent() == Some(dir) && file.is_file()).then_some(file)
}

fn content_type(file: &Path) -> &'static str {
    match file.extension().and_then(|e| e.to_str()) {
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("ron" | "md" | "csv") => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_folders_own_files_are_served() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().canonicalize().unwrap();
        let dir = root.join("build");
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(root.join("secret.txt"), "above").unwrap();
        std::fs::write(dir.join("library.crowd"), "lib").unwrap();
        std::fs::write(dir.join("sub/inner.txt"), "below").unwrap();
        let dir = dir.canonicalize().unwrap();
        assert_eq!(route(&dir, "/files/library.crowd").0, 200);
        assert_eq!(route(&dir, "/files/library.crowd").2, b"lib");
        for url in [
            "/files/../secret.txt",
            "/files/..%2Fsecret.txt",
            "/files/sub/inner.txt",
            "/files/sub",
            "/files/",
            "/files/..",
            "/secret.txt",
            "/../secret.txt",
        ] {
            assert_eq!(route(&dir, url).0, 404, "{url}");
        }
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(root.join("secret.txt"), dir.join("link.txt")).unwrap();
            assert_eq!(route(&dir, "/files/link.txt").0, 404);
        }
        assert_eq!(route(&dir, "/").0, 200);
        assert_eq!(route(&dir, "/viewer.js").0, 200);
    }
}
