//! `mimicgen serve` as a browser and an attacker meet it: real sockets on loopback, a real
//! backend. Each refusal is tested, and that the server (and other tabs) go on after it.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mimicgen_server::{Bundle, ServeOptions, Server};
use mimicgen_ui::protocol::{ClientMessage, PreviewRequest, Reply, Request, RunUpdate, ServerMessage};
use tungstenite::client::IntoClientRequest as _;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::{Message, WebSocket};

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/io/tests/data/source_D0_prepared.hdf5")
}

/// A server on a free loopback port (or `host`), serving `root`, running on its own thread.
fn serve(root: &Path, host: [u8; 4], token: Option<&str>) -> (SocketAddr, String) {
    let options =
        ServeOptions { host: host.into(), port: 0, root: root.to_path_buf(), token: token.map(str::to_owned), ..ServeOptions::default() };
    let server = Server::bind_with(options, Bundle::default()).unwrap();
    let (addr, url) = (server.local_addr(), server.url());
    std::thread::spawn(move || server.run());
    (SocketAddr::from(([127, 0, 0, 1], addr.port())), url)
}

/// A plain HTTP GET; returns the status and the whole response.
fn get(addr: SocketAddr, target: &str, headers: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    write!(s, "GET {target} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n{headers}\r\n", addr.port()).unwrap();
    let mut response = String::new();
    s.read_to_string(&mut response).unwrap();
    let status = response.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    (status, response)
}

type Socket = WebSocket<TcpStream>;

/// A tab's WebSocket, with the page's own origin unless told otherwise.
fn connect(addr: SocketAddr, query: &str, origin: Option<&str>) -> Result<Socket, tungstenite::Error> {
    let stream = TcpStream::connect(addr).unwrap();
    let mut request = format!("ws://127.0.0.1:{}/ws{query}", addr.port()).into_client_request().unwrap();
    let own = format!("http://127.0.0.1:{}", addr.port());
    if let Some(origin) = origin.or(Some(&own)).filter(|o| !o.is_empty()) {
        request.headers_mut().insert("Origin", origin.parse().unwrap());
    }
    let (ws, _) = tungstenite::client(request, stream).map_err(|e| match e {
        tungstenite::HandshakeError::Failure(e) => e,
        tungstenite::HandshakeError::Interrupted(_) => tungstenite::Error::ConnectionClosed,
    })?;
    ws.get_ref().set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    Ok(ws)
}

fn send(ws: &mut Socket, id: u64, request: Request) {
    ws.send(Message::text(serde_json::to_string(&ClientMessage { id, request }).unwrap())).unwrap();
}

/// The next message the server sends.
fn next(ws: &mut Socket) -> ServerMessage {
    loop {
        match ws.read().unwrap() {
            Message::Text(t) => return serde_json::from_str(&t).unwrap(),
            Message::Close(frame) => panic!("closed: {frame:?}"),
            _ => {}
        }
    }
}

/// Messages until one answers `id` and ends its request; returns them all.
fn until_answered(ws: &mut Socket, id: u64) -> Vec<ServerMessage> {
    let mut got = Vec::new();
    loop {
        let m = next(ws);
        let done = m.id == Some(id) && m.reply.ends_request();
        got.push(m);
        if done {
            return got;
        }
    }
}

/// The close frame's code, once the server closes.
fn closed_with(ws: &mut Socket) -> Option<CloseCode> {
    loop {
        match ws.read() {
            Ok(Message::Close(frame)) => return frame.map(|f| f.code),
            Ok(_) => {}
            Err(_) => return None,
        }
    }
}

