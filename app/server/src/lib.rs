//! `mimicgen serve`: the inspection app for a browser, for machines without a display. One
//! process serves the page (the egui UI compiled to WebAssembly by `mimicgen-web`), runs the app's
//! backend natively (`mimicgen-backend`: files, simulation, runs) and carries their requests and
//! replies over a WebSocket; the Rerun web viewer is reached through it too, so one port (one SSH
//! tunnel) is all a user needs.
//!
//! Safety, since this is a server: it binds 127.0.0.1 unless told otherwise, and then answers only
//! requests whose `Host` is a loopback name (no DNS rebinding); any other address needs a token
//! (random per start, in the printed URL, checked on every request in constant time); a WebSocket
//! must come from the page this server served (`Origin`); every path a request names stays inside
//! `--root` (prepared copies are read through `@prepared/`, never named by their place); a
//! malformed or oversized message closes only its own connection; at most [`MAX_TABS`] tabs and
//! [`MAX_CONNECTIONS`] connections; with [`ServeOptions::vet`], every file a tab names is first
//! read in a child process, so a file that crashes libhdf5 cannot take the server down.
//!
//! Each tab has a backend worker of its own (its file, preview and 3D recording); the run is the
//! server's (`session`).
//!
//! What it does not do: TLS (tunnel it over SSH, or put a TLS proxy in front).
//!
//! The connection loop and routing enforce the rules above, in one file so they can be read
//! against them (the parts with a life of their own are `http`,
//! `root`, `session` and `viewer`).
//!
//! ```no_run
//! let options = mimicgen_server::ServeOptions { root: ".".into(), ..Default::default() };
//! let server = mimicgen_server::Server::bind(options)?;
//! println!("open {}", server.url());
//! server.run();
//! # Ok::<(), mimicgen_server::ServerError>(())
//! ```

pub mod http;
pub mod root;
pub mod session;
pub mod viewer;

use std::collections::BTreeMap;
use std::io::Write as _;
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex, PoisonError};

use mimicgen_ui::protocol::{ClientMessage, Welcome};
use tungstenite::protocol::frame::Frame;
use tungstenite::protocol::frame::coding::{CloseCode, Data, OpCode};
use tungstenite::protocol::{CloseFrame, Role, WebSocketConfig};
use tungstenite::{Message, WebSocket};

use crate::http::{Head, HeadError, refuse, respond};
use crate::root::Root;
use crate::session::Session;
use crate::viewer::Viewer;
pub use mimicgen_backend::Vetter;

/// The largest message a tab may send (requests are small; a bigger one is a bug or an attack).
pub const MAX_MESSAGE_BYTES: usize = 1 << 20;
/// The most tabs open at once (each has a backend worker, its own open file and simulation);
/// one more is refused with 503, saying so.
pub const MAX_TABS: usize = 100;
/// The most connections open at once (tabs, page loads, 3D viewer requests, and clients still
/// sending their request head, each of which is closed after 10 s); one more is answered 503 and
/// closed at once.
pub const MAX_CONNECTIONS: usize = 2048;
/// The cookie that carries the token after the page was opened with it.
const TOKEN_COOKIE: &str = "mimicgen_token";

/// The server's errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServerError {
    /// `--root` cannot be served.
    #[error("--root {}: {reason}", path.display())]
    Root {
        /// The folder.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The address cannot be bound.
    #[error("cannot listen on {addr}: {reason}")]
    Bind {
        /// The address.
        addr: String,
        /// What the OS said.
        reason: String,
    },
    /// The browser app's files are not there.
    #[error("the browser app is not built: {} has no {file} (run `bash scripts/build_web.sh`, or set MIMICGEN_WEB_DIR)", dir.display())]
    Bundle {
        /// The folder looked in.
        dir: PathBuf,
        /// The file missing.
        file: String,
    },
    /// An argument is wrong.
    #[error("{flag}: {reason}")]
    Argument {
        /// The flag.
        flag: String,
        /// Why.
        reason: String,
    },
}

