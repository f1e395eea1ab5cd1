//! The browser's end of the backend: a WebSocket to the server that served the page, reconnecting
//! when it drops (a lost SSH tunnel, a restarted server); the server then greets the tab again and
//! replays the run it owns.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use mimicgen_ui::protocol::{ClientMessage, Reply, Request, ServerMessage};
use mimicgen_ui::{Transport, egui};
use wasm_bindgen::prelude::*;
use web_sys::{CloseEvent, MessageEvent, WebSocket};

/// Seconds between reconnection attempts.
const RETRY_S: f64 = 2.0;

/// The socket's event handlers, kept alive as long as the socket.
type Callbacks = Vec<Closure<dyn FnMut(JsValue)>>;

/// What the socket's callbacks share with the app.
#[derive(Default)]
struct Shared {
    replies: VecDeque<Reply>,
    /// Requests made before the socket opened.
    pending: Vec<String>,
    open: bool,
    closed_at_ms: Option<f64>,
}

/// The WebSocket transport.
pub struct Socket {
    url: String,
    ws: Option<WebSocket>,
    shared: Rc<RefCell<Shared>>,
    ctx: egui::Context,
    next_id: u64,
    _callbacks: Callbacks,
}

fn now_ms() -> f64 {
    js_sys::Date::now()
}

/// `ws://` or `wss://` to `/ws` on the page's own host, with the token.
fn socket_url(token: Option<&str>) -> String {
    let location = web_sys::window().map(|w| w.location());
    let host = location.as_ref().and_then(|l| l.host().ok()).unwrap_or_default();
    let secure = location.as_ref().and_then(|l| l.protocol().ok()).is_some_and(|p| p == "https:");
    let scheme = if secure { "wss" } else { "ws" };
    match token {
        Some(token) => format!("{scheme}://{host}/ws?token={}", String::from(js_sys::encode_uri_component(token))),
        None => format!("{scheme}://{host}/ws"),
    }
}

impl Socket {
    /// Connects to the page's server; `ctx` repaints whenever something arrives.
    pub fn connect(token: Option<&str>, ctx: egui::Context) -> Self {
        let url = socket_url(token);
        let shared = Rc::new(RefCell::new(Shared::default()));
        let (ws, callbacks) = open(&url, &shared, &ctx);
        Self { url, ws, shared, ctx, next_id: 1, _callbacks: callbacks }
    }

    fn reconnect_if_due(&mut self) {
        let due = self.shared.borrow().closed_at_ms.is_some_and(|t| now_ms() - t >= RETRY_S * 1000.0);
        if due {
            self.shared.borrow_mut().closed_at_ms = None;
            let (ws, callbacks) = open(&self.url, &self.shared, &self.ctx);
            self.ws = ws;
            self._callbacks = callbacks;
        }
    }
}

/// Opens a socket whose callbacks fill `shared`.
fn open(url: &str, shared: &Rc<RefCell<Shared>>, ctx: &egui::Context) -> (Option<WebSocket>, Callbacks) {
    let ws = match WebSocket::new(url) {
        Ok(ws) => ws,
        Err(e) => {
            let mut s = shared.borrow_mut();
            s.replies.push_back(Reply::Failed { what: "connecting to the server".to_owned(), error: format!("{e:?}") });
            s.closed_at_ms = Some(now_ms());
            return (None, Vec::new());
        }
    };
    let on_open = {
        let (shared, ctx, ws) = (Rc::clone(shared), ctx.clone(), ws.clone());
        Closure::<dyn FnMut(JsValue)>::new(move |_| {
            let pending = {
                let mut s = shared.borrow_mut();
                s.open = true;
                std::mem::take(&mut s.pending)
            };
            for text in pending {
                let _ = ws.send_with_str(&text);
            }
            ctx.request_repaint();
        })
    };
    let on_message = {
        let (shared, ctx) = (Rc::clone(shared), ctx.clone());
        Closure::<dyn FnMut(JsValue)>::new(move |event: JsValue| {
            let Some(data) = event.dyn_ref::<MessageEvent>().map(MessageEvent::data) else { return };
            // Text: JSON; binary (camera images): ServerMessage::from_binary's frame.
            let decoded = match (data.as_string(), data.dyn_ref::<js_sys::ArrayBuffer>()) {
                (Some(text), _) => crate::decode(&text),
                (None, Some(buffer)) => ServerMessage::from_binary(&js_sys::Uint8Array::new(buffer).to_vec()),
                (None, None) => return,
            };
            let reply = match decoded {
                Ok(message) => message.reply,
                Err(e) => Reply::Failed { what: "reading the server's reply".to_owned(), error: e },
            };
            shared.borrow_mut().replies.push_back(reply);
            ctx.request_repaint();
        })
    };
    let on_close = {
        let (shared, ctx) = (Rc::clone(shared), ctx.clone());
        Closure::<dyn FnMut(JsValue)>::new(move |event: JsValue| {
            let reason = event.dyn_ref::<CloseEvent>().map(CloseEvent::reason).filter(|r| !r.is_empty());
            let mut s = shared.borrow_mut();
            let was_open = std::mem::replace(&mut s.open, false);
            if was_open || s.closed_at_ms.is_none() {
                let error = match reason {
                    Some(r) => format!("the connection closed: {r}; reconnecting"),
                    None => "the connection to the server is lost; reconnecting".to_owned(),
                };
                s.replies.push_back(Reply::Failed { what: "talking to the server".to_owned(), error });
            }
            s.closed_at_ms = Some(now_ms());
            drop(s);
            ctx.request_repaint();
        })
    };
    ws.set_binary_type(web_sys::BinaryType::Arraybuffer);
    ws.set_onopen(Some(on_open.as_ref().unchecked_ref()));
    ws.set_onmessage(Some(on_message.as_ref().unchecked_ref()));
    ws.set_onclose(Some(on_close.as_ref().unchecked_ref()));
    (Some(ws), vec![on_open, on_message, on_close])
}

impl Transport for Socket {
    fn send(&mut self, request: Request) {
        let message = ClientMessage { id: self.next_id, request };
        self.next_id += 1;
        let Some(text) = crate::encode(&message) else { return };
        let open = self.shared.borrow().open;
        if open && self.ws.as_ref().is_some_and(|ws| ws.send_with_str(&text).is_ok()) {
            return;
        }
        self.shared.borrow_mut().pending.push(text);
    }

    fn try_replies(&mut self) -> Vec<Reply> {
        self.reconnect_if_due();
        if self.shared.borrow().closed_at_ms.is_some() {
            // A frame when the next retry is due.
            self.ctx.request_repaint_after(std::time::Duration::from_secs_f64(RETRY_S));
        }
        self.shared.borrow_mut().replies.drain(..).collect()
    }
}
