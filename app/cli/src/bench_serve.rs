//! `mimicgen bench-serve`: `mimicgen serve` under a lab's load. A server in this process, on a
//! free loopback port, and N tabs (WebSocket clients on threads) that each open the file, then for
//! the rest of the time scrub through demos, list the folder, preview scenes and try every fifth
//! one in simulation, while a long run started by the first tab goes on and every tab watches it.
//! Reports each request kind's latency (p50/p95/p99), errors, the time a new tab takes to be
//! greeted while all that goes on, and the process's memory.

use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::sync::mpsc::channel;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use mimicgen_server::{Bundle, ServeOptions, Server, Vetter};
use mimicgen_ui::protocol::{ClientMessage, PreviewRequest, Reply, Request, ServerMessage};
use serde_json::json;
use tungstenite::client::IntoClientRequest as _;
use tungstenite::{Message, WebSocket};

use crate::exit::outln;

/// Arguments of `mimicgen bench-serve`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen bench-serve                                  # 1, 10 and 50 tabs, 60 s each, the bundled Stack demos
  mimicgen bench-serve --tabs 10 --seconds 20
  mimicgen bench-serve my_sources.hdf5 --tabs 1,5 --run 500

Prints a Markdown table (and with --json, one JSON object per tab count): per request kind the
count and p50/p95/p99 latency in ms from send to the reply that ends it; errors (refusals and
lost connections); ms until a new tab is greeted half-way through; peak and final resident memory
of this process (server and clients).")]
pub struct BenchServeArgs {
    /// The file every tab opens (default: the bundled Stack D0 source demos).
    file: Option<PathBuf>,
    /// Tab counts to measure, one after another, each on a fresh server.
    #[arg(long, value_delimiter = ',', default_value = "1,10,50")]
    tabs: Vec<usize>,
    /// Seconds of load per tab count.
    #[arg(long, default_value_t = 60)]
    seconds: u64,
    /// Attempts of the run the first tab starts (cancelled at the end; 0: no run).
    #[arg(long, default_value_t = 10_000)]
    run: usize,
    /// Print JSON lines instead of the table.
    #[arg(long)]
    json: bool,
}

type Socket = WebSocket<TcpStream>;

