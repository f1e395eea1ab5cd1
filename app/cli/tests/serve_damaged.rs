//! `mimicgen serve` given a file that crashes libhdf5: the server reads each file a tab names in a
//! `mimicgen vet` child first, so the tab hears the file is damaged, and the server, the other
//! tabs and a run in progress go on. Real sockets on loopback, the real binary as the child.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

use mimicgen_server::{Bundle, ServeOptions, Server, Vetter};
use mimicgen_ui::protocol::{ClientMessage, Reply, Request, RunUpdate, ServerMessage};
use tungstenite::client::IntoClientRequest as _;
use tungstenite::{Message, WebSocket};

type Socket = WebSocket<TcpStream>;

fn repo_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(relative)
}

fn connect(addr: SocketAddr) -> Socket {
    let stream = TcpStream::connect(addr).unwrap();
    let mut request = format!("ws://127.0.0.1:{}/ws", addr.port()).into_client_request().unwrap();
    request.headers_mut().insert("Origin", format!("http://127.0.0.1:{}", addr.port()).parse().unwrap());
    let (ws, _) = tungstenite::client(request, stream).map_err(|e| format!("{e}")).unwrap();
    // A safety net only: every wait below is on a message.
    ws.get_ref().set_read_timeout(Some(Duration::from_secs(300))).unwrap();
    ws
}

fn send(ws: &mut Socket, id: u64, request: Request) {
    ws.send(Message::text(serde_json::to_string(&ClientMessage { id, request }).unwrap())).unwrap();
}

fn next(ws: &mut Socket) -> ServerMessage {
    loop {
        if let Message::Text(t) = ws.read().unwrap() {
            return serde_json::from_str(&t).unwrap();
        }
    }
}

/// The reply that ends request `id` (run updates before it are skipped).
fn answer(ws: &mut Socket, id: u64) -> Reply {
    loop {
        let m = next(ws);
        if m.id == Some(id) && m.reply.ends_request() {
            return m.reply;
        }
    }
}

#[test]
fn a_file_that_crashes_libhdf5_leaves_the_server_its_tabs_and_its_run_alive() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(repo_path("core/io/tests/data/source_D0_prepared.hdf5"), dir.path().join("demos.hdf5")).unwrap();
    let damaged = dir.path().join("damaged.hdf5");
    std::fs::copy(repo_path("app/cli/tests/data/damaged_crashes_libhdf5.hdf5"), &damaged).unwrap();
    // What the server is protected from: the child reading it dies (here, by a signal).
    let direct = std::process::Command::new(env!("CARGO_BIN_EXE_mimicgen")).arg("vet").arg(&damaged).output().unwrap();
    let crashes = direct.status.code().is_none_or(|c| c > 1);
    let vet = Vetter::new(vec![env!("CARGO_BIN_EXE_mimicgen").into(), "vet".into()]);
    let options = ServeOptions { port: 0, root: dir.path().into(), vet, ..ServeOptions::default() };
    let server = Server::bind_with(options, Bundle::default()).unwrap();
    let addr = SocketAddr::from(([127, 0, 0, 1], server.local_addr().port()));
    std::thread::spawn(move || server.run());

    let mut runner = connect(addr);
    next(&mut runner);
    let config = mimicgen_run::RunConfig {
        source: Some("demos.hdf5".into()),
        out: "out/run.hdf5".into(),
        // Long enough to be going while the other tab reads the damaged file; cancelled below.
        num_demos: Some(1000),
        seed: Some(1),
        keep_failed: true,
        ..Default::default()
    };
    send(&mut runner, 1, Request::Run(Box::new(config)));
    assert_eq!(answer(&mut runner, 1), Reply::RunAccepted);

    let mut victim = connect(addr);
    next(&mut victim);
    for (id, request) in [
        (1, Request::Open { path: "damaged.hdf5".into() }),
        (2, Request::OpenCompare { path: "damaged.hdf5".into() }),
        (3, Request::Preview(Box::new(mimicgen_ui::protocol::PreviewRequest { source: "damaged.hdf5".into(), ..Default::default() }))),
    ] {
        send(&mut victim, id, request);
        let Reply::Failed { error, .. } = answer(&mut victim, id) else { panic!("request {id} on a damaged file refused") };
        assert!(error.contains("damaged.hdf5"), "{error}");
        if crashes {
            assert!(error.contains("damaged (the HDF5 library crashed"), "{error}");
        }
    }
    // The same tab goes on with a good file and cancels the server's run, which ends with its
    // dataset written for the tab that started it.
    send(&mut victim, 4, Request::Open { path: "demos.hdf5".into() });
    assert!(matches!(answer(&mut victim, 4), Reply::Opened(_)));
    send(&mut victim, 5, Request::CancelRun);
    assert_eq!(answer(&mut victim, 5), Reply::Cancelling);
    loop {
        match next(&mut runner).reply {
            Reply::Run(RunUpdate::Finished(report)) => {
                assert!(report.cancelled || report.attempts == 1000, "{report:?}");
                break;
            }
            Reply::Run(RunUpdate::Failed(e)) => panic!("{e}"),
            _ => {}
        }
    }
    assert!(dir.path().join("out/run.hdf5").is_file());
    let mut later = connect(addr);
    assert!(matches!(next(&mut later).reply, Reply::Welcome(_)));
}
