//! Just enough HTTP/1.1 for the app's page: one request head per connection (read with a size and
//! time limit), plain responses, and the checks every request passes (host, token, origin).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// The largest request head read.
const MAX_HEAD: usize = 16 * 1024;
/// How long a client may take to send its request head.
const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

/// A request head.
#[derive(Debug, Clone)]
pub struct Head {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path, without the query.
    pub path: String,
    /// The query (after `?`), possibly empty.
    pub query: String,
    /// Header names (lower case) and values.
    pub headers: Vec<(String, String)>,
    /// The head's raw bytes (for a proxy).
    pub raw: Vec<u8>,
    /// Bytes read after the head (the start of a body).
    pub rest: Vec<u8>,
}

impl Head {
    /// The first header called `name` (lower case).
    #[must_use]
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// The query parameter `name`, percent-decoded.
    #[must_use]
    pub fn param(&self, name: &str) -> Option<String> {
        self.query.split('&').find_map(|pair| {
            let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
            (k == name).then(|| percent_decode(v))
        })
    }

    /// The cookie `name`.
    #[must_use]
    pub fn cookie(&self, name: &str) -> Option<String> {
        self.header("cookie")?.split(';').find_map(|c| {
            let (k, v) = c.trim().split_once('=')?;
            (k == name).then(|| v.to_owned())
        })
    }

    /// Whether it asks for a WebSocket.
    #[must_use]
    pub fn is_websocket(&self) -> bool {
        self.header("upgrade").is_some_and(|u| u.eq_ignore_ascii_case("websocket"))
    }
}

fn percent_decode(s: &str) -> String {
    let hex = |h: &[u8]| std::str::from_utf8(h).ok().and_then(|h| u8::from_str_radix(h, 16).ok());
    let mut rest = s.as_bytes();
    let mut out = Vec::with_capacity(rest.len());
    while let Some((&first, tail)) = rest.split_first() {
        rest = tail;
        match (first, tail) {
            (b'%', [h, l, after @ ..]) if let Some(b) = hex(&[*h, *l]) => {
                out.push(b);
                rest = after;
            }
            (b'+', _) => out.push(b' '),
            (b, _) => out.push(b),
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Why a request head could not be read.
#[derive(Debug)]
pub enum HeadError {
    /// The connection closed or failed (nothing to answer).
    Closed,
    /// Too large, too slow or not HTTP: answered with this status and message.
    Bad(u16, &'static str),
}

/// Reads one request head from `stream`.
///
/// # Errors
/// [`HeadError`].
pub fn read_head(stream: &mut TcpStream) -> Result<Head, HeadError> {
    let started = Instant::now();
    let _ = stream.set_read_timeout(Some(HEAD_TIMEOUT));
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0_u8; 2048];
    loop {
        let mut headers = [httparse::EMPTY_HEADER; 64];
        let mut request = httparse::Request::new(&mut headers);
        match request.parse(&buf) {
            Ok(httparse::Status::Complete(len)) => {
                let target = request.path.unwrap_or("/");
                let (path, query) = target.split_once('?').unwrap_or((target, ""));
                let head = Head {
                    method: request.method.unwrap_or("GET").to_owned(),
                    path: path.to_owned(),
                    query: query.to_owned(),
                    headers: request
                        .headers
                        .iter()
                        .map(|h| (h.name.to_ascii_lowercase(), String::from_utf8_lossy(h.value).into_owned()))
                        .collect(),
                    // httparse's length is of the bytes it parsed, so within `buf`.
                    raw: buf.get(..len).unwrap_or_default().to_vec(),
                    rest: buf.get(len..).unwrap_or_default().to_vec(),
                };
                return Ok(head);
            }
            Ok(httparse::Status::Partial) => {}
            Err(httparse::Error::TooManyHeaders) => return Err(HeadError::Bad(431, "too many headers")),
            Err(_) => return Err(HeadError::Bad(400, "not an HTTP request")),
        }
        if buf.len() >= MAX_HEAD {
            return Err(HeadError::Bad(431, "request head too large"));
        }
        if started.elapsed() > HEAD_TIMEOUT {
            return Err(HeadError::Bad(408, "request head too slow"));
        }
        match stream.read(&mut chunk) {
            Ok(0) => return Err(HeadError::Closed),
            #[allow(clippy::indexing_slicing, reason = "Read::read returns at most the buffer's length")]
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                return Err(HeadError::Bad(408, "request head too slow"));
            }
            Err(_) => return Err(HeadError::Closed),
        }
    }
}

/// Headers every response carries: no sniffing, no referrer (the token is in the page's URL), and
/// a content policy that lets the page run its own scripts and WebAssembly and talk only to this
/// server.
const SECURITY_HEADERS: &str =
    "X-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\nCross-Origin-Resource-Policy: same-origin\r\n";

/// The page's content policy.
pub const PAGE_POLICY: &str = "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; connect-src 'self'; \
    style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; frame-src 'self'; frame-ancestors 'self'; object-src 'none'; base-uri 'none'";

/// Writes a whole response and closes the connection's write side.
///
/// # Errors
/// The socket's.
pub fn respond(stream: &mut TcpStream, status: u16, content_type: &str, extra_headers: &str, body: &[u8]) -> std::io::Result<()> {
    let reason = match status {
        200 => "OK",
        204 => "No Content",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        431 => "Request Header Fields Too Large",
        502 => "Bad Gateway",
        503 => "Service Unavailable",
        _ => "Error",
    };
    let head = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nConnection: close\r\n{SECURITY_HEADERS}{extra_headers}\r\n",
        body.len()
    );
    stream.write_all(head.as_bytes())?;
    stream.write_all(body)?;
    stream.flush()
}

/// A plain-text error response.
pub fn refuse(stream: &mut TcpStream, status: u16, message: &str) {
    let _ = respond(stream, status, "text/plain; charset=utf-8", "", format!("{message}\n").as_bytes());
}

/// Whether `a` and `b` are equal, in time that depends only on their lengths.
#[must_use]
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    let mut diff = u8::from(a.len() != b.len());
    for i in 0..a.len().max(b.len()) {
        diff |= a.get(i).copied().unwrap_or(0) ^ b.get(i).copied().unwrap_or(0xff);
    }
    diff == 0
}

