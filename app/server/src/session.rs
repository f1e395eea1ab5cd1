//! The server's tabs and its run. Each tab has a backend worker of its own, on its own thread: its
//! open file, annotations, preview and 3D recording are its own, and a slow request in one tab
//! does not hold up another. The run is the server's: one at a time, started from any tab, and its
//! updates go to every tab and are kept, so a tab that connects later (or reconnects after a lost
//! tunnel) is greeted with the whole run so far; any tab may cancel it.

use std::collections::BTreeMap;
use std::sync::mpsc::{Receiver, Sender, SyncSender, TrySendError, channel, sync_channel};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use mimicgen_backend::{Notify, RunSlot, Vetter, Worker};
use mimicgen_ui::protocol::{ClientMessage, Frame, Reply, Request, RunUpdate, ServerMessage, Welcome};

use crate::root::{PreparedNames, Root};

/// Messages queued for one tab before it is dropped as too slow to read them.
const QUEUE: usize = 4096;

/// A connected tab.
pub type ClientId = u64;

/// The tabs and the run's log.
#[derive(Default)]
struct Clients {
    next: ClientId,
    /// What to send each tab.
    queues: BTreeMap<ClientId, SyncSender<Frame>>,
    /// Each tab's requests, to its worker.
    inboxes: BTreeMap<ClientId, Sender<ClientMessage>>,
    /// The server's run so far, as sent: `Joined` then every update.
    run_log: Vec<String>,
    /// The prepared copies' folder as messages may spell it; a tab reads the alias instead.
    prepared: PreparedNames,
}

impl Clients {
    /// `text` with the prepared copies' folder named by its alias.
    fn scrub(&self, text: String) -> String {
        self.prepared.hide(text)
    }

    /// Queues `text` for `client`; a tab whose queue is full is dropped (its socket then closes).
    fn send(&mut self, client: ClientId, frame: Frame) {
        let frame = match frame {
            Frame::Text(text) => Frame::Text(self.scrub(text)),
            binary @ Frame::Binary(_) => binary,
        };
        if let Some(queue) = self.queues.get(&client)
            && let Err(TrySendError::Full(_)) = queue.try_send(frame)
        {
            eprintln!("mimicgen serve: tab {client} reads too slowly; closing its connection");
            self.queues.remove(&client);
            self.inboxes.remove(&client);
        }
    }

    fn broadcast(&mut self, text: &str, except: Option<ClientId>) {
        let clients: Vec<ClientId> = self.queues.keys().copied().filter(|c| Some(*c) != except).collect();
        for client in clients {
            self.send(client, Frame::Text(text.to_owned()));
        }
    }
}

/// A reply as its frame: camera images binary, the rest JSON text.
fn frame(id: Option<u64>, reply: Reply) -> Frame {
    ServerMessage { id, reply }.to_frame().unwrap_or_else(|error| {
        // Replies are plain data; this would be a bug. The tab still hears of it.
        Frame::Text(encode(id, Reply::Failed { what: "sending a reply".to_owned(), error }))
    })
}

/// A reply as JSON text (everything but images).
fn encode(id: Option<u64>, reply: Reply) -> String {
    serde_json::to_string(&ServerMessage { id, reply }).unwrap_or_default()
}

/// What every tab's worker shares.
struct Shared {
    clients: Mutex<Clients>,
    welcome: Welcome,
    root: Root,
    /// The server's 3D viewer (a gRPC URL).
    viewer: Option<String>,
    runs: RunSlot,
    /// Held while a tab starts a run, so two tabs cannot both announce one.
    starting: Mutex<()>,
    vetter: Option<Vetter>,
}

impl Shared {
    fn clients(&self) -> MutexGuard<'_, Clients> {
        // A panic while holding the lock leaves plain data behind: go on with it.
        self.clients.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The server's tabs and run.
#[derive(Clone)]
pub struct Session {
    shared: Arc<Shared>,
}

/// Why a tab could not join.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum JoinError {
    /// As many tabs are open as the server takes.
    Full(usize),
    /// The OS would not start the tab's worker thread.
    Thread(String),
}

impl std::fmt::Display for JoinError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Full(limit) => write!(f, "this server has {limit} tabs open, its limit; close one and reload"),
            Self::Thread(e) => write!(f, "cannot start the tab's backend: {e}"),
        }
    }
}

impl Session {
    /// A session whose paths are confined to `root`, whose 3D views stream to `viewer` (a gRPC
    /// URL), whose tabs are greeted with `welcome`, and whose user-chosen files are first read
    /// by `vetter` in a child process.
    #[must_use]
    pub fn new(root: Root, viewer: Option<String>, welcome: Welcome, vetter: Option<Vetter>) -> Self {
        // Whatever a message says of the prepared copies' folder (a run's report, an error), the
        // tab reads the alias.
        let prepared = root.prepared_names().clone();
        let shared = Shared {
            clients: Mutex::new(Clients { prepared, ..Clients::default() }),
            welcome,
            root,
            viewer,
            runs: RunSlot::default(),
            starting: Mutex::new(()),
            vetter,
        };
        Self { shared: Arc::new(shared) }
    }