/// What one tab measured.
#[derive(Default)]
struct TabLog {
    /// (kind, ms) per answered request.
    latencies: Vec<(&'static str, f64)>,
    errors: Vec<String>,
}

fn connect(addr: SocketAddr) -> anyhow::Result<Socket> {
    let stream = TcpStream::connect(addr)?;
    let mut request = format!("ws://127.0.0.1:{}/ws", addr.port()).into_client_request()?;
    request.headers_mut().insert("Origin", format!("http://127.0.0.1:{}", addr.port()).parse()?);
    let (ws, _) = tungstenite::client(request, stream).map_err(|e| anyhow::anyhow!("connecting a tab: {e}"))?;
    ws.get_ref().set_read_timeout(Some(Duration::from_secs(600)))?;
    Ok(ws)
}

/// The next message (binary frames are images).
fn next(ws: &mut Socket) -> anyhow::Result<ServerMessage> {
    loop {
        match ws.read()? {
            Message::Text(t) => return Ok(serde_json::from_str(&t)?),
            Message::Binary(b) => return ServerMessage::from_binary(&b).map_err(anyhow::Error::msg),
            Message::Close(f) => anyhow::bail!("closed: {f:?}"),
            _ => {}
        }
    }
}

/// Sends `request` as `id` and waits for the reply that ends it (run updates on the way are the
/// run everyone watches).
fn ask(ws: &mut Socket, id: u64, request: Request) -> anyhow::Result<(Reply, f64)> {
    let start = Instant::now();
    ws.send(Message::text(serde_json::to_string(&ClientMessage { id, request })?))?;
    loop {
        let m = next(ws)?;
        if m.id == Some(id) && m.reply.ends_request() {
            return Ok((m.reply, start.elapsed().as_secs_f64() * 1000.0));
        }
    }
}

/// One tab's session until `until`.
fn tab(addr: SocketAddr, index: usize, until: Instant, run: usize) -> TabLog {
    let mut log = TabLog::default();
    let mut go = || -> anyhow::Result<()> {
        let mut ws = connect(addr)?;
        next(&mut ws)?;
        let (reply, ms) = ask(&mut ws, 1, Request::Open { path: "demos.hdf5".into() })?;
        let Reply::Opened(file) = reply else { anyhow::bail!("open: {reply:?}") };
        log.latencies.push(("open", ms));
        let demos = file.total_demos.max(1);
        if index == 0 && run > 0 {
            let config = mimicgen_run::RunConfig {
                source: Some("demos.hdf5".into()),
                out: "out/bench.hdf5".into(),
                num_demos: Some(run),
                seed: Some(1),
                overwrite: true,
                ..Default::default()
            };
            let (reply, _) = ask(&mut ws, 2, Request::Run(Box::new(config)))?;
            if reply != Reply::RunAccepted {
                log.errors.push(format!("run: {reply:?}"));
            }
        }
        let mut id = 10;
        let mut k: usize = index * 7;
        while Instant::now() < until {
            id += 1;
            k += 1;
            let (kind, request) = match k % 4 {
                0 => ("list", Request::ListDir { path: ".".into() }),
                1 => ("scrub", Request::ShowDemo { demo: k % demos, in_3d: false }),
                _ => {
                    let execute = k % 20 == 2;
                    let request = PreviewRequest { source: file.path.clone(), seed: 1, index: k as u64, execute, ..Default::default() };
                    (if execute { "try" } else { "preview" }, Request::Preview(Box::new(request)))
                }
            };
            let (reply, ms) = ask(&mut ws, id, request)?;
            if let Reply::Failed { what, error } = reply {
                log.errors.push(format!("{kind}: {what}: {error}"));
            } else {
                log.latencies.push((kind, ms));
            }
        }
        if index == 0 && run > 0 {
            ask(&mut ws, id + 1, Request::CancelRun)?;
        }
        Ok(())
    };
    if let Err(e) = go() {
        log.errors.push(format!("tab {index}: {e}"));
    }
    log
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
    let i = ((sorted.len().saturating_sub(1)) as f64 * p).round() as usize;
    sorted.get(i).copied().unwrap_or(f64::NAN)
}

/// Resident memory of this process now (MiB).
fn rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// One request kind's latencies.
struct Latency {
    count: usize,
    /// p50, p95, p99 (ms, one decimal).
    p: [f64; 3],
}

/// What one tab count measured.
struct Measured {
    tabs: usize,
    seconds: u64,
    kinds: Vec<(&'static str, Latency)>,
    errors: Vec<String>,
    new_tab_ms: f64,
    peak_rss_mib: Option<f64>,
    rss_mib: Option<f64>,
}

impl Measured {
    fn kind(&self, name: &str) -> Option<&Latency> {
        self.kinds.iter().find(|(k, _)| *k == name).map(|(_, l)| l)
    }

