//! Camera observations as robosuite makes them: MuJoCo's own renderer, offscreen through EGL (on a
//! machine with no display and no GPU, Mesa's software EGL device), robosuite's cameras by name
//! (`agentview`, `robot0_eye_in_hand`, ...), robosuite's default visual options, images upright
//! (robomimic flips robosuite's OpenGL-ordered frames; datasets hold them upright).
//!
//! Rendering uses the scene with its image textures (physics runs on a copy without them, see
//! [`crate::compose::without_image_textures`]). A GL context belongs to the thread that made it,
//! so each thread that renders keeps its own renderer (made on its first frame).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::sync::Arc;

pub use mimicgen_engine::image::{ImageStream, Pixels};
use mujoco_rs::prelude::*;
use mujoco_rs::renderer::MjRenderer;

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
}

/// One thread's renderer and the data it renders from.
struct ThreadRenderer {
    model: *const MjModel,
    size: (usize, usize, bool),
    data: MjData<Arc<MjModel>>,
    renderer: MjRenderer,
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
        // The offscreen buffer at the image size: MuJoCo clears and resolves all of it every frame,
        // which on a software renderer costs more than drawing an 84 x 84 image.
        let xml = with_visual(&crate::compose::with_arena(&scene.xml, "32M"), config.width, config.height, config.fast);
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
        if config.width == 0 || config.height == 0 || config.width > MAX_SIZE || config.height > MAX_SIZE {
            return Err(SimError::Render {
                file: origin,
                reason: format!(
                    "camera size {}x{} (height x width) must be between 1x1 and {MAX_SIZE}x{MAX_SIZE}",
                    config.height, config.width
                ),
            });
        }
        Ok(Self { model: Arc::new(model), config, ids, origin })
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
            if !slot.as_ref().is_some_and(|r| r.model == key && r.size == size) {
                *slot = None; // free the old context before making a new one
                // robosuite's offscreen renderer: MuJoCo's default options with the collision
                // geoms (group 0) hidden, the visual ones (group 1) shown.
                let mut opts = MjvOption::default();
                opts.geomgroup[0] = 0;
                opts.geomgroup[1] = 1;
                let renderer = MjRenderer::builder()
                    .opts(opts)
                    .width(u32::try_from(size.0).unwrap_or(u32::MAX))
                    .height(u32::try_from(size.1).unwrap_or(u32::MAX))
                    .rgb(true)
                    .depth(size.2)
                    .build(&self.model)
                    .map_err(|e| render_error(&self.origin, "making the offscreen renderer", &e))?;
                *slot = Some(ThreadRenderer { model: key, size, data: MjData::new(Arc::clone(&self.model)), renderer });
            }
            let Some(r) = slot.as_mut() else { return Ok(()) };
            copy_kinematic_state(physics, &mut r.data).map_err(|reason| SimError::State { file: self.origin.clone(), reason })?;
            r.data.forward_kinematics();
            for (name, &id) in self.config.names.iter().zip(&self.ids) {
                r.renderer.set_camera(MjvCamera::new_fixed(id));
                r.renderer.sync_data(&mut r.data).map_err(|e| render_error(&self.origin, "updating the scene", &e))?;
                r.renderer.render().map_err(|e| render_error(&self.origin, "rendering", &e))?;
                if let (Some(rgb), Some(ImageStream { pixels: Pixels::Rgb(out), .. })) =
                    (r.renderer.rgb_flat(), streams.get_mut(&format!("{name}_image")))
                {
                    out.extend_from_slice(rgb);
                }
                if let (Some(depth), Some(ImageStream { pixels: Pixels::Depth(out), .. })) =
                    (r.renderer.depth_flat(), streams.get_mut(&format!("{name}_depth")))
                {
                    out.extend(depth.iter().map(|&metres| depth_buffer_value(metres, &self.model)));
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

/// The renderer's depth in metres back to the OpenGL depth-buffer value robosuite returns.
fn depth_buffer_value(metres: f32, model: &MjModel) -> f32 {
    let extent = model.stat().extent as f32;
    let (near, far) = (model.vis().map.znear * extent, model.vis().map.zfar * extent);
    if metres <= 0.0 { 0.0 } else { ((1.0 - near / metres) / (1.0 - near / far)).clamp(0.0, 1.0) }
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
