//! The app's state and the one place that changes it: [`AppModel::apply`] takes a [`Command`] from
//! the UI (or a test) and returns the backend request it needs, if any; [`AppModel::on_reply`]
//! takes the backend's answers. Nothing here draws, reads files or waits.
//!
//! One `match` over every [`Command`] and one over every reply, each read best whole (the screens' own state lives in `annotation`, `run_state` and the
//! `*_ui` modules); about a quarter of the file is its tests.

use std::collections::BTreeMap;

pub use mimicgen_run::CameraConfig;
use mimicgen_run::RunConfig;
pub use mimicgen_run::SpecOverrides;

use crate::annotation::Annotation;
pub use crate::command::{Command, Screen};
use crate::protocol::{DoctorUpdate, Listing, LoadedFile, OpenedRun, PreviewRequest, PreviewView, Reply, Request, RunUpdate, Welcome};
pub use crate::run_state::{DoctorState, RunForm, RunState, SideBySide, nearest_success};

/// What the preview screen shows and asks for.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewState {
    /// Run seed (the one `mimicgen generate --seed` takes).
    pub seed: u64,
    /// Attempt index: which of the run's scenes.
    pub index: u64,
    /// The source demo forced per subtask (`None`: the selection strategy picks).
    pub sources: Vec<Option<usize>>,
    /// Objects moved by hand in the top-down view: (x, y) per object name.
    pub moved: BTreeMap<String, [f64; 2]>,
    /// The last preview the backend sent.
    pub view: Option<PreviewView>,
    /// Task variant the scenes come from (the run form's, or a re-run run's).
    pub variant: Option<String>,
    /// Spec fields over the task spec's (the run form's, or a re-run run's).
    pub spec: SpecOverrides,
}

impl Default for PreviewState {
    fn default() -> Self {
        Self { seed: 1, index: 0, sources: Vec::new(), moved: BTreeMap::new(), view: None, variant: None, spec: SpecOverrides::default() }
    }
}

/// The app's state.
#[derive(Debug, Default)]
pub struct AppModel {
    /// The open file.
    pub file: Option<LoadedFile>,
    /// The demo shown.
    pub selected: usize,
    /// Camera images of a demo of the open file (its index; empty without cameras).
    pub images: (usize, Vec<crate::protocol::CameraView>),
    /// The time cursor (a step of the shown demo).
    pub cursor: usize,
    /// The subtask end the keyboard moves.
    pub boundary: usize,
    /// The annotation: subtask ends and segment starts per demo, with undo.
    pub annotation: Annotation,
    /// Playing the shown demo.
    pub playing: bool,
    /// What the backend is doing, if anything.
    pub busy: Option<String>,
    /// The last thing that went wrong (names file and field), shown until the next success.
    pub error: Option<String>,
    /// The last thing that went right.
    pub status: String,
    /// The screen shown.
    pub screen: Screen,
    /// The preview screen's state.
    pub preview: PreviewState,
    /// Requests sent and not yet answered.
    pub in_flight: usize,
    /// Where the 3D view streams, once open.
    pub viewer: Option<String>,
    /// Progress of a long request: units done and in all.
    pub progress: Option<(usize, usize)>,
    /// The run form.
    pub run_form: RunForm,
    /// The last run started from the app.
    pub run: Option<RunState>,
    /// A finished run shown beside the current one (coverage of two datasets side by side).
    pub compare: Option<OpenedRun>,
    /// The file browser, while it is open: the directory it shows.
    pub browser: Option<Listing>,
    /// Whether the file browser was asked for (it opens when the listing arrives).
    pub browsing: bool,
    /// The attempt of the run selected in the table.
    pub selected_attempt: Option<u64>,
    /// Whether the 3D view stays on the selected attempt (else it follows the run's latest).
    pub stay_on_selected: bool,
    /// Two attempts re-run to be seen side by side.
    pub side_by_side: Option<SideBySide>,
    /// What the backend said of itself when it connected.
    pub welcome: Welcome,
    /// Whether "Save as" may replace an existing file.
    pub save_overwrite: bool,
    /// The run doctor.
    pub doctor: DoctorState,
    /// In a two-arm file, the arm annotated: its views are the file's `demos`, its annotation
    /// `annotation`.
    pub arm: usize,
    /// In a two-arm file, every arm's annotation but the one annotated (whose slot is empty).
    pub arm_annotations: Vec<Annotation>,
}

impl AppModel {
    /// A run's subtask `k` in words: `subtask 2`, or for a two-arm file, whose runs number arm 1's
    /// subtasks after arm 0's, `robot1 subtask 0`.
    #[must_use]
    pub fn subtask_name(&self, k: usize) -> String {
        let arms = self.file.as_ref().map_or(&[][..], |f| f.arms.as_slice());
        let mut first = 0;
        for arm in arms {
            // An arm's subtasks: one more than the signals that end them.
            let count = arm.signal_names.len() + 1;
            if k < first + count {
                return format!("{} subtask {}", arm.name, k - first);
            }
            first += count;
        }
        format!("subtask {k}")
    }