impl ServerError {
    /// True when the user's input is at fault (exit code 2).
    #[must_use]
    pub fn is_user_error(&self) -> bool {
        matches!(self, Self::Root { .. } | Self::Argument { .. } | Self::Bind { .. } | Self::Bundle { .. })
    }
}

/// How `mimicgen serve` was asked to run.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// A file to open in every new tab.
    pub file: Option<PathBuf>,
    /// The address to bind.
    pub host: IpAddr,
    /// The port (0: any free one).
    pub port: u16,
    /// The folder every path stays inside.
    pub root: PathBuf,
    /// The token; required for any host but loopback (made at random when not given).
    pub token: Option<String>,
    /// The browser app's files ([`Bundle::default_dir`] when not given).
    pub web_dir: Option<PathBuf>,
    /// The `rerun` CLI that serves the web viewer (`None`: no 3D view).
    pub rerun: Option<PathBuf>,
    /// Reads each file a tab names in a child process first, so a file that crashes the HDF5
    /// library is refused and the server goes on (`mimicgen serve` sets `mimicgen vet`).
    pub vet: Option<mimicgen_backend::Vetter>,
}

impl Default for ServeOptions {
    fn default() -> Self {
        Self {
            file: None,
            host: IpAddr::from([127, 0, 0, 1]),
            port: 8080,
            root: PathBuf::from("."),
            token: None,
            web_dir: None,
            rerun: None,
            vet: None,
        }
    }
}

/// The browser app's files, read once at start.
#[derive(Debug, Default, Clone)]
pub struct Bundle {
    files: BTreeMap<&'static str, BundleFile>,
}

/// One file of the bundle, as read and (when built) gzip-compressed.
#[derive(Debug, Clone)]
struct BundleFile {
    plain: Arc<Vec<u8>>,
    gzipped: Option<Arc<Vec<u8>>>,
}

/// The page and its start-up script, from `app/web` (part of this binary).
const INDEX_HTML: &str = include_str!("../../web/index.html");
const MAIN_JS: &str = include_str!("../../web/main.js");

/// The files `scripts/build_web.sh` makes, served as they are (with a `.gz` beside, compressed).
const BUNDLE_FILES: [&str; 2] = ["mimicgen_web.js", "mimicgen_web_bg.wasm"];

impl Bundle {
    /// Where `scripts/build_web.sh` puts the files: `$MIMICGEN_WEB_DIR`, else
    /// `$MIMICGEN_CACHE/web`, else `~/.cache/mimicgen/web`.
    #[must_use]
    pub fn default_dir() -> PathBuf {
        if let Some(dir) = std::env::var_os("MIMICGEN_WEB_DIR") {
            return dir.into();
        }
        let cache = std::env::var_os("MIMICGEN_CACHE")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/mimicgen")))
            .unwrap_or_else(|| PathBuf::from(".cache/mimicgen"));
        cache.join("web")
    }

    /// Reads the files from `dir`.
    ///
    /// # Errors
    /// [`ServerError::Bundle`] naming the file missing.
    pub fn load(dir: &Path) -> Result<Self, ServerError> {
        let mut files = BTreeMap::new();
        for name in BUNDLE_FILES {
            let read = |p: PathBuf| std::fs::read(p).map(Arc::new);
            let plain = read(dir.join(name)).map_err(|_| ServerError::Bundle { dir: dir.to_path_buf(), file: name.to_owned() })?;
            let gzipped = read(dir.join(format!("{name}.gz"))).ok();
            files.insert(name, BundleFile { plain, gzipped });
        }
        Ok(Self { files })
    }
}