    fn json(&self) -> serde_json::Value {
        let kinds: serde_json::Map<String, serde_json::Value> = self
            .kinds
            .iter()
            .map(|(k, l)| ((*k).to_owned(), json!({"count": l.count, "p50_ms": l.p[0], "p95_ms": l.p[1], "p99_ms": l.p[2]})))
            .collect();
        json!({
            "tabs": self.tabs,
            "seconds": self.seconds,
            "requests": kinds,
            "errors": self.errors.len(),
            "first_errors": self.errors.iter().take(3).collect::<Vec<_>>(),
            "new_tab_ms": self.new_tab_ms,
            "peak_rss_mib": self.peak_rss_mib,
            "rss_mib": self.rss_mib,
        })
    }
}

const KINDS: [&str; 5] = ["open", "scrub", "list", "preview", "try"];

fn measure(file: &std::path::Path, tabs: usize, seconds: u64, run: usize) -> anyhow::Result<Measured> {
    let dir = tempfile::tempdir()?;
    std::fs::copy(file, dir.path().join("demos.hdf5")).with_context(|| format!("copying {}", file.display()))?;
    mimicgen_pipeline::memory::reset_peak_rss();
    let options = ServeOptions { port: 0, root: dir.path().into(), vet: Vetter::this_binary(), ..ServeOptions::default() };
    let server = Server::bind_with(options, Bundle::default())?;
    let addr = SocketAddr::from(([127, 0, 0, 1], server.local_addr().port()));
    std::thread::spawn(move || server.run());
    let start = Instant::now();
    let until = start + Duration::from_secs(seconds);
    let (done, logs) = channel();
    for index in 0..tabs {
        let done = done.clone();
        std::thread::spawn(move || {
            let _ = done.send(tab(addr, index, until, run));
        });
    }
    drop(done);
    // Half-way: how long a new tab waits for its greeting.
    std::thread::sleep(Duration::from_secs(seconds / 2));
    let greeted = Instant::now();
    let mut newcomer = connect(addr)?;
    next(&mut newcomer)?;
    let new_tab_ms = (greeted.elapsed().as_secs_f64() * 10_000.0).round() / 10.0;
    drop(newcomer);
    let logs: Vec<TabLog> = logs.iter().collect();
    let kinds = KINDS
        .iter()
        .map(|&kind| {
            let mut ms: Vec<f64> = logs.iter().flat_map(|l| l.latencies.iter().filter(|(k, _)| *k == kind).map(|(_, ms)| *ms)).collect();
            ms.sort_by(f64::total_cmp);
            let p = |q| (percentile(&ms, q) * 10.0).round() / 10.0;
            (kind, Latency { count: ms.len(), p: [p(0.5), p(0.95), p(0.99)] })
        })
        .collect();
    Ok(Measured {
        tabs,
        seconds: start.elapsed().as_secs(),
        kinds,
        errors: logs.into_iter().flat_map(|l| l.errors).collect(),
        new_tab_ms,
        peak_rss_mib: mimicgen_pipeline::memory::peak_rss_mib().map(f64::round),
        rss_mib: rss_mib().map(f64::round),
    })
}

/// Runs `mimicgen bench-serve`.
///
/// # Errors
/// A file that cannot be read or a server that cannot start.
pub fn run(args: &BenchServeArgs) -> anyhow::Result<()> {
    let file = match &args.file {
        Some(f) => f.clone(),
        None => mimicgen_pipeline::bundled::source_demos("stack")?,
    };
    if !args.json {
        outln!(
            "| tabs | open p50 / p99 ms | scrub p50 / p95 / p99 ms | preview p50 / p95 / p99 ms | try p50 / p99 ms | list p99 ms | requests | errors | new tab ms | peak RSS MiB |"
        );
        outln!("|---|---|---|---|---|---|---|---|---|---|");
    }
    for &tabs in &args.tabs {
        let m = measure(&file, tabs.max(1), args.seconds, args.run)?;
        if args.json {
            outln!("{}", m.json());
            continue;
        }
        let ps = |kind: &str, which: &[usize]| {
            let l = m.kind(kind);
            which.iter().map(|&i| l.and_then(|l| l.p.get(i)).map_or_else(|| "-".to_owned(), f64::to_string)).collect::<Vec<_>>().join(" / ")
        };
        let total: usize = m.kinds.iter().map(|(_, l)| l.count).sum();
        outln!(
            "| {tabs} | {} | {} | {} | {} | {} | {total} | {} | {} | {} |",
            ps("open", &[0, 2]),
            ps("scrub", &[0, 1, 2]),
            ps("preview", &[0, 1, 2]),
            ps("try", &[0, 2]),
            ps("list", &[2]),
            m.errors.len(),
            m.new_tab_ms,
            m.peak_rss_mib.map_or_else(|| "-".to_owned(), |v| v.to_string()),
        );
        if !m.errors.is_empty() {
            eprintln!("bench-serve: {tabs} tabs: first errors: {:?}", m.errors.iter().take(3).collect::<Vec<_>>());
        }
    }
    Ok(())
}