#[test]
fn the_page_and_socket_answer_on_loopback_and_refuse_other_hosts_and_origins() {
    let dir = tempfile::tempdir().unwrap();
    let (addr, url) = serve(dir.path(), [127, 0, 0, 1], None);
    assert!(!url.contains("token"), "no token on loopback: {url}");
    let (status, page) = get(addr, "/", "");
    assert_eq!(status, 200, "{page}");
    assert!(page.contains("<canvas id=\"app\">") && page.contains("Content-Security-Policy:"), "{page}");
    // DNS rebinding: a page of another site whose name resolves to 127.0.0.1.
    let mut s = TcpStream::connect(addr).unwrap();
    write!(s, "GET / HTTP/1.1\r\nHost: evil.example:{}\r\n\r\n", addr.port()).unwrap();
    let mut response = String::new();
    s.read_to_string(&mut response).unwrap();
    assert!(response.starts_with("HTTP/1.1 403"), "{response}");
    // Another site's page opening a socket to us.
    for origin in ["http://evil.example", "http://127.0.0.1:1", ""] {
        let err = connect(addr, "", Some(origin)).unwrap_err();
        assert!(matches!(&err, tungstenite::Error::Http(r) if r.status() == 403), "{origin:?}: {err}");
    }
    let mut ws = connect(addr, "", None).unwrap();
    let ServerMessage { id: None, reply: Reply::Welcome(welcome) } = next(&mut ws) else { panic!("a greeting first") };
    assert_eq!(welcome.root.as_deref(), Some(dir.path().canonicalize().unwrap().as_path()));
    // Unknown files and methods.
    assert_eq!(get(addr, "/../../etc/passwd", "").0, 404);
    assert_eq!(get(addr, "/mimicgen_web_bg.wasm", "").0, 404, "no bundle in this test");
}

#[test]
fn any_other_host_needs_the_token_on_every_request() {
    let dir = tempfile::tempdir().unwrap();
    let (addr, url) = serve(dir.path(), [0, 0, 0, 0], None);
    let token = url.split("token=").nth(1).unwrap().to_owned();
    assert_eq!(token.len(), 32, "128 random bits: {url}");
    let (_, url2) = serve(dir.path(), [0, 0, 0, 0], None);
    assert_ne!(url2.split("token=").nth(1).unwrap(), token, "a new token per start");
    assert_eq!(get(addr, "/", "").0, 401);
    assert_eq!(get(addr, "/?token=0123456789abcdef0123456789abcdef", "").0, 401);
    assert_eq!(get(addr, &format!("/?token={}", &token[..31]), "").0, 401);
    let (status, response) = get(addr, &format!("/?token={token}"), "");
    assert_eq!(status, 200);
    assert!(response.contains(&format!("mimicgen_token={token}; Path=/; HttpOnly; SameSite=Strict")), "{response}");
    // The page's files and the socket carry it as a cookie or in the query.
    assert_eq!(get(addr, "/main.js", &format!("Cookie: mimicgen_token={token}\r\n")).0, 200);
    assert_eq!(get(addr, "/main.js", "Cookie: mimicgen_token=nope\r\n").0, 401);
    let err = connect(addr, "", None).unwrap_err();
    assert!(matches!(&err, tungstenite::Error::Http(r) if r.status() == 401), "{err}");
    let mut ws = connect(addr, &format!("?token={token}"), None).unwrap();
    assert!(matches!(next(&mut ws).reply, Reply::Welcome(_)));
    // A token of one's own must be long enough to guess.
    let short = ServeOptions { port: 0, root: dir.path().into(), token: Some("abc".into()), ..ServeOptions::default() };
    assert!(Server::bind_with(short, Bundle::default()).unwrap_err().to_string().contains("--token"));
}

#[test]
fn malformed_and_oversized_messages_close_only_their_connection() {
    let dir = tempfile::tempdir().unwrap();
    let (addr, _) = serve(dir.path(), [127, 0, 0, 1], None);
    let mut watcher = connect(addr, "", None).unwrap();
    next(&mut watcher);
    let mut bad = connect(addr, "", None).unwrap();
    next(&mut bad);
    bad.send(Message::text("{\"id\": 1, \"request\": {\"Nope\": {}}}")).unwrap();
    assert_eq!(closed_with(&mut bad), Some(CloseCode::Invalid));
    let mut big = connect(addr, "", None).unwrap();
    next(&mut big);
    let huge = format!("{{\"id\": 1, \"request\": {{\"Open\": {{\"path\": \"{}\"}}}}}}", "a".repeat(2 << 20));
    let _ = big.send(Message::text(huge));
    assert_eq!(closed_with(&mut big), Some(CloseCode::Size));
    let mut binary = connect(addr, "", None).unwrap();
    next(&mut binary);
    binary.send(Message::binary(vec![0_u8; 8])).unwrap();
    assert_eq!(closed_with(&mut binary), Some(CloseCode::Unsupported));
    // A bad request head on plain HTTP.
    let mut s = TcpStream::connect(addr).unwrap();
    s.write_all(b"\x16\x03\x01 not http\r\n\r\n").unwrap();
    let mut response = String::new();
    s.read_to_string(&mut response).unwrap();
    assert!(response.starts_with("HTTP/1.1 400"), "{response}");
    // The tab that behaved still works, and new ones connect.
    send(&mut watcher, 7, Request::ListDir { path: ".".into() });
    let replies = until_answered(&mut watcher, 7);
    assert!(matches!(&replies.last().unwrap().reply, Reply::Listing(l) if l.parent.is_none()), "{replies:?}");
    let mut again = connect(addr, "", None).unwrap();
    assert!(matches!(next(&mut again).reply, Reply::Welcome(_)));
}

