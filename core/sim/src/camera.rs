//! Camera observations as robosuite makes them: MuJoCo's own renderer, offscreen through EGL (on a
//! machine with no display and no GPU, Mesa's software EGL device), robosuite's cameras by name
//! (`agentview`, `robot0_eye_in_hand`, ...), robosuite's default visual options, images upright
//! (robomimic flips robosuite's OpenGL-ordered frames; datasets hold them upright).
//!
//! Rendering uses the scene with its image textures (physics runs on a copy without them, see
//! [`crate::mjcf_edit::without_image_textures`]). A GL context belongs to the thread that made it,
//! so each thread that renders keeps its own renderer (made on its first frame).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::sync::Arc;

pub use mimicgen_engine::image::{ImageStream, Pixels};
use mujoco_rs::prelude::*;

use crate::offscreen::Offscreen;
pub use crate::offscreen::RenderOptions;
use crate::{Scene, SimError};

/// The largest image side rendered (the offscreen buffer is made the image's size).
pub const MAX_SIZE: usize = 4096;

pub use mimicgen_run::CameraConfig;

/// A scene's cameras, ready to render any state of it.
#[derive(Debug)]
pub struct Cameras {
    model: Arc<MjModel>,
    config: CameraConfig,
    ids: Vec<usize>,
    origin: String,
    how: RenderOptions,
}

/// One thread's renderer and the data it renders from.
struct ThreadRenderer {
    model: *const MjModel,
    size: (usize, usize, bool),
    how: RenderOptions,
    data: MjData<Arc<MjModel>>,
    renderer: Offscreen,
}

thread_local! {
    static RENDERER: RefCell<Option<ThreadRenderer>> = const { RefCell::new(None) };
}

/// What went wrong rendering (the GL context, most likely).
fn render_error(origin: &str, what: &str, e: &impl std::fmt::Debug) -> SimError {
    SimError::Render {
        file: origin.to_owned(),
        reason: format!(
            "{what}: {e:?} (offscreen rendering needs EGL: Debian's libegl1, libegl-mesa0 and libgl1-mesa-dri, \
             which scripts/setup.sh installs)"
        ),
    }
}