/// The host part of a `Host` header or an origin's authority (`[::1]:8080` -> `[::1]`).
fn host_of(authority: &str) -> &str {
    if authority.starts_with('[') {
        return authority.split_once(']').map_or(authority, |(h, _)| &authority[..=h.len()]);
    }
    authority.rsplit_once(':').map_or(authority, |(h, _)| h)
}

/// Whether `host` (a `Host` header) names this machine's loopback: what a browser sends when it
/// reaches a server bound to 127.0.0.1 directly or through an SSH tunnel. Another name pointing at
/// 127.0.0.1 is how a web page would reach the server by DNS rebinding, so it is refused.
#[must_use]
pub fn is_loopback_host(host: &str) -> bool {
    matches!(host_of(host).to_ascii_lowercase().as_str(), "localhost" | "127.0.0.1" | "[::1]")
}

/// Whether a WebSocket's `Origin` is the page this server served: the same scheme-less authority
/// as its `Host`. Any other page (another site open in the same browser) is refused.
#[must_use]
pub fn origin_matches(origin: Option<&str>, host: Option<&str>) -> bool {
    let (Some(origin), Some(host)) = (origin, host) else { return false };
    let authority = origin.strip_prefix("http://").or_else(|| origin.strip_prefix("https://"));
    authority.is_some_and(|a| a.eq_ignore_ascii_case(host))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_compare_whole() {
        assert!(constant_time_eq(b"abc", b"abc"));
        assert!(!constant_time_eq(b"abc", b"abd"));
        assert!(!constant_time_eq(b"abc", b"ab"));
        assert!(!constant_time_eq(b"", b"a"));
        assert!(constant_time_eq(b"", b""));
    }

    #[test]
    fn only_loopback_names_and_the_page_s_own_origin_pass() {
        for ok in ["localhost:8080", "127.0.0.1:8080", "[::1]:8080", "LOCALHOST", "127.0.0.1"] {
            assert!(is_loopback_host(ok), "{ok}");
        }
        for bad in ["evil.example:8080", "127.0.0.1.evil.example", "10.0.0.1:8080", "[::2]:80"] {
            assert!(!is_loopback_host(bad), "{bad}");
        }
        assert!(origin_matches(Some("http://127.0.0.1:8080"), Some("127.0.0.1:8080")));
        assert!(!origin_matches(Some("http://evil.example"), Some("127.0.0.1:8080")));
        assert!(!origin_matches(Some("http://127.0.0.1:8081"), Some("127.0.0.1:8080")));
        assert!(!origin_matches(None, Some("127.0.0.1:8080")));
        assert!(!origin_matches(Some("null"), Some("127.0.0.1:8080")));
    }

    #[test]
    fn query_parameters_and_cookies_are_read() {
        let head = Head {
            method: "GET".into(),
            path: "/".into(),
            query: "a=1&token=x%2By+z".into(),
            headers: vec![("cookie".into(), "other=1; mimicgen_token=abc".into())],
            raw: Vec::new(),
            rest: Vec::new(),
        };
        assert_eq!(head.param("token").as_deref(), Some("x+y z"));
        assert_eq!(head.param("b"), None);
        assert_eq!(head.cookie("mimicgen_token").as_deref(), Some("abc"));
    }

    #[test]
    fn percent_escapes_cut_short_or_not_hex_are_kept_as_written() {
        for (query, decoded) in
            [("%41%4", "A%4"), ("%", "%"), ("%zz%41", "%zzA"), ("a%2", "a%2"), ("%e2%9c%93", "\u{2713}"), ("%ff", "\u{fffd}")]
        {
            assert_eq!(percent_decode(query), decoded, "{query}");
        }
    }
}