#[test]
fn every_path_stays_inside_the_root() {
    let dir = tempfile::tempdir().unwrap();
    let outside = tempfile::tempdir().unwrap();
    std::fs::copy(fixture(), outside.path().join("demos.hdf5")).unwrap();
    std::os::unix::fs::symlink(outside.path(), dir.path().join("link")).unwrap();
    let (addr, _) = serve(dir.path(), [127, 0, 0, 1], None);
    let mut ws = connect(addr, "", None).unwrap();
    next(&mut ws);
    let escaping: Vec<(Request, String)> = vec![
        (Request::ListDir { path: "..".into() }, "..".into()),
        (Request::Open { path: outside.path().join("demos.hdf5") }, outside.path().join("demos.hdf5").display().to_string()),
        (Request::Open { path: "link/demos.hdf5".into() }, "link/demos.hdf5".into()),
        (Request::OpenRun { path: "/etc/passwd".into() }, "/etc/passwd".into()),
        (
            Request::Save {
                source: "link/demos.hdf5".into(),
                out: "a.hdf5".into(),
                marks: Default::default(),
                signal_names: Vec::new(),
                overwrite: false,
            },
            "link/demos.hdf5".into(),
        ),
    ];
    for (id, (request, path)) in (1..).zip(escaping) {
        send(&mut ws, id, request);
        let replies = until_answered(&mut ws, id);
        let Reply::Failed { error, .. } = &replies.last().unwrap().reply else { panic!("{path}: refused, got {replies:?}") };
        assert!(error.starts_with(&path) && (error.contains("outside") || error.contains("`..`")), "{path}: {error}");
    }
    // Nothing was written outside, and the file there is as it was.
    assert_eq!(std::fs::read_dir(outside.path()).unwrap().count(), 1);
}

#[test]
fn a_run_belongs_to_the_server_and_every_tab_sees_it_also_after_reconnecting() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(fixture(), dir.path().join("demos.hdf5")).unwrap();
    let (addr, _) = serve(dir.path(), [127, 0, 0, 1], None);
    let mut starter = connect(addr, "", None).unwrap();
    next(&mut starter);
    let mut other = connect(addr, "", None).unwrap();
    next(&mut other);
    let config = mimicgen_run::RunConfig {
        source: Some("demos.hdf5".into()),
        out: "out/run.hdf5".into(),
        num_demos: Some(3),
        seed: Some(1),
        keep_failed: true,
        ..Default::default()
    };
    send(&mut starter, 2, Request::Run(Box::new(config)));
    assert!(until_answered(&mut starter, 2).iter().any(|m| m.reply == Reply::RunAccepted));
    // The other tab watches it: joined first, then the updates.
    let ServerMessage { id: None, reply: Reply::Run(RunUpdate::Joined(joined)) } = next(&mut other) else { panic!("joined first") };
    assert_eq!(joined.out, dir.path().canonicalize().unwrap().join("out/run.hdf5"), "paths resolved inside the root");
    let finished = |ws: &mut Socket| {
        let mut attempts = 0;
        let deadline = Instant::now() + Duration::from_secs(120);
        while Instant::now() < deadline {
            match next(ws).reply {
                Reply::Run(RunUpdate::Attempt(_)) => attempts += 1,
                Reply::Run(RunUpdate::Finished(report)) => return (attempts, report.attempts),
                Reply::Run(RunUpdate::Failed(e)) => panic!("{e}"),
                _ => {}
            }
        }
        panic!("the run did not finish")
    };
    assert_eq!(finished(&mut other), (3, 3));
    // The starting tab goes (a closed tab, a lost tunnel); a new one is greeted with the whole run.
    drop(starter);
    let mut later = connect(addr, "", None).unwrap();
    assert!(matches!(next(&mut later).reply, Reply::Welcome(_)));
    assert!(matches!(next(&mut later).reply, Reply::Run(RunUpdate::Joined(_))));
    assert_eq!(finished(&mut later), (3, 3));
    assert!(dir.path().join("out/run.hdf5").is_file());
}