    /// Each arm's subtask ends of every demo as annotated (the arm shown: its edits so far), for a
    /// two-arm file.
    fn all_arm_ends(&self) -> Vec<BTreeMap<String, Vec<usize>>> {
        let arms = self.file.as_ref().map_or(0, |f| f.arms.len());
        (0..arms)
            .map(|k| {
                let annotation = if k == self.arm { &self.annotation } else { self.arm_annotations.get(k).unwrap_or(&self.annotation) };
                annotation.marks.ends.clone()
            })
            .collect()
    }

    /// The demo shown, if a file is open.
    #[must_use]
    pub fn demo(&self) -> Option<&crate::protocol::DemoView> {
        self.file.as_ref().and_then(|f| f.demos.get(self.selected))
    }

    /// Arm `arm`'s ends of the shown demo (a two-arm file's; the annotated arm's are
    /// [`AppModel::demo_ends`]).
    #[must_use]
    pub fn arm_ends(&self, arm: usize) -> Vec<usize> {
        let Some(demo) = self.demo() else { return Vec::new() };
        if arm == self.arm {
            return self.annotation.ends(&demo.name);
        }
        self.arm_annotations.get(arm).map(|a| a.ends(&demo.name)).unwrap_or_default()
    }

    /// The ends of the shown demo.
    #[must_use]
    pub fn demo_ends(&self) -> Vec<usize> {
        self.demo().map(|d| self.annotation.ends(&d.name)).unwrap_or_default()
    }

    /// Whether transit to subtask `k` is planned, and how near its object the segment starts
    /// (m), as a run from the form would have them: the form's spec fields over the file's spec.
    #[must_use]
    pub fn approach(&self, k: usize) -> (bool, f64) {
        let file = self.file.as_ref();
        let spec = &self.run_form.spec;
        // As `SpecOverrides::apply` reads them: the last value given for all subtasks or for `k`.
        fn last<T: Copy>(values: &[mimicgen_run::Scoped<T>], k: usize) -> Option<T> {
            values.iter().rev().find(|s| s.subtask.is_none_or(|j| j == k)).map(|s| s.value)
        }
        let planned = last(&spec.transit, k).map(|t| t == mimicgen_engine::spec::Transit::Plan);
        let approach_m = last(&spec.approach_m, k);
        (
            planned.unwrap_or_else(|| file.and_then(|f| f.planned.get(k).copied()).unwrap_or(false)),
            approach_m.or_else(|| file.and_then(|f| f.approach_m.get(k).copied())).unwrap_or(0.1),
        )
    }

    /// The marked segment starts of the shown demo (one per subtask, `None` where unmarked).
    #[must_use]
    pub fn demo_starts(&self) -> Vec<Option<usize>> {
        self.demo().map(|d| self.annotation.starts(&d.name)).unwrap_or_default()
    }

    /// A new run: no attempt selected or side by side, the 3D view following.
    fn forget_attempts(&mut self) {
        self.selected_attempt = None;
        self.stay_on_selected = false;
        self.side_by_side = None;
    }

    /// Applies a command; returns the backend request it needs.
    pub fn apply(&mut self, command: Command) -> Option<Request> {
        let request = self.apply_command(command);
        if request.is_some() {
            self.in_flight += 1;
        }
        request
    }

    /// The preview request for the current state, if a file is open.
    fn preview_request(&mut self, execute: bool) -> Option<Request> {
        let file = self.file.as_ref()?;
        self.preview.sources.resize(file.subtask_objects.len(), None);
        let p = &self.preview;
        self.busy = Some(format!("{} attempt {} (seed {})", if execute { "trying" } else { "planning" }, p.index, p.seed));
        let arm_ends = self.all_arm_ends();
        Some(Request::Preview(Box::new(PreviewRequest {
            source: file.path.clone(),
            marks: self.annotation.marks.clone(),
            seed: p.seed,
            index: p.index,
            sources: p.sources.clone(),
            moved: p.moved.clone(),
            execute,
            variant: p.variant.clone(),
            spec: p.spec.clone(),
            arm_ends,
        })))
    }

    /// The request that executes attempt `index` of the last run as the run did (its seed, variant
    /// and spec fields; the open file's ends), or why it cannot.
    fn rerun_request(&self, index: u64) -> Result<PreviewRequest, String> {
        let run = self.run.as_ref().ok_or("no run")?;
        let open = self.file.as_ref().map(|f| f.path.clone());
        if run.config.source != open {
            return Err(format!(
                "this run was made from {}; open that file to re-run its attempts",
                run.config.source.as_ref().map_or_else(|| "an unknown source (no report)".to_owned(), |p| p.display().to_string())
            ));
        }
        let (Some(source), Some(seed)) = (open, run.config.seed) else { return Err("the run's seed is not known".to_owned()) };
        Ok(PreviewRequest {
            source,
            marks: self.annotation.marks.clone(),
            seed,
            index,
            sources: Vec::new(),
            moved: BTreeMap::new(),
            execute: true,
            variant: run.config.variant.clone(),
            spec: run.config.spec.clone(),
            arm_ends: self.all_arm_ends(),
        })
    }