    /// A new tab, unless `limit` tabs are open: its id and the queue of what to send it, starting
    /// with the greeting and the run so far; its worker thread is started.
    ///
    /// # Errors
    /// [`JoinError`].
    pub fn join(&self, limit: usize) -> Result<(ClientId, Receiver<Frame>), JoinError> {
        let (queue, receiver) = sync_channel(QUEUE);
        let (inbox, requests) = channel::<ClientMessage>();
        let mut clients = self.shared.clients();
        if clients.queues.len() >= limit {
            return Err(JoinError::Full(limit));
        }
        let id = clients.next + 1;
        let shared = Arc::clone(&self.shared);
        std::thread::Builder::new()
            .name(format!("mimicgen-serve-tab-{id}"))
            .spawn(move || answer(id, &requests, &shared))
            .map_err(|e| JoinError::Thread(e.to_string()))?;
        clients.next = id;
        let _ = queue.try_send(frame(None, Reply::Welcome(Box::new(self.shared.welcome.clone()))));
        for text in &clients.run_log {
            let _ = queue.try_send(Frame::Text(clients.scrub(text.clone())));
        }
        clients.queues.insert(id, queue);
        clients.inboxes.insert(id, inbox);
        Ok((id, receiver))
    }

    /// A tab has gone: its worker ends after the request it is answering.
    pub fn leave(&self, client: ClientId) {
        let mut clients = self.shared.clients();
        clients.queues.remove(&client);
        clients.inboxes.remove(&client);
    }

    /// Queues a tab's request for its worker.
    pub fn request(&self, client: ClientId, message: ClientMessage) {
        if let Some(inbox) = self.shared.clients().inboxes.get(&client) {
            let _ = inbox.send(message);
        }
    }

    /// How many tabs are connected.
    #[must_use]
    pub fn tabs(&self) -> usize {
        self.shared.clients().queues.len()
    }
}

/// A tab's worker thread: answers the tab's requests in order, with a worker of its own.
fn answer(client: ClientId, requests: &Receiver<ClientMessage>, shared: &Arc<Shared>) {
    // The request being answered: its progress replies carry its id.
    let current: Arc<Mutex<Option<u64>>> = Arc::new(Mutex::new(None));
    let notify: Notify = {
        let (shared, current) = (Arc::clone(shared), Arc::clone(&current));
        Arc::new(move |reply| {
            let asked = *current.lock().unwrap_or_else(PoisonError::into_inner);
            if let Some(id) = asked {
                let frame = frame(Some(id), shared.root.filter(reply));
                shared.clients().send(client, frame);
            }
        })
    };
    let run_notify: Notify = {
        let shared = Arc::clone(shared);
        Arc::new(move |reply| {
            let text = encode(None, reply);
            let mut clients = shared.clients();
            clients.run_log.push(text.clone());
            clients.broadcast(&text, None);
        })
    };
    let mut worker =
        Worker::new(notify, None).with_run_notify(run_notify).with_run_slot(shared.runs.clone()).with_vetter(shared.vetter.clone());
    for ClientMessage { id, request } in requests {
        *current.lock().unwrap_or_else(PoisonError::into_inner) = Some(id);
        let reply = match shared.root.confine(request, shared.viewer.as_deref()) {
            Err(error) => {
                eprintln!("mimicgen serve: tab {client}: refused: {error}");
                Reply::Failed { what: "checking the request".to_owned(), error }
            }
            Ok(Request::Run(config)) => start_run(client, *config, &mut worker, shared),
            Ok(request) => shared.root.filter(worker.handle_guarded(request)),
        };
        shared.clients().send(client, frame(Some(id), reply));
        *current.lock().unwrap_or_else(PoisonError::into_inner) = None;
    }
}

/// Starts the server's run from `client`'s tab: every other tab starts watching it before its
/// first update.
fn start_run(client: ClientId, config: mimicgen_run::RunConfig, worker: &mut Worker, shared: &Shared) -> Reply {
    let _starting = shared.starting.lock().unwrap_or_else(PoisonError::into_inner);
    let starts = !shared.runs.running();
    if starts {
        let mut shown = config.clone();
        shown.source = shown.source.map(|p| shared.root.outward(&p));
        let joined = encode(None, Reply::Run(RunUpdate::Joined(Box::new(shown))));
        let mut clients = shared.clients();
        clients.run_log = vec![joined.clone()];
        clients.broadcast(&joined, Some(client));
    }
    let reply = shared.root.filter(worker.handle_guarded(Request::Run(Box::new(config))));
    if starts && let Reply::Failed { error, .. } = &reply {
        let failed = encode(None, Reply::Run(RunUpdate::Failed(error.clone())));
        let mut clients = shared.clients();
        clients.run_log.push(failed.clone());
        clients.broadcast(&failed, Some(client));
    }
    reply
}