/// Opens `path` in `ws` (request `id`); returns the file as opened.
fn open(ws: &mut Socket, id: u64, path: &str) -> mimicgen_ui::protocol::LoadedFile {
    send(ws, id, Request::Open { path: path.into() });
    let replies = until_answered(ws, id);
    let opened = replies.iter().find_map(|m| match &m.reply {
        Reply::Opened(file) => Some((**file).clone()),
        _ => None,
    });
    opened.unwrap_or_else(|| panic!("{path} opened: {:?}", replies.last()))
}

#[test]
fn each_tab_has_its_own_open_file_and_a_plain_robomimic_file_works_through_its_prepared_copy() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(fixture(), dir.path().join("demos.hdf5")).unwrap();
    let lift = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/io/tests/data/robosuite_lift_demo.hdf5");
    std::fs::copy(lift, dir.path().join("lift.hdf5")).unwrap();
    let (addr, _) = serve(dir.path(), [127, 0, 0, 1], None);
    let mut a = connect(addr, "", None).unwrap();
    next(&mut a);
    let mut b = connect(addr, "", None).unwrap();
    next(&mut b);
    assert_eq!(open(&mut a, 1, "demos.hdf5").total_demos, 10);
    // A plain robomimic file (no datagen_info) is prepared by replay into the server's cache, and
    // the tab names the copy by an alias, never by where it lies on the server.
    let file = open(&mut b, 1, "lift.hdf5");
    assert_eq!(file.total_demos, 3);
    assert_eq!(file.prepared_from.as_deref(), Some(dir.path().canonicalize().unwrap().join("lift.hdf5").as_path()));
    let alias = file.path.clone();
    assert!(alias.starts_with("@prepared") && alias.to_string_lossy().contains("lift"), "{}", alias.display());
    // Each tab's 3D view shows its own file: tab a's demo 9 (of 10) though tab b opened 3 demos.
    send(&mut a, 2, Request::Open3d { sink: mimicgen_ui::protocol::ViewerSink::Save("a.rrd".into()), demo: 9 });
    let reply = until_answered(&mut a, 2).pop().unwrap().reply;
    assert!(matches!(reply, Reply::Streaming { .. }), "{reply:?}");
    send(&mut b, 2, Request::Open3d { sink: mimicgen_ui::protocol::ViewerSink::Save("b.rrd".into()), demo: 9 });
    let Reply::Failed { error, .. } = until_answered(&mut b, 2).pop().unwrap().reply else { panic!("tab b has 3 demos") };
    assert!(error.contains("no demo 9"), "{error}");
    // Every later request about the plain file works through the alias: preview, try, save, run.
    let preview = |execute| PreviewRequest { source: alias.clone(), seed: 1, execute, ..PreviewRequest::default() };
    send(&mut b, 3, Request::Preview(Box::new(preview(true))));
    let reply = until_answered(&mut b, 3).pop().unwrap().reply;
    let Reply::Previewed(view) = reply else { panic!("previewed: {reply:?}") };
    assert_eq!(view.task, "lift");
    assert!(view.executed.is_some(), "tried");
    let save = Request::Save {
        source: alias.clone(),
        out: "lift_annotated.hdf5".into(),
        marks: Default::default(),
        signal_names: Vec::new(),
        overwrite: false,
    };
    send(&mut b, 4, save);
    let reply = until_answered(&mut b, 4).pop().unwrap().reply;
    assert!(matches!(reply, Reply::Saved { .. }), "{reply:?}");
    assert!(dir.path().join("lift_annotated.hdf5").is_file());
    let config = mimicgen_run::RunConfig {
        source: Some(alias.clone()),
        out: "out/lift.hdf5".into(),
        num_demos: Some(1),
        seed: Some(1),
        ..Default::default()
    };
    send(&mut b, 5, Request::Run(Box::new(config)));
    assert!(until_answered(&mut b, 5).iter().any(|m| m.reply == Reply::RunAccepted));
    let deadline = Instant::now() + Duration::from_secs(300);
    loop {
        assert!(Instant::now() < deadline, "the run did not finish");
        match next(&mut b).reply {
            Reply::Run(RunUpdate::Joined(joined)) => panic!("the starting tab is not told it joined: {joined:?}"),
            Reply::Run(RunUpdate::Finished(report)) => {
                assert_eq!(report.attempts, 1, "{report:?}");
                assert!(report.source.starts_with("@prepared/lift-"), "no server path in a report: {}", report.source);
                break;
            }
            Reply::Run(RunUpdate::Failed(e)) => panic!("{e}"),
            _ => {}
        }
    }
    assert!(dir.path().join("out/lift.hdf5").is_file());
    // Tab a was never told about tab b's file; its run updates are the server's.
    let mut seen = Vec::new();
    loop {
        match next(&mut a).reply {
            Reply::Notice(n) => panic!("a notice about another tab: {n}"),
            Reply::Run(RunUpdate::Finished(_)) => break,
            other => seen.push(other),
        }
    }
    assert!(matches!(seen.first(), Some(Reply::Run(RunUpdate::Joined(_)))), "{seen:?}");
    // Nothing is written among the prepared copies.
    let save =
        Request::Save { source: alias.clone(), out: alias.clone(), marks: Default::default(), signal_names: Vec::new(), overwrite: true };
    send(&mut b, 9, save);
    let Reply::Failed { error, .. } = until_answered(&mut b, 9).pop().unwrap().reply else { panic!("saving onto a prepared copy refused") };
    assert!(error.contains("only read"), "{error}");
    // Aliases name one prepared copy, nothing else; no reply names the server's cache.
    for (id, bad) in (10..).zip(["@prepared/../secret.hdf5", "@prepared/nope.hdf5", "@prepared/a/b.hdf5", "@prepared"]) {
        send(&mut b, id, Request::Open { path: bad.into() });
        let Reply::Failed { error, .. } = until_answered(&mut b, id).pop().unwrap().reply else { panic!("{bad} refused") };
        assert!(error.starts_with(bad), "{bad}: {error}");
        assert!(!error.contains(".cache") && !error.contains("prepared/") || error.starts_with("@prepared"), "{error}");
    }
}