impl Cameras {
    /// The cameras `config` names on `scene` (compiled again with its textures).
    ///
    /// # Errors
    /// [`SimError::Compile`] if the textured scene does not compile, [`SimError::MissingName`]
    /// for a camera the scene lacks (the message lists those it has), [`SimError::Render`] for
    /// a size of zero or above [`MAX_SIZE`].
    pub fn new(scene: &Scene, config: CameraConfig) -> Result<Self, SimError> {
        let origin = format!("{} (cameras)", scene.origin);
        if config.names.is_empty() {
            return Err(SimError::Render { file: origin, reason: "no camera named (e.g. agentview,robot0_eye_in_hand)".to_owned() });
        }
        // The offscreen buffer holds every camera's image side by side and no more: MuJoCo
        // resolves all of it every frame.
        let buffer_width = config.width.saturating_mul(config.names.len());
        let xml = with_visual(&crate::mjcf_edit::with_arena(&scene.xml, "32M"), buffer_width, config.height, config.fast);
        let model = crate::scene::compile_mjcf(&xml).map_err(|reason| SimError::Compile { file: origin.clone(), reason })?;
        let ncam = usize::try_from(model.ffi().ncam).unwrap_or_default();
        let names: Vec<String> = (0..ncam).filter_map(|i| model.id_to_name(MjtObjBase::mjOBJ_CAMERA, i).map(str::to_owned)).collect();
        let ids = config
            .names
            .iter()
            .map(|name| {
                model.name_to_id(MjtObjBase::mjOBJ_CAMERA, name).ok_or_else(|| SimError::MissingName {
                    file: scene.origin.clone(),
                    kind: format!("camera (it has {})", names.join(", ")),
                    name: name.clone(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if config.width == 0 || config.height == 0 || buffer_width > MAX_SIZE || config.height > MAX_SIZE {
            return Err(SimError::Render {
                file: origin,
                reason: format!(
                    "camera size {}x{} (height x width) must be between 1x1 and {MAX_SIZE}x{MAX_SIZE}, the {} cameras' \
                     images side by side at most {MAX_SIZE} wide",
                    config.height,
                    config.width,
                    config.names.len()
                ),
            });
        }
        let how = RenderOptions { reflection: config.reflection, ..RenderOptions::default() };
        Ok(Self { model: Arc::new(model), config, ids, origin, how })
    }

    /// These cameras drawn another way (benchmarks: `mimicgen bench-render`).
    #[must_use]
    pub fn with_render_options(mut self, how: RenderOptions) -> Self {
        self.how = how;
        self
    }

    /// The configuration rendered.
    #[must_use]
    pub fn config(&self) -> &CameraConfig {
        &self.config
    }

    /// The observation keys written, in order: `<camera>_image` (and `<camera>_depth`) per camera.
    #[must_use]
    pub fn keys(&self) -> Vec<String> {
        let mut keys = Vec::new();
        for name in &self.config.names {
            keys.push(format!("{name}_image"));
            if self.config.depth {
                keys.push(format!("{name}_depth"));
            }
        }
        keys
    }

    /// Empty streams for `steps` steps, to [`Cameras::capture`] into.
    #[must_use]
    pub fn streams(&self, steps: usize) -> BTreeMap<String, ImageStream> {
        let (h, w) = (self.config.height, self.config.width);
        let mut out = BTreeMap::new();
        for name in &self.config.names {
            out.insert(
                format!("{name}_image"),
                ImageStream { shape: [h, w, 3], pixels: Pixels::Rgb(Vec::with_capacity(steps * h * w * 3)) },
            );
            if self.config.depth {
                out.insert(
                    format!("{name}_depth"),
                    ImageStream { shape: [h, w, 1], pixels: Pixels::Depth(Vec::with_capacity(steps * h * w)) },
                );
            }
        }
        out
    }

    /// Renders every camera in the state `physics` is in (positions, and the mocap bodies the
    /// flattened state does not hold) and appends the frames to `streams` (from
    /// [`Cameras::streams`]).
    ///
    /// # Errors
    /// [`SimError::Render`] when the GL context cannot be made or used; [`SimError::State`] when
    /// `physics` is not of this scene.
    pub fn capture(&self, physics: &MjData<Arc<MjModel>>, streams: &mut BTreeMap<String, ImageStream>) -> Result<(), SimError> {
        RENDERER.with_borrow_mut(|slot| {
            let size = (self.config.width, self.config.height, self.config.depth);
            let key = Arc::as_ptr(&self.model);
            if !slot.as_ref().is_some_and(|r| r.model == key && r.size == size && r.how == self.how) {
                *slot = None; // free the old context before making a new one
                // robosuite's offscreen renderer: MuJoCo's default options with the collision
                // geoms (group 0) hidden, the visual ones (group 1) shown.
                let mut opts = MjvOption::default();
                opts.geomgroup[0] = 0;
                opts.geomgroup[1] = 1;
                let renderer = Offscreen::new(&self.model, opts, (size.0, size.1), self.ids.len(), self.how)
                    .map_err(|e| render_error(&self.origin, "making the offscreen renderer", &e))?;
                *slot = Some(ThreadRenderer { model: key, size, how: self.how, data: MjData::new(Arc::clone(&self.model)), renderer });
            }
            let Some(r) = slot.as_mut() else { return Ok(()) };
            copy_kinematic_state(physics, &mut r.data).map_err(|reason| SimError::State { file: self.origin.clone(), reason })?;
            r.data.forward_kinematics();
            let frame =
                r.renderer.render(&mut r.data, &self.ids, self.config.depth).map_err(|e| render_error(&self.origin, "rendering", &e))?;
            for (i, name) in self.config.names.iter().enumerate() {
                if let Some(ImageStream { pixels: Pixels::Rgb(out), .. }) = streams.get_mut(&format!("{name}_image")) {
                    frame.rgb_into(i, out);
                }
                if let Some(ImageStream { pixels: Pixels::Depth(out), .. }) = streams.get_mut(&format!("{name}_depth")) {
                    frame.depth_into(i, out);
                }
            }
            Ok(())
        })
    }
}

/// `xml` with its offscreen buffer `width` x `height` (`<visual><global offwidth offheight>`), and
/// without multisampling when `fast`.
fn with_visual(xml: &str, width: usize, height: usize, fast: bool) -> String {
    let quality = if fast { r#"<quality offsamples="0"/>"# } else { "" };
    let global = format!(r#"<global offwidth="{width}" offheight="{height}"/>{quality}"#);
    if let Some(at) = xml.find("<visual>") {
        let at = at + "<visual>".len();
        return format!("{}{global}{}", &xml[..at], &xml[at..]);
    }
    match xml.find("<mujoco").and_then(|start| xml[start..].find('>').map(|end| start + end + 1)) {
        Some(at) => format!("{}<visual>{global}</visual>{}", &xml[..at], &xml[at..]),
        None => xml.to_owned(),
    }
}

/// Copies joint positions and mocap poses (all rendering reads) between two data of models with
/// the same structure.
fn copy_kinematic_state(from: &MjData<Arc<MjModel>>, to: &mut MjData<Arc<MjModel>>) -> Result<(), String> {
    if from.qpos().len() != to.qpos().len() || from.mocap_pos().len() != to.mocap_pos().len() {
        return Err(format!(
            "the simulator has {} positions and {} mocap bodies, the rendered scene {} and {}",
            from.qpos().len(),
            from.mocap_pos().len(),
            to.qpos().len(),
            to.mocap_pos().len()
        ));
    }
    to.qpos_mut().copy_from_slice(from.qpos());
    to.mocap_pos_mut().copy_from_slice(from.mocap_pos());
    to.mocap_quat_mut().copy_from_slice(from.mocap_quat());
    Ok(())
}