/// A bound server, ready to run.
#[derive(Debug)]
pub struct Server {
    listener: TcpListener,
    addr: SocketAddr,
    token: Option<String>,
    loopback: bool,
    bundle: Bundle,
    session: SessionHandle,
    viewer: Option<Arc<Viewer>>,
    /// Connections open now.
    connections: Arc<AtomicUsize>,
}

/// The session, shared by the connection threads.
struct SessionHandle(Session);

impl std::fmt::Debug for SessionHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session").finish_non_exhaustive()
    }
}

/// Counts a connection while it lives.
struct Counted(Arc<AtomicUsize>);

impl Drop for Counted {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// 128 random bits, hex.
fn random_token() -> Result<String, ServerError> {
    let mut bytes = [0_u8; 16];
    getrandom::fill(&mut bytes)
        .map_err(|e| ServerError::Argument { flag: "--token".to_owned(), reason: format!("no random token: {e}") })?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

impl Server {
    /// Checks the options, starts the backend (and the 3D viewer, when `rerun` is given and
    /// starts), and binds. The browser app's files come from `options.web_dir`; use
    /// [`Server::bind_with`] to give them (or none, for tests of the protocol).
    ///
    /// # Errors
    /// [`ServerError`].
    pub fn bind(options: ServeOptions) -> Result<Self, ServerError> {
        let dir = options.web_dir.clone().unwrap_or_else(Bundle::default_dir);
        let bundle = Bundle::load(&dir)?;
        Self::bind_with(options, bundle)
    }

    /// [`Server::bind`] with the browser app's files given.
    ///
    /// # Errors
    /// [`ServerError`].
    pub fn bind_with(options: ServeOptions, bundle: Bundle) -> Result<Self, ServerError> {
        let root = Root::new(&options.root)?.with_prepared(&mimicgen_backend::prepared_dir());
        let loopback = options.host.is_loopback();
        let token = match options.token {
            Some(t) if t.len() < 16 || !t.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_') => {
                return Err(ServerError::Argument {
                    flag: "--token".to_owned(),
                    reason: "at least 16 characters of letters, digits, '-' and '_'".to_owned(),
                });
            }
            Some(t) => Some(t),
            None if loopback => None,
            None => Some(random_token()?),
        };
        let file = match &options.file {
            Some(f) => Some(root.resolve(f).map_err(|reason| ServerError::Argument { flag: "FILE".to_owned(), reason })?),
            None => None,
        };
        let viewer = options.rerun.as_deref().and_then(|rerun| match Viewer::start(rerun) {
            Ok(v) => Some(Arc::new(v)),
            Err(e) => {
                eprintln!("mimicgen serve: no 3D view: {e}");
                None
            }
        });
        let addr = SocketAddr::new(options.host, options.port);
        let listener = TcpListener::bind(addr).map_err(|e| ServerError::Bind { addr: addr.to_string(), reason: e.to_string() })?;
        let addr = listener.local_addr().map_err(|e| ServerError::Bind { addr: addr.to_string(), reason: e.to_string() })?;
        let welcome = Welcome {
            cores: std::thread::available_parallelism().map_or(1, std::num::NonZero::get),
            root: Some(root.dir().to_path_buf()),
            file,
            viewer_url: viewer.as_ref().map(|_| viewer::PAGE_PREFIX.to_owned()),
            robots: mimicgen_backend::robots(),
        };
        let grpc = viewer.as_ref().map(|v| v.grpc_url());
        let session = Session::new(root, grpc, welcome, options.vet);
        let connections = Arc::new(AtomicUsize::new(0));
        Ok(Self { listener, addr, token, loopback, bundle, session: SessionHandle(session), viewer, connections })
    }

    /// The address bound.
    #[must_use]
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The URL to open (with the token, when there is one).
    #[must_use]
    pub fn url(&self) -> String {
        let host = if self.addr.ip().is_unspecified() { "127.0.0.1".to_owned() } else { self.addr.ip().to_string() };
        let host = if self.addr.is_ipv6() && !self.addr.ip().is_unspecified() { format!("[{host}]") } else { host };
        match &self.token {
            Some(t) => format!("http://{host}:{}/?token={t}", self.addr.port()),
            None => format!("http://{host}:{}/", self.addr.port()),
        }
    }

    /// Whether the 3D view is there.
    #[must_use]
    pub fn has_viewer(&self) -> bool {
        self.viewer.is_some()
    }

    /// Serves until the process ends: a thread per connection, up to [`MAX_CONNECTIONS`].
    pub fn run(self) {
        let shared = Arc::new(self);
        for stream in shared.listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            if shared.connections.fetch_add(1, Ordering::Relaxed) >= MAX_CONNECTIONS {
                shared.connections.fetch_sub(1, Ordering::Relaxed);
                // Unread, so answered without waiting on the client (its send buffer is empty).
                let _ = stream.set_nonblocking(true);
                let _ = stream
                    .write_all(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nRetry-After: 10\r\nConnection: close\r\n\r\n");
                continue;
            }
            let counted = Counted(Arc::clone(&shared.connections));
            let server = Arc::clone(&shared);
            let spawned = std::thread::Builder::new().name("mimicgen-serve-conn".to_owned()).spawn(move || {
                let _counted = counted;
                server.connection(stream);
            });
            if let Err(e) = spawned {
                eprintln!("mimicgen serve: cannot start a connection thread: {e}");
            }
        }
    }

    /// Whether `head` carries the token (or none is needed).
    fn authorized(&self, head: &Head) -> bool {
        let Some(token) = &self.token else { return true };
        let given = head.param("token").or_else(|| head.cookie(TOKEN_COOKIE)).unwrap_or_default();
        http::constant_time_eq(given.as_bytes(), token.as_bytes())
    }

    fn connection(&self, mut stream: TcpStream) {
        let peer = stream.peer_addr().map_or_else(|_| "?".to_owned(), |a| a.to_string());
        let head = match http::read_head(&mut stream) {
            Ok(head) => head,
            Err(HeadError::Closed) => return,
            Err(HeadError::Bad(status, message)) => {
                eprintln!("mimicgen serve: {peer}: {message}");
                return refuse(&mut stream, status, message);
            }
        };
        if self.loopback && !head.header("host").is_some_and(http::is_loopback_host) {
            eprintln!("mimicgen serve: {peer}: refused Host {:?} (this server answers only to localhost)", head.header("host"));
            return refuse(&mut stream, 403, "this server answers only to localhost, 127.0.0.1 or [::1]");
        }
        if !self.authorized(&head) {
            eprintln!("mimicgen serve: {peer}: {} {}: no valid token", head.method, head.path);
            return refuse(&mut stream, 401, "a valid token is needed: open the URL `mimicgen serve` printed");
        }
        if let Some(port) = self.viewer.as_ref().and_then(|v| v.port_for(&head.path)) {
            if let Err(e) = viewer::proxy(stream, &head, port) {
                eprintln!("mimicgen serve: {peer}: 3D viewer proxy: {e}");
            }
            return;
        }
        if head.method != "GET" {
            return refuse(&mut stream, 405, "only GET");
        }
        if head.path == "/ws" {
            if !head.is_websocket() {
                return refuse(&mut stream, 400, "a WebSocket is expected here");
            }
            if !http::origin_matches(head.header("origin"), head.header("host")) {
                eprintln!("mimicgen serve: {peer}: refused WebSocket from origin {:?}", head.header("origin"));
                return refuse(&mut stream, 403, "a WebSocket from another page than this server's is refused");
            }
            return self.socket(stream, &head, &peer);
        }
        self.file(&mut stream, &head);
    }

    /// Answers a GET for the page or one of its files.
    fn file(&self, stream: &mut TcpStream, head: &Head) {
        let cookie = match (&self.token, head.param("token")) {
            (Some(token), Some(_)) => format!("Set-Cookie: {TOKEN_COOKIE}={token}; Path=/; HttpOnly; SameSite=Strict\r\n"),
            _ => String::new(),
        };
        let no_store = "Cache-Control: no-store\r\n";
        let _ = match head.path.as_str() {
            "/" | "/index.html" => {
                let headers =
                    format!("{cookie}{no_store}Content-Security-Policy: {}\r\nX-Frame-Options: SAMEORIGIN\r\n", http::PAGE_POLICY);
                respond(stream, 200, "text/html; charset=utf-8", &headers, INDEX_HTML.as_bytes())
            }
            "/main.js" => respond(stream, 200, "text/javascript; charset=utf-8", no_store, MAIN_JS.as_bytes()),
            // No icon (and no 404 in the browser's console for it).
            "/favicon.ico" => respond(stream, 204, "image/x-icon", "", &[]),
            path if self.viewer.is_some() && viewer::page(path).is_some() => {
                let (kind, body) = viewer::page(path).unwrap_or_default();
                let headers = format!("{no_store}Content-Security-Policy: {}\r\nX-Frame-Options: SAMEORIGIN\r\n", viewer::PAGE_POLICY);
                respond(stream, 200, kind, &headers, body.as_bytes())
            }
            path => {
                let name = path.trim_start_matches('/');
                let Some(BundleFile { plain, gzipped }) = self.bundle.files.get(name) else {
                    return refuse(stream, 404, "not found");
                };
                let kind = if name.ends_with(".wasm") { "application/wasm" } else { "text/javascript; charset=utf-8" };
                let accepts_gzip = head.header("accept-encoding").is_some_and(|e| e.contains("gzip"));
                match gzipped.as_ref().filter(|_| accepts_gzip) {
                    Some(body) => {
                        respond(stream, 200, kind, &format!("{no_store}Content-Encoding: gzip\r\nVary: Accept-Encoding\r\n"), body)
                    }
                    None => respond(stream, 200, kind, no_store, plain),
                }
            }
        };
    }

    /// A tab's WebSocket: requests in (this thread, blocking on the socket), replies and the run's
    /// updates out (a writer thread, blocking on the tab's queue), so neither waits on a timer.
    fn socket(&self, mut stream: TcpStream, head: &Head, peer: &str) {
        let Some(key) = head.header("sec-websocket-key") else { return refuse(&mut stream, 400, "no Sec-WebSocket-Key") };
        let session = &self.session.0;
        let (client, queue) = match session.join(MAX_TABS) {
            Ok(joined) => joined,
            Err(e) => {
                eprintln!("mimicgen serve: {peer}: refused a tab: {e}");
                return refuse(&mut stream, 503, &e.to_string());
            }
        };
        let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
        let response = format!(
            "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
        );
        if std::io::Write::write_all(&mut stream, response.as_bytes()).is_err() {
            return session.leave(client);
        }
        let _ = stream.set_read_timeout(None);
        let _ = stream.set_nodelay(true);
        let Ok(read) = stream.try_clone() else { return session.leave(client) };
        let writes = Arc::new(Mutex::new(stream));
        let reading = Arc::new(AtomicBool::new(true));
        eprintln!("mimicgen serve: tab {client} connected from {peer} ({} open)", session.tabs());
        let writer = {
            let (writes, reading) = (Arc::clone(&writes), Arc::clone(&reading));
            std::thread::Builder::new().name("mimicgen-serve-write".to_owned()).spawn(move || write_replies(&queue, &writes, &reading))
        };
        let config = WebSocketConfig::default().max_message_size(Some(MAX_MESSAGE_BYTES)).max_frame_size(Some(MAX_MESSAGE_BYTES));
        let mut ws = WebSocket::from_raw_socket(ReadHalf { read, writes: Arc::clone(&writes) }, Role::Server, Some(config));
        let close = |ws: &mut WebSocket<ReadHalf>, code: CloseCode, reason: &str| {
            let _ = ws.close(Some(CloseFrame { code, reason: reason.to_owned().into() }));
            let _ = ws.flush();
        };
        if writer.is_ok() {
            loop {
                match ws.read() {
                    Ok(Message::Text(text)) => match serde_json::from_str::<ClientMessage>(&text) {
                        Ok(message) => session.request(client, message),
                        Err(e) => {
                            eprintln!("mimicgen serve: tab {client}: malformed message ({e}); closing its connection");
                            close(&mut ws, CloseCode::Invalid, "malformed message");
                            break;
                        }
                    },
                    Ok(Message::Binary(_)) => {
                        eprintln!("mimicgen serve: tab {client}: binary message; closing its connection");
                        close(&mut ws, CloseCode::Unsupported, "text messages only");
                        break;
                    }
                    Ok(Message::Close(_)) => break,
                    Ok(_) => {}
                    Err(tungstenite::Error::Capacity(e)) => {
                        eprintln!("mimicgen serve: tab {client}: {e}; closing its connection");
                        close(&mut ws, CloseCode::Size, "message too large");
                        break;
                    }
                    Err(tungstenite::Error::ConnectionClosed | tungstenite::Error::AlreadyClosed) => break,
                    Err(e) => {
                        if reading.load(Ordering::Relaxed) {
                            eprintln!("mimicgen serve: tab {client}: {e}; closing its connection");
                        }
                        break;
                    }
                }
            }
        }
        reading.store(false, Ordering::Relaxed);
        // The writer ends when the session drops the tab's queue.
        session.leave(client);
        if let Ok(writer) = writer {
            let _ = writer.join();
        }
        let _ = ws.get_ref().read.shutdown(std::net::Shutdown::Both);
        eprintln!("mimicgen serve: tab {client} left ({} open)", session.tabs());
    }
}

/// A tab's socket as its WebSocket reader sees it: reads from the socket, writes (pongs, close
/// frames) through the lock the writer thread writes under, so frames never interleave.
struct ReadHalf {
    read: TcpStream,
    writes: Arc<Mutex<TcpStream>>,
}

impl std::io::Read for ReadHalf {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.read.read(buf)
    }
}

