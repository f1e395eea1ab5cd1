//! The 3D view for browsers: the Rerun web viewer that the pinned `rerun-sdk` wheel's CLI serves
//! (`rerun --serve-web`, bound to loopback), reached through this server so that one port (one
//! SSH tunnel) carries everything: its page under `/rerun/`, its gRPC-web proxy (the recordings
//! the backend streams) under `/rerun.*`.

use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::http::Head;

/// The path prefix of the viewer's page.
pub const PAGE_PREFIX: &str = "/rerun/";
/// The path prefix of the viewer's gRPC-web calls (`/rerun.sdk_comms.v1alpha1.MessageProxyService/...`).
pub const GRPC_PREFIX: &str = "/rerun.";

/// The viewer's page, this server's own (from `app/web`): it starts the viewer of the wheel with
/// the recording named in its query and keeps its handle for the app's time cursor (the wheel's
/// own page does not expose it, and reaches for web fonts and telemetry).
pub const PAGE: &str = include_str!("../../web/viewer.html");
/// The page's script.
pub const PAGE_JS: &str = include_str!("../../web/viewer.js");

/// The content policy of the viewer's page: its scripts, WebAssembly and workers from this
/// server, nothing reached elsewhere (no fonts, no telemetry).
pub const PAGE_POLICY: &str = "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; worker-src 'self' blob:; \
    connect-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; media-src 'self' blob:; \
    frame-ancestors 'self'; object-src 'none'; base-uri 'none'";

/// Which of the viewer page's two files `path` is (content type and body), if it is one.
#[must_use]
pub fn page(path: &str) -> Option<(&'static str, &'static str)> {
    match path.strip_prefix(PAGE_PREFIX)? {
        "" | "index.html" => Some(("text/html; charset=utf-8", PAGE)),
        "viewer.js" => Some(("text/javascript; charset=utf-8", PAGE_JS)),
        _ => None,
    }
}

/// The viewer process and its two loopback ports.
#[derive(Debug)]
pub struct Viewer {
    child: Child,
    page_port: u16,
    grpc_port: u16,
}

fn free_port() -> std::io::Result<u16> {
    Ok(TcpListener::bind((Ipv4Addr::LOCALHOST, 0))?.local_addr()?.port())
}

impl Viewer {
    /// Starts `rerun` (the wheel's CLI) serving its web viewer and gRPC proxy on free loopback
    /// ports, and waits (up to 20 s) until both answer.
    ///
    /// # Errors
    /// A message saying what failed.
    pub fn start(rerun: &Path) -> Result<Self, String> {
        if !rerun.is_file() {
            return Err(format!("{} not found (bash scripts/setup.sh installs it; MIMICGEN_RERUN names another)", rerun.display()));
        }
        let (page_port, grpc_port) = (free_port().map_err(|e| e.to_string())?, free_port().map_err(|e| e.to_string())?);
        let child = Command::new(rerun)
            .args(["--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", &page_port.to_string(), "--port", &grpc_port.to_string()])
            .env("RERUN_ANALYTICS", "0")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("{}: {e}", rerun.display()))?;
        let mut viewer = Self { child, page_port, grpc_port };
        let started = Instant::now();
        loop {
            let up = |port| TcpStream::connect((Ipv4Addr::LOCALHOST, port)).is_ok();
            if up(page_port) && up(grpc_port) {
                return Ok(viewer);
            }
            if let Ok(Some(status)) = viewer.child.try_wait() {
                return Err(format!("{} --serve-web exited: {status}", rerun.display()));
            }
            if started.elapsed() > Duration::from_secs(20) {
                return Err(format!("{} --serve-web did not answer in 20 s", rerun.display()));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Where the backend streams recordings (`rerun+http://127.0.0.1:PORT/proxy`).
    #[must_use]
    pub fn grpc_url(&self) -> String {
        format!("rerun+http://127.0.0.1:{}/proxy", self.grpc_port)
    }

    /// The loopback port that answers `path`, if it is the viewer's (its page, [`PAGE`], is this
    /// server's own).
    #[must_use]
    pub fn port_for(&self, path: &str) -> Option<u16> {
        if page(path).is_some() {
            None
        } else if path.starts_with(PAGE_PREFIX) {
            Some(self.page_port)
        } else if path.starts_with(GRPC_PREFIX) {
            Some(self.grpc_port)
        } else {
            None
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The request target upstream: `/rerun/x` is the viewer's `/x`; a gRPC path
/// (`/rerun.sdk_comms...`) goes as it is.
fn upstream_target(path: &str, query: &str) -> String {
    let path = path.strip_prefix(PAGE_PREFIX).map_or_else(|| path.to_owned(), |p| format!("/{p}"));
    if query.is_empty() { path } else { format!("{path}?{query}") }
}

/// Forwards the request `head` (its path under [`PAGE_PREFIX`] made the viewer's own, the
/// connection closed after one response) to `port`, and pipes both ways until either side
/// closes.
///
/// # Errors
/// The socket's.
pub fn proxy(mut client: TcpStream, head: &Head, port: u16) -> std::io::Result<()> {
    let mut upstream = TcpStream::connect((Ipv4Addr::LOCALHOST, port))?;
    let mut request = format!("{} {} HTTP/1.1\r\n", head.method, upstream_target(&head.path, &head.query));
    for (name, value) in &head.headers {
        // One request per upstream connection; no credentials of ours go further.
        if matches!(name.as_str(), "connection" | "keep-alive" | "cookie" | "upgrade") {
            continue;
        }
        request.push_str(&format!("{name}: {value}\r\n"));
    }
    request.push_str("connection: close\r\n\r\n");
    upstream.write_all(request.as_bytes())?;
    upstream.write_all(&head.rest)?;
    let _ = client.set_read_timeout(None);
    let (mut client_read, mut upstream_write) = (client.try_clone()?, upstream.try_clone()?);
    let uploads = std::thread::Builder::new().name("mimicgen-serve-proxy".to_owned()).spawn(move || {
        let _ = std::io::copy(&mut client_read, &mut upstream_write);
        let _ = upstream_write.shutdown(std::net::Shutdown::Write);
    })?;
    let mut buf = [0_u8; 16 * 1024];
    loop {
        let n = upstream.read(&mut buf)?;
        if n == 0 {
            break;
        }
        #[allow(clippy::indexing_slicing, reason = "Read::read returns at most the buffer's length")]
        client.write_all(&buf[..n])?;
    }
    let _ = client.shutdown(std::net::Shutdown::Both);
    let _ = uploads.join();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_files_are_ours_and_the_rest_goes_upstream_unchanged() {
        assert_eq!(upstream_target("/rerun/re_viewer_bg.wasm", ""), "/re_viewer_bg.wasm");
        assert_eq!(upstream_target("/rerun/x", "a=1"), "/x?a=1");
        let grpc = "/rerun.sdk_comms.v1alpha1.MessageProxyService/ReadMessages";
        assert_eq!(upstream_target(grpc, ""), grpc);
        assert!(page("/rerun/").is_some_and(|(kind, body)| kind.starts_with("text/html") && body.contains("viewer.js")));
        assert!(page("/rerun/viewer.js").is_some());
        assert_eq!(page("/rerun/re_viewer.js"), None);
        assert_eq!(page(grpc), None);
    }
}