    fn apply_command(&mut self, command: Command) -> Option<Request> {
        let len = self.demo().map_or(0, |d| d.len);
        match command {
            Command::Open(path) => {
                self.browsing = false;
                self.browser = None;
                self.images = (0, Vec::new());
                self.busy = Some(format!("opening {}", path.display()));
                return Some(Request::Open { path });
            }
            Command::SelectDemo(i) => {
                if self.file.as_ref().is_some_and(|f| i < f.demos.len()) && i != self.selected {
                    self.selected = i;
                    self.cursor = self.cursor.min(self.demo().map_or(0, |d| d.len.saturating_sub(1)));
                    self.playing = false;
                    let in_3d = self.viewer.is_some();
                    if in_3d {
                        self.busy = Some("sending the demo to the 3D view".to_owned());
                    }
                    return Some(Request::ShowDemo { demo: i, in_3d });
                }
            }
            Command::SetCursor(t) => self.cursor = t.min(len.saturating_sub(1)),
            Command::StepCursor(dt) => {
                let t = i64::try_from(self.cursor).unwrap_or(i64::MAX).saturating_add(dt).max(0);
                self.cursor = usize::try_from(t).unwrap_or_default().min(len.saturating_sub(1));
            }
            Command::SelectBoundary(b) => {
                if b < self.demo_ends().len() {
                    self.boundary = b;
                }
            }
            Command::SelectArm(k) => {
                let file = self.file.as_mut()?;
                let arm = file.arms.get(k)?.clone();
                if k != self.arm && k < self.arm_annotations.len() {
                    // The annotated arm's annotation goes back to its slot; arm k's comes out.
                    let mut current = std::mem::take(&mut self.annotation);
                    if let Some(slot) = self.arm_annotations.get_mut(self.arm) {
                        std::mem::swap(slot, &mut current);
                    }
                    if let Some(slot) = self.arm_annotations.get_mut(k) {
                        self.annotation = std::mem::take(slot);
                    }
                    (file.demos, file.signal_names, file.subtask_objects) = (arm.demos, arm.signal_names, arm.subtask_objects);
                    self.arm = k;
                    self.boundary = 0;
                    self.status = format!("annotating arm {k} ({})", arm.name);
                }
            }
            Command::SetEnd { subtask, end } => {
                let demo = self.file.as_ref()?.demos.get(self.selected)?;
                self.annotation.set_end(demo, subtask, end);
            }
            Command::SetStart { subtask, start } => {
                let demo = self.file.as_ref()?.demos.get(self.selected)?;
                self.annotation.set_start(demo, subtask, start);
            }
            Command::SetStartAtCursor => {
                let subtask = self.demo_ends().iter().take_while(|&&end| end <= self.cursor).count();
                return self.apply_command(Command::SetStart { subtask, start: Some(self.cursor) });
            }
            Command::SetEndAtCursor => {
                let subtask = self.boundary;
                return self.apply_command(Command::SetEnd { subtask, end: self.cursor + 1 });
            }
            Command::AcceptProposals => {
                let demo = self.file.as_ref()?.demos.get(self.selected)?;
                self.annotation.set_ends(demo, demo.proposals.iter().map(|p| p.end).collect());
            }
            Command::AcceptAllProposals => {
                for demo in self.file.iter().flat_map(|f| &f.demos) {
                    self.annotation.set_ends(demo, demo.proposals.iter().map(|p| p.end).collect());
                }
            }
            Command::Undo => {
                self.annotation.undo();
            }
            Command::Redo => {
                self.annotation.redo();
            }
            Command::Save(out) => {
                let file = self.file.as_ref()?;
                let (source, signal_names) = (file.path.clone(), file.signal_names.clone());
                if out == source {
                    self.error = Some(format!("{}: saving over the source file is not allowed; choose a new file", out.display()));
                    return None;
                }
                self.busy = Some(format!("saving {}", out.display()));
                if !file.arms.is_empty() {
                    let arms = file
                        .arms
                        .iter()
                        .enumerate()
                        .map(|(k, arm)| {
                            let annotation =
                                if k == self.arm { &self.annotation } else { self.arm_annotations.get(k).unwrap_or(&self.annotation) };
                            crate::protocol::ArmMarks { signal_names: arm.signal_names.clone(), ends: annotation.marks.ends.clone() }
                        })
                        .collect();
                    return Some(Request::SaveArms { source, out, arms, overwrite: self.save_overwrite });
                }
                let marks = self.annotation.marks.clone();
                return Some(Request::Save { source, out, marks, signal_names, overwrite: self.save_overwrite });
            }
            Command::SetSaveOverwrite(on) => self.save_overwrite = on,
            Command::TogglePlay => self.playing = !self.playing && len > 0,
            Command::Tick => {
                if self.playing {
                    if self.cursor + 1 >= len {
                        self.playing = false;
                    } else {
                        self.cursor += 1;
                    }
                }
            }
            Command::Show(screen) => {
                self.screen = screen;
                self.playing = false;
                if screen == Screen::Preview {
                    self.preview.variant.clone_from(&self.run_form.variant);
                    self.preview.spec.clone_from(&self.run_form.spec);
                    return self.preview_request(false);
                }
            }
            Command::SetPreviewSeed(seed) => {
                self.preview.seed = seed;
                self.preview.moved.clear();
                return self.preview_request(false);
            }
            Command::SetPreviewIndex(index) => {
                self.preview.index = index;
                self.preview.moved.clear();
                return self.preview_request(false);
            }
            Command::NextScene => {
                self.preview.index = self.preview.index.saturating_add(1);
                self.preview.moved.clear();
                return self.preview_request(false);
            }
            Command::MoveObject { name, xy } => {
                if xy.iter().all(|v| v.is_finite()) {
                    self.preview.moved.insert(name, xy);
                    return self.preview_request(false);
                }
            }
            Command::ResetObjects => {
                if !self.preview.moved.is_empty() {
                    self.preview.moved.clear();
                    return self.preview_request(false);
                }
            }
            Command::SetPreviewSource { subtask, demo } => {
                let num_demos = self.file.as_ref().map_or(0, |f| f.demos.len());
                if subtask < self.file.as_ref().map_or(0, |f| f.subtask_objects.len()) && demo.is_none_or(|d| d < num_demos) {
                    if self.preview.sources.len() <= subtask {
                        self.preview.sources.resize(subtask + 1, None);
                    }
                    if let Some(slot) = self.preview.sources.get_mut(subtask) {
                        *slot = demo;
                    }
                    return self.preview_request(false);
                }
            }
            Command::TryIt => return self.preview_request(true),
            Command::SetRunForm(form) => self.run_form = *form,
            Command::StartRun => {
                let file = self.file.as_ref()?;
                if self.run.as_ref().is_some_and(RunState::running) {
                    self.error = Some("a run is going: cancel it or wait for it to end".to_owned());
                    return None;
                }
                if self.annotation.dirty {
                    self.error = Some(format!(
                        "the subtask ends or starts have unsaved changes: save them (\"Save as\") and open the saved file first; a run reads the ends from {}",
                        file.path.display()
                    ));
                    return None;
                }
                let config = self.run_form.config(&file.path, file.two_arm_task());
                self.run = Some(RunState::new(config.clone()));
                self.forget_attempts();
                self.busy = Some("starting the run".to_owned());
                return Some(Request::Run(Box::new(config)));
            }
            Command::CancelRun => {
                let run = self.run.as_mut().filter(|r| r.running() && !r.cancelling)?;
                run.cancelling = true;
                return Some(Request::CancelRun);
            }
            Command::OpenCompare(path) => {
                self.busy = Some(format!("reading {} to compare", path.display()));
                return Some(Request::OpenCompare { path });
            }
            Command::CloseCompare => self.compare = None,
            Command::Browse(path) => {
                self.browsing = true;
                return Some(Request::ListDir { path });
            }
            Command::CloseBrowser => {
                self.browsing = false;
                self.browser = None;
            }
            Command::OpenRun(path) => {
                if self.run.as_ref().is_some_and(RunState::running) {
                    self.error = Some("a run is going: cancel it or wait for it to end".to_owned());
                    return None;
                }
                self.run = Some(RunState::new(RunConfig { out: path.clone(), source: None, ..RunConfig::default() }));
                self.forget_attempts();
                self.busy = Some(format!("reading the run {}", path.display()));
                return Some(Request::OpenRun { path });
            }
            Command::ReRun(index) => match self.rerun_request(index) {
                Ok(request) => {
                    self.preview.seed = request.seed;
                    self.preview.index = index;
                    self.preview.moved.clear();
                    self.preview.sources.clear();
                    self.preview.variant.clone_from(&request.variant);
                    self.preview.spec.clone_from(&request.spec);
                    self.screen = Screen::Preview;
                    return self.preview_request(true);
                }
                Err(e) => self.error = Some(e),
            },
            Command::SideBySide { failed, success } => {
                let rows = self.run.as_ref().map_or(&[][..], |r| &r.rows[..]);
                let nearest =
                    || rows.iter().find(|r| r.index == failed && !r.success).and_then(|f| nearest_success(rows, f)).map(|(r, _)| r.index);
                let Some(success) = success.or_else(nearest) else {
                    self.error = Some(format!("attempt {failed} is not a failure of the run with a success to compare it with"));
                    return None;
                };
                match (self.rerun_request(failed), self.rerun_request(success)) {
                    (Ok(a), Ok(b)) => {
                        self.side_by_side = Some(SideBySide { indices: [failed, success], views: None });
                        self.busy = Some(format!("re-running attempts {failed} and {success}"));
                        return Some(Request::SideBySide(Box::new([a, b])));
                    }
                    (Err(e), _) | (_, Err(e)) => self.error = Some(e),
                }
            }
            Command::CloseSideBySide => self.side_by_side = None,
            Command::SelectAttempt(index) => {
                self.selected_attempt = Some(index);
                self.stay_on_selected = true;
            }
            Command::FollowLatest(on) => self.stay_on_selected = !on && self.selected_attempt.is_some(),
            Command::ShowDoctor(shown) => self.doctor.shown = shown,
            Command::SetDoctor { budget, top } => (self.doctor.budget, self.doctor.top) = (budget.max(1), top.max(1)),
            Command::Diagnose => {
                if self.doctor.running {
                    self.error = Some("the doctor is at work: stop it or wait for it".to_owned());
                    return None;
                }
                let Some(run) = self.run.as_ref().filter(|r| r.report.is_some()) else {
                    self.error = Some("the doctor reads a finished run: run one, or open one (\"Open run\")".to_owned());
                    return None;
                };
                let request = Request::Doctor { run: run.config.out.clone(), budget: self.doctor.budget, top: self.doctor.top };
                let DoctorState { budget, top, .. } = self.doctor;
                self.doctor = DoctorState { running: true, shown: true, budget, top, ..DoctorState::default() };
                return Some(request);
            }
            Command::CancelDoctor => {
                if self.doctor.running {
                    return Some(Request::CancelDoctor);
                }
            }
            Command::UseSuggestion(trial) => {
                let t = self.doctor.diagnosis.as_ref().and_then(|d| d.trials.get(trial))?;
                let base = self
                    .run
                    .as_ref()
                    .and_then(|r| r.report.as_ref())
                    .map_or_else(|| self.run_form.spec.clone(), |r| r.spec_overrides.clone());
                self.run_form.spec = base.then(&t.suggestion.change);
                self.status = format!("run form: {} ({})", t.suggestion.what, t.suggestion.flags());
            }
            Command::Open3d(sink) => {
                self.file.as_ref()?;
                self.busy = Some("opening the 3D view".to_owned());
                return Some(Request::Open3d { sink, demo: self.selected });
            }
        }
        None
    }