impl std::io::Write for ReadHalf {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writes.lock().unwrap_or_else(PoisonError::into_inner).write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.writes.lock().unwrap_or_else(PoisonError::into_inner).flush()
    }
}

/// Writes each frame the session queues for `client` (text, or binary for images), as it comes.
/// When the session drops the queue while the tab is still reading, the tab was too slow to take
/// its replies: it is told so and disconnected.
fn write_replies(queue: &Receiver<mimicgen_ui::protocol::Frame>, writes: &Mutex<TcpStream>, reading: &AtomicBool) {
    let frame = |frame: Frame| -> std::io::Result<()> {
        let mut bytes = Vec::new();
        frame.format(&mut bytes).map_err(std::io::Error::other)?;
        writes.lock().unwrap_or_else(PoisonError::into_inner).write_all(&bytes)
    };
    let mut failed = false;
    for message in queue {
        let (bytes, kind) = match message {
            mimicgen_ui::protocol::Frame::Text(text) => (text.into_bytes(), Data::Text),
            mimicgen_ui::protocol::Frame::Binary(bytes) => (bytes, Data::Binary),
        };
        if frame(Frame::message(bytes, OpCode::Data(kind), true)).is_err() {
            failed = true;
            break;
        }
    }
    if !failed && reading.swap(false, Ordering::Relaxed) {
        // (The session has said so in the log.)
        let _ = frame(Frame::close(Some(CloseFrame { code: CloseCode::Policy, reason: "too slow to read the replies".into() })));
    }
    // Wakes the reader, if it still waits.
    let _ = writes.lock().unwrap_or_else(PoisonError::into_inner).shutdown(std::net::Shutdown::Both);
}
