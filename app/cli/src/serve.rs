//! `mimicgen serve`: the inspection app for a browser (see `mimicgen-server`).

use std::net::IpAddr;
use std::path::PathBuf;

use mimicgen_server::{ServeOptions, Server};

/// A line for the person who started the server; a closed stdout does not stop the server.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// The app in a browser, for machines without a display (a server, a cluster node over SSH).
#[derive(clap::Args)]
#[command(after_help = "\
Over SSH: run it on the server, then on your own machine
  ssh -L 8080:localhost:8080 user@server
and open http://localhost:8080/ there.

Examples:
  mimicgen serve                                  # the bundled Stack D0 demos, files under .
  mimicgen serve data/my_sources.hdf5 --root data # open a file; paths stay inside data/
  mimicgen serve --port 9000                      # another port (on 127.0.0.1)
  mimicgen serve --host 0.0.0.0                   # on every interface: the printed URL carries a token

Safety: it binds 127.0.0.1 by default and then answers only to localhost names; any other
--host needs a token (random per start unless --token), checked on every request. Every path
a request names stays inside --root; an existing output is replaced only when asked for.
There is no TLS: reach it through an SSH tunnel (or a TLS proxy) from other machines.

Many people at once: each tab has its own open file, preview and 3D recording (up to 100 tabs);
a run belongs to the server, and every tab watches it. A plain robomimic file is prepared into
the server's cache (tabs name it @prepared/...). Each file a tab opens is first read in a child
process (`mimicgen vet`), so a damaged file that crashes the HDF5 library is refused and the
server goes on.")]
pub struct ServeArgs {
    /// Source demos to open in every new tab (default: the bundled Stack D0 demos, when inside --root).
    file: Option<PathBuf>,
    /// Port to listen on (0: any free port).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Address to listen on. Anything but loopback requires the token.
    #[arg(long, default_value = "127.0.0.1")]
    host: IpAddr,
    /// The folder the file browser shows and every path stays inside (default: the working directory).
    #[arg(long, default_value = ".")]
    root: PathBuf,
    /// The token the URL carries (default: random per start, and only when --host is not loopback).
    #[arg(long)]
    token: Option<String>,
    /// Where the browser app's files are (default: $MIMICGEN_WEB_DIR, else ~/.cache/mimicgen/web,
    /// where `scripts/build_web.sh` puts them).
    #[arg(long, value_name = "DIR")]
    web_dir: Option<PathBuf>,
    /// No 3D view (else the Rerun web viewer of the rerun-sdk wheel is served beside the app).
    #[arg(long)]
    no_viewer: bool,
}

/// Serves until interrupted.
///
/// # Errors
/// The server's, whole.
pub fn run(args: ServeArgs) -> Result<(), mimicgen_server::ServerError> {
    let file = args.file.or_else(|| {
        let bundled = mimicgen_pipeline::bundled::source_demos("stack").ok()?;
        let root = args.root.canonicalize().ok()?;
        bundled.canonicalize().ok().filter(|b| b.starts_with(&root))
    });
    let options = ServeOptions {
        file,
        host: args.host,
        port: args.port,
        root: args.root,
        token: args.token,
        web_dir: args.web_dir,
        rerun: (!args.no_viewer).then(mimicgen_viz::viewer_path),
        vet: mimicgen_server::Vetter::this_binary(),
    };
    let server = Server::bind(options)?;
    let url = server.url();
    say!("mimicgen serve: open {url}");
    if !server.local_addr().ip().is_loopback() {
        say!("  (the token in it is checked on every request; anyone with the URL can use the app)");
    }
    say!("  from another machine: ssh -L {0}:localhost:{0} <this host>, then open the URL there", server.local_addr().port());
    if !server.has_viewer() {
        say!("  no 3D view on this server");
    }
    server.run();
    Ok(())
}