    /// Takes a backend reply. A failed open keeps the file (and the annotation) that was open.
    pub fn on_reply(&mut self, reply: Reply) {
        if let Reply::Progress { what, done, total } = reply {
            self.busy = Some(format!("{what} ({done} of {total})"));
            self.progress = Some((done, total));
            return;
        }
        self.progress = None;
        if reply.ends_request() {
            self.in_flight = self.in_flight.saturating_sub(1);
            if self.in_flight == 0 {
                self.busy = None;
            }
        }
        match reply {
            Reply::Progress { .. } => {}
            Reply::RunAccepted => self.status = "run started".to_owned(),
            Reply::RunOpened => {}
            Reply::Compared(run) => {
                self.status = format!("comparing with {}", run.path.display());
                self.compare = Some(*run);
            }
            Reply::Listing(listing) => {
                if self.browsing {
                    self.browser = Some(*listing);
                }
            }
            Reply::Cancelling => self.status = "cancelling: finishing the attempts already decided".to_owned(),
            Reply::Welcome(welcome) => self.welcome = *welcome,
            Reply::Notice(notice) => self.error = Some(notice),
            Reply::Run(RunUpdate::Joined(config)) => {
                self.run = Some(RunState::new(*config));
                self.forget_attempts();
                self.screen = Screen::Generate;
                self.status = "watching the server's run".to_owned();
            }
            Reply::Run(update) => self.on_run_update(update),
            Reply::DoctorAccepted => self.status = "the doctor is reading the run".to_owned(),
            Reply::Doctor(update) => self.on_doctor_update(update),
            Reply::MoreDemos { path, demos, .. } => {
                let Some(file) = self.file.as_mut().filter(|f| f.path == path) else { return };
                self.annotation.add(&demos);
                file.demos.extend(demos);
                let (loaded, total) = (file.demos.len(), file.total_demos);
                if loaded < total {
                    self.busy = Some(format!("reading demos: {loaded} of {total}"));
                    self.progress = Some((loaded, total));
                } else {
                    self.status =
                        format!("opened {} ({total} demos of {})", file.prepared_from.as_ref().unwrap_or(&file.path).display(), file.task);
                }
            }
            Reply::Opened(file) => {
                self.annotation = Annotation::opened(&file.demos);
                self.arm = 0;
                self.arm_annotations = file.arms.iter().map(|arm| Annotation::opened(&arm.demos)).collect();
                if let Some(first) = self.arm_annotations.first_mut() {
                    *first = Annotation::default();
                }
                self.status = match &file.prepared_from {
                    Some(plain) => format!(
                        "opened {} ({} demos of {}), prepared by replay into {}",
                        plain.display(),
                        file.demos.len(),
                        file.task,
                        file.path.display()
                    ),
                    None => format!("opened {} ({} demos of {})", file.path.display(), file.demos.len(), file.task),
                };
                self.file = Some(*file);
                self.selected = 0;
                self.cursor = 0;
                self.boundary = 0;
                self.error = None;
                self.preview.sources.clear();
                self.preview.view = None;
                self.viewer = None;
                if let Some(file) = &self.file
                    && file.demos.len() < file.total_demos
                {
                    self.busy = Some(format!("reading demos: {} of {}", file.demos.len(), file.total_demos));
                    self.progress = Some((file.demos.len(), file.total_demos));
                }
            }
            Reply::Streaming { to } => {
                self.status = format!("3D view: streaming to {to}");
                self.viewer = Some(to);
                self.error = None;
            }
            Reply::Shown { what } => self.status = format!("showing {what}"),
            Reply::Images { demo, cameras } => self.images = (demo, cameras),
            Reply::Saved { out, demos } => {
                self.status = format!("saved the subtask ends of {demos} demos to {}", out.display());
                self.annotation.dirty = false;
                for annotation in &mut self.arm_annotations {
                    annotation.dirty = false;
                }
                self.error = None;
            }
            Reply::Previewed(view) => {
                self.status = match &view.executed {
                    Some(e) if e.success => format!("attempt {} (seed {}) succeeded in {} steps", view.index, view.seed, e.path.len()),
                    Some(e) => format!("attempt {} (seed {}) failed: {}", view.index, view.seed, e.failure.as_deref().unwrap_or("")),
                    None => format!("planned attempt {} (seed {}) of {} {}", view.index, view.seed, view.task, view.variant),
                };
                // Replies arrive in request order: a plan asked for after a "try it" replaces it.
                self.error = view.failure_3d.as_ref().map(|e| format!("sending the attempt to the 3D view: {e}"));
                self.preview.view = Some(*view);
            }
            Reply::SideBySide(views) => {
                let [a, b] = &*views;
                if let Some(pair) = self.side_by_side.as_mut().filter(|p| p.indices == [a.index, b.index]) {
                    self.status = format!("re-ran attempts {} and {}", pair.indices[0], pair.indices[1]);
                    pair.views = Some(views);
                }
            }
            Reply::Failed { what, error } => self.error = Some(format!("{what}: {error}")),
        }
    }
}

