//! The server's one backend, shared by every tab: a worker thread that answers requests in the
//! order they come (from any tab), the tabs connected now, and the run the server owns. A request's
//! replies go to the tab that asked; a run's updates go to every tab and are kept, so a tab that
//! connects later (or reconnects after a lost tunnel) is greeted with the whole run so far.

use std::collections::BTreeMap;
use std::sync::mpsc::{Receiver, Sender, SyncSender, TrySendError, channel, sync_channel};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use mimicgen_backend::{Notify, Worker};
use mimicgen_ui::protocol::{ClientMessage, Reply, Request, RunUpdate, ServerMessage, Welcome};

use crate::root::Root;

/// Messages queued for one tab before it is dropped as too slow to read them.
const QUEUE: usize = 4096;

/// A connected tab.
pub type ClientId = u64;

/// The tabs and the run's log.
#[derive(Default)]
struct Clients {
    next: ClientId,
    queues: BTreeMap<ClientId, SyncSender<String>>,
    /// The server's run so far, as sent: `Joined` then every update.
    run_log: Vec<String>,
}

impl Clients {
    /// Queues `text` for `client`; a tab whose queue is full is dropped (its socket then closes).
    fn send(&mut self, client: ClientId, text: String) {
        if let Some(queue) = self.queues.get(&client)
            && let Err(TrySendError::Full(_)) = queue.try_send(text)
        {
            eprintln!("mimicgen serve: tab {client} reads too slowly; closing its connection");
            self.queues.remove(&client);
        }
    }

    fn broadcast(&mut self, text: &str, except: Option<ClientId>) {
        let clients: Vec<ClientId> = self.queues.keys().copied().filter(|c| Some(*c) != except).collect();
        for client in clients {
            self.send(client, text.to_owned());
        }
    }
}

fn encode(id: Option<u64>, reply: Reply) -> String {
    serde_json::to_string(&ServerMessage { id, reply }).unwrap_or_else(|e| {
        // Replies are plain data; this would be a bug. The tab still hears of it.
        let reply = Reply::Failed { what: "sending a reply".to_owned(), error: e.to_string() };
        serde_json::to_string(&ServerMessage { id, reply }).unwrap_or_default()
    })
}

/// The shared backend.
#[derive(Clone)]
pub struct Session {
    inbox: Sender<(ClientId, ClientMessage)>,
    clients: Arc<Mutex<Clients>>,
    welcome: Arc<Welcome>,
}

fn lock(clients: &Mutex<Clients>) -> MutexGuard<'_, Clients> {
    // A panic while holding the lock leaves plain data behind: go on with it.
    clients.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Session {
    /// Starts the backend's worker thread; paths are confined to `root`, 3D views stream to
    /// `viewer` (a gRPC URL), and every tab is greeted with `welcome`.
    ///
    /// # Errors
    /// The OS's, when the thread cannot start.
    pub fn start(root: Root, viewer: Option<String>, welcome: Welcome) -> std::io::Result<Self> {
        let clients = Arc::new(Mutex::new(Clients::default()));
        let (inbox, requests) = channel::<(ClientId, ClientMessage)>();
        let worker_clients = Arc::clone(&clients);
        std::thread::Builder::new()
            .name("mimicgen-serve-backend".to_owned())
            .spawn(move || answer(&requests, &worker_clients, &root, viewer.as_deref()))?;
        Ok(Self { inbox, clients, welcome: Arc::new(welcome) })
    }

    /// A new tab: its id and the queue of what to send it, starting with the greeting and the run.
    #[must_use]
    pub fn join(&self) -> (ClientId, Receiver<String>) {
        let (queue, receiver) = sync_channel(QUEUE);
        let mut clients = lock(&self.clients);
        clients.next += 1;
        let id = clients.next;
        let _ = queue.try_send(encode(None, Reply::Welcome(Box::new((*self.welcome).clone()))));
        for text in &clients.run_log {
            let _ = queue.try_send(text.clone());
        }
        clients.queues.insert(id, queue);
        (id, receiver)
    }

    /// A tab has gone.
    pub fn leave(&self, client: ClientId) {
        lock(&self.clients).queues.remove(&client);
    }

    /// Queues a tab's request for the backend.
    pub fn request(&self, client: ClientId, message: ClientMessage) {
        let _ = self.inbox.send((client, message));
    }

    /// How many tabs are connected.
    #[must_use]
    pub fn tabs(&self) -> usize {
        lock(&self.clients).queues.len()
    }
}

/// The backend thread: answers requests one at a time, routing replies.
fn answer(requests: &Receiver<(ClientId, ClientMessage)>, clients: &Arc<Mutex<Clients>>, root: &Root, viewer: Option<&str>) {
    // The request being answered: where its progress replies go.
    let current: Arc<Mutex<Option<(ClientId, u64)>>> = Arc::new(Mutex::new(None));
    let notify: Notify = {
        let (clients, current) = (Arc::clone(clients), Arc::clone(&current));
        Arc::new(move |reply| {
            let asker = *current.lock().unwrap_or_else(PoisonError::into_inner);
            if let Some((client, id)) = asker {
                lock(&clients).send(client, encode(Some(id), reply));
            }
        })
    };
    let run_notify: Notify = {
        let clients = Arc::clone(clients);
        Arc::new(move |reply| {
            let text = encode(None, reply);
            let mut clients = lock(&clients);
            clients.run_log.push(text.clone());
            clients.broadcast(&text, None);
        })
    };
    let mut worker = Worker::new(notify, None).with_run_notify(run_notify);
    for (client, ClientMessage { id, request }) in requests {
        *current.lock().unwrap_or_else(PoisonError::into_inner) = Some((client, id));
        let reply = match root.confine(request, viewer) {
            Err(error) => {
                eprintln!("mimicgen serve: tab {client}: refused: {error}");
                Reply::Failed { what: "checking the request".to_owned(), error }
            }
            Ok(request) => {
                // Every other tab starts watching the run before its first update.
                let starts_run = match &request {
                    Request::Run(config) if !worker.running() => {
                        let joined = encode(None, Reply::Run(RunUpdate::Joined(config.clone())));
                        let mut clients = lock(clients);
                        clients.run_log = vec![joined.clone()];
                        clients.broadcast(&joined, Some(client));
                        true
                    }
                    _ => false,
                };
                let opening = matches!(request, Request::Open { .. });
                let reply = root.filter(worker.handle_guarded(request));
                if opening && let Reply::Opened(file) = &reply {
                    // The open file is the server's, not the tab's: the other tabs' previews and
                    // 3D views now work on this one, which they are told.
                    let notice = Reply::Notice(format!(
                        "another tab opened {}: this server has one open file, so previews and the 3D view now use it; open yours again to go on",
                        file.path.display()
                    ));
                    lock(clients).broadcast(&encode(None, notice), Some(client));
                }
                if starts_run && let Reply::Failed { error, .. } = &reply {
                    let failed = encode(None, Reply::Run(RunUpdate::Failed(error.clone())));
                    let mut clients = lock(clients);
                    clients.run_log.push(failed.clone());
                    clients.broadcast(&failed, Some(client));
                }
                reply
            }
        };
        lock(clients).send(client, encode(Some(id), reply));
        *current.lock().unwrap_or_else(PoisonError::into_inner) = None;
    }
}