#[test]
fn idle_connections_do_not_keep_a_new_tab_out_and_tabs_past_the_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (addr, _) = serve(dir.path(), [127, 0, 0, 1], None);
    // 500 clients that connect and send nothing (or half a request head); each takes two of this
    // process's file descriptors (its end and the server's), and the 100 tabs below two more.
    let soft_limit = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|l| l.lines().find(|l| l.starts_with("Max open files"))?.split_whitespace().nth(3)?.parse::<usize>().ok())
        .unwrap_or(4096);
    let count = 500.min(soft_limit.saturating_sub(500) / 2);
    if count < 500 {
        eprintln!("only {count} idle connections: this process may open {soft_limit} files");
    }
    let idle: Vec<TcpStream> = (0..count)
        .map(|i| {
            let mut s = TcpStream::connect(addr).unwrap();
            if i % 2 == 0 {
                s.write_all(b"GET / HTTP/1.1\r\nHost: 127.0").unwrap();
            }
            s
        })
        .collect();
    let mut tab = connect(addr, "", None).unwrap();
    assert!(matches!(next(&mut tab).reply, Reply::Welcome(_)));
    send(&mut tab, 1, Request::ListDir { path: ".".into() });
    assert!(matches!(until_answered(&mut tab, 1).pop().unwrap().reply, Reply::Listing(_)));
    drop(idle);
    // Tabs up to the limit connect; one more is refused with 503, saying why.
    let tabs: Vec<Socket> = (1..mimicgen_server::MAX_TABS)
        .map(|_| {
            let mut ws = connect(addr, "", None).unwrap();
            assert!(matches!(next(&mut ws).reply, Reply::Welcome(_)));
            ws
        })
        .collect();
    let upgrade = format!(
        "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: http://127.0.0.1:{}\r\n",
        addr.port()
    );
    let (status, response) = get(addr, "/ws", &upgrade);
    assert_eq!(status, 503, "{response}");
    assert!(response.contains("tabs open, its limit"), "{response}");
    // One closes; a new one gets in.
    drop(tabs);
    drop(tab);
    let mut again = (0..).find_map(|_| connect(addr, "", None).ok()).unwrap();
    assert!(matches!(next(&mut again).reply, Reply::Welcome(_)));
}