impl AppModel {
    fn on_doctor_update(&mut self, update: DoctorUpdate) {
        let doctor = &mut self.doctor;
        match update {
            DoctorUpdate::Started { suggestions, arms, attempts } => {
                doctor.suggestions = suggestions;
                doctor.attempts = attempts;
                doctor.progress = vec![(0, 0); arms];
            }
            DoctorUpdate::Attempt { arm, done, successes } => {
                if let Some(p) = doctor.progress.get_mut(arm) {
                    *p = (done, successes);
                }
            }
            DoctorUpdate::Finished(diagnosis) => {
                doctor.running = false;
                self.status = match diagnosis.best() {
                    Some(best) => format!("doctor: {} helps most ({:+.1} points)", best.suggestion.what, 100.0 * best.paired.difference),
                    None => format!("doctor: no change was shown to help on {} attempts", diagnosis.attempts),
                };
                doctor.diagnosis = Some(*diagnosis);
            }
            DoctorUpdate::Failed(error) => {
                doctor.running = false;
                self.error = Some(format!("the doctor stopped: {error}"));
                doctor.error = Some(error);
            }
        }
    }

    fn on_run_update(&mut self, update: RunUpdate) {
        let Some(run) = self.run.as_mut() else { return };
        match update {
            RunUpdate::Started { info, dimensions } => {
                if run.config.source.is_none() && !info.source.as_os_str().is_empty() {
                    run.config.source = Some(info.source.clone());
                    run.config.seed = Some(info.seed);
                    run.config.variant = Some(info.variant.clone());
                    run.config.spec.clone_from(&info.spec_overrides);
                }
                run.info = Some(*info);
                run.dimensions = dimensions;
            }
            RunUpdate::Attempt(row) => run.rows.push(*row),
            RunUpdate::Finished(report) => {
                self.status = format!(
                    "{} of {} attempts succeeded ({:.1} %){}; dataset {}",
                    report.successes,
                    report.attempts,
                    100.0 * report.generation_rate,
                    if report.cancelled { ", cancelled" } else { "" },
                    report.output
                );
                run.report = Some(*report);
            }
            RunUpdate::Failed(error) => {
                self.error = Some(format!("the run stopped: {error}"));
                run.error = Some(error);
            }
            RunUpdate::Joined(_) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{DemoView, LoadedFile};

    fn model(len: usize, ends: Vec<usize>) -> AppModel {
        let demo = DemoView {
            name: "demo_0".into(),
            len,
            gripper: vec![0.0; len],
            finger_width_m: None,
            eef_speed: vec![0.0; len],
            distances: BTreeMap::new(),
            signals: BTreeMap::new(),
            stored_ends: Some(ends),
            stored_starts: None,
            proposals: Vec::new(),
        };
        let mut m = AppModel::default();
        m.on_reply(Reply::Opened(Box::new(LoadedFile {
            variants: vec!["D0".into()],
            path: "f.hdf5".into(),
            prepared_from: None,
            total_demos: 1,
            task: "t".into(),
            signal_names: vec!["a".into(), "b".into()],
            subtask_objects: vec![Some("a".into()), Some("b".into())],
            approach_m: vec![0.1, 0.1],
            planned: vec![false, true],
            demos: vec![demo],
            arms: Vec::new(),
        })));
        m
    }

    #[test]
    fn ends_stay_ordered_and_leave_every_segment_room_for_its_signal() {
        let mut m = model(50, vec![10, 30]);
        m.apply(Command::SetEnd { subtask: 0, end: 0 });
        assert_eq!(m.demo_ends(), vec![2, 30]);
        m.apply(Command::SetEnd { subtask: 0, end: 45 });
        assert_eq!(m.demo_ends(), vec![28, 30]);
        m.apply(Command::SetEnd { subtask: 1, end: 80 });
        assert_eq!(m.demo_ends(), vec![28, 49]);
        m.apply(Command::Undo);
        m.apply(Command::Undo);
        assert_eq!(m.demo_ends(), vec![2, 30]);
        m.apply(Command::Redo);
        assert_eq!(m.demo_ends(), vec![28, 30]);
        // A new change clears what could be redone.
        m.apply(Command::SetEnd { subtask: 1, end: 40 });
        assert!(!m.annotation.can_redo());
    }

    #[test]
    fn a_start_marked_at_the_cursor_belongs_to_the_subtask_there_and_is_previewed_and_saved() {
        let mut m = model(50, vec![10, 30]);
        m.apply(Command::SetCursor(14));
        m.apply(Command::SetStartAtCursor);
        assert_eq!(m.demo_starts(), vec![None, Some(14), None]);
        m.apply(Command::SetCursor(45));
        m.apply(Command::SetStartAtCursor);
        assert_eq!(m.demo_starts(), vec![None, Some(14), Some(45)]);
        assert!(m.annotation.dirty);
        let Some(Request::Preview(p)) = m.apply(Command::Show(Screen::Preview)) else { panic!("no preview asked") };
        assert_eq!(p.marks.starts["demo_0"], vec![None, Some(14), Some(45)]);
        m.apply(Command::SetStart { subtask: 1, start: None });
        m.apply(Command::Undo);
        assert_eq!(m.demo_starts()[1], Some(14));
        let Some(Request::Save { marks, .. }) = m.apply(Command::Save("g.hdf5".into())) else { panic!("no save asked") };
        assert_eq!(marks.starts["demo_0"], vec![None, Some(14), Some(45)]);
        assert_eq!(m.apply(Command::StartRun), None, "unsaved starts keep a run from starting");
    }

    #[test]
    fn a_run_does_not_start_over_unsaved_ends() {
        let mut m = model(50, vec![10]);
        m.apply(Command::SetEnd { subtask: 0, end: 20 });
        assert_eq!(m.apply(Command::StartRun), None, "unsaved ends: the run would not read them");
        assert!(m.error.as_deref().is_some_and(|e| e.contains("unsaved")));
    }

    #[test]
    fn preview_commands_ask_for_the_scene_sources_and_ends_shown() {
        let mut m = model(50, vec![10]);
        m.apply(Command::SetEnd { subtask: 0, end: 20 });
        let Some(Request::Preview(p)) = m.apply(Command::Show(Screen::Preview)) else { panic!("no preview asked") };
        assert_eq!((p.seed, p.index, p.execute, p.marks.ends["demo_0"].clone()), (1, 0, false, vec![20]));
        let Some(Request::Preview(p)) = m.apply(Command::NextScene) else { panic!("no preview asked") };
        assert_eq!(p.index, 1);
        assert_eq!(m.apply(Command::SetPreviewSource { subtask: 0, demo: Some(3) }), None, "there is one demo");
        let Some(Request::Preview(p)) = m.apply(Command::SetPreviewSource { subtask: 1, demo: Some(0) }) else { panic!() };
        assert_eq!(p.sources, vec![None, Some(0)]);
        // Choosing subtask 0's source keeps the later subtasks' choices.
        let Some(Request::Preview(p)) = m.apply(Command::SetPreviewSource { subtask: 0, demo: Some(0) }) else { panic!() };
        assert_eq!(p.sources, vec![Some(0), Some(0)]);
        let Some(Request::Preview(p)) = m.apply(Command::TryIt) else { panic!("no try asked") };
        assert!(p.execute);
        assert_eq!(m.in_flight, 5);
        m.on_reply(Reply::Failed { what: "w".into(), error: "e".into() });
        assert!(m.busy.is_some(), "busy until every request is answered");
    }

    #[test]
    fn previews_use_the_forms_spec_and_reruns_the_runs() {
        let mut m = model(50, vec![10]);
        let noise = |v: f64| SpecOverrides { action_noise: vec![mimicgen_run::Scoped::all(v)], ..SpecOverrides::default() };
        m.apply(Command::SetRunForm(Box::new(RunForm { spec: noise(0.01), variant: Some("D1".into()), ..RunForm::default() })));
        let Some(Request::Preview(p)) = m.apply(Command::Show(Screen::Preview)) else { panic!("no preview asked") };
        assert_eq!((p.spec.clone(), p.variant.as_deref()), (noise(0.01), Some("D1")));
        let Some(Request::Run(config)) = m.apply(Command::StartRun) else { panic!("no run started") };
        assert_eq!(config.spec, noise(0.01));
        // The form changes after the run: a re-run still makes the run's attempt.
        m.apply(Command::SetRunForm(Box::new(RunForm { spec: noise(0.2), ..RunForm::default() })));
        m.apply(Command::SelectAttempt(3));
        assert!(m.stay_on_selected);
        let Some(Request::Preview(p)) = m.apply(Command::ReRun(3)) else { panic!("no re-run asked") };
        assert_eq!((p.index, p.execute, p.spec.clone(), p.variant.as_deref()), (3, true, noise(0.01), Some("D1")));
        let Some(Request::SideBySide(pair)) = m.apply(Command::SideBySide { failed: 3, success: Some(4) }) else { panic!("no pair asked") };
        assert_eq!(pair.iter().map(|p| (p.index, p.spec.clone())).collect::<Vec<_>>(), [(3, noise(0.01)), (4, noise(0.01))]);
        m.apply(Command::FollowLatest(true));
        assert!(!m.stay_on_selected);
        // A new run forgets the selection and the pair.
        m.on_reply(Reply::Run(RunUpdate::Failed("stopped".into())));
        m.apply(Command::StartRun);
        assert_eq!((m.selected_attempt, m.side_by_side.is_none()), (None, true));
    }

    #[test]
    fn a_streaming_file_is_browsable_from_its_first_part() {
        let mut m = model(50, vec![10]);
        let mut file = m.file.clone().unwrap();
        file.path = "big.hdf5".into();
        file.total_demos = 2;
        m.in_flight = 1;
        let second = DemoView { name: "demo_1".into(), ..file.demos[0].clone() };
        m.on_reply(Reply::Opened(Box::new(file)));
        assert_eq!((m.in_flight, m.file.as_ref().unwrap().demos.len()), (1, 1), "the first part does not end the request");
        assert!(m.busy.as_deref().is_some_and(|b| b.contains("1 of 2")));
        m.apply(Command::SetEnd { subtask: 0, end: 12 });
        m.on_reply(Reply::MoreDemos { path: "other.hdf5".into(), demos: vec![second.clone()], last: false });
        assert_eq!(m.file.as_ref().unwrap().demos.len(), 1, "parts of another file are ignored");
        m.on_reply(Reply::MoreDemos { path: "big.hdf5".into(), demos: vec![second], last: true });
        assert_eq!((m.in_flight, m.file.as_ref().unwrap().demos.len()), (0, 2));
        assert_eq!(m.annotation.marks.ends["demo_1"], vec![10]);
        assert_eq!(m.annotation.marks.ends["demo_0"], vec![12], "edits made while it streamed are kept");
        assert!(m.busy.is_none());
    }

    #[test]
    fn saving_over_the_source_is_refused_and_playback_stops_at_the_end() {
        let mut m = model(5, vec![2]);
        assert_eq!(m.apply(Command::Save("f.hdf5".into())), None);
        assert!(m.error.as_deref().is_some_and(|e| e.contains("f.hdf5")));
        assert!(matches!(m.apply(Command::Save("g.hdf5".into())), Some(Request::Save { .. })));
        m.apply(Command::TogglePlay);
        for _ in 0..10 {
            m.apply(Command::Tick);
        }
        assert_eq!((m.cursor, m.playing), (4, false));
    }

    /// A two-arm file: each arm has its own ends; switching arms keeps each arm's edits, and
    /// saving sends both arms' ends with their own signal names.
    #[test]
    fn two_arms_keep_their_own_ends_and_save_together() {
        use crate::protocol::{ArmFile, DemoView};
        let view = |len: usize, end: usize| DemoView {
            name: "demo_0".into(),
            len,
            gripper: vec![0.0; len],
            finger_width_m: None,
            eef_speed: vec![0.0; len],
            distances: BTreeMap::new(),
            signals: BTreeMap::new(),
            stored_ends: Some(vec![end]),
            stored_starts: None,
            proposals: Vec::new(),
        };
        let arm = |name: &str, signal: &str, end: usize| ArmFile {
            name: name.into(),
            signal_names: vec![signal.into()],
            subtask_objects: vec![Some("pot".into()), Some("pot".into())],
            demos: vec![view(50, end)],
        };
        let arms = vec![arm("robot0", "grasp_handle0", 20), arm("robot1", "grasp_handle1", 30)];
        let mut m = AppModel::default();
        m.on_reply(Reply::Opened(Box::new(LoadedFile {
            variants: vec!["D0".into()],
            path: "two.hdf5".into(),
            prepared_from: None,
            total_demos: 1,
            task: "two_arm_lift".into(),
            signal_names: arms[0].signal_names.clone(),
            subtask_objects: arms[0].subtask_objects.clone(),
            approach_m: vec![0.1, 0.1],
            planned: vec![false, false],
            demos: arms[0].demos.clone(),
            arms,
        })));
        assert_eq!((m.demo_ends(), m.arm_ends(1)), (vec![20], vec![30]));
        m.apply(Command::SelectArm(1));
        assert_eq!((m.arm, m.demo_ends(), m.arm_ends(0)), (1, vec![30], vec![20]));
        assert_eq!(m.file.as_ref().unwrap().signal_names, ["grasp_handle1"]);
        m.apply(Command::SetEnd { subtask: 0, end: 33 });
        m.apply(Command::SelectArm(0));
        assert_eq!((m.demo_ends(), m.arm_ends(1)), (vec![20], vec![33]), "arm 1's edit kept");
        let Some(Request::SaveArms { arms, .. }) = m.apply(Command::Save("out.hdf5".into())) else { panic!("no two-arm save") };
        assert_eq!(arms[0].signal_names, ["grasp_handle0"]);
        assert_eq!(arms[1].ends["demo_0"], [33]);
        assert_eq!(arms[0].ends["demo_0"], [20]);
    }
}
