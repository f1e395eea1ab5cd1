//! One thread's offscreen OpenGL renderer: an EGL pbuffer context (on a machine with no display
//! and no GPU, Mesa's software device), MuJoCo's rendering context and scene, and the frame
//! buffer every camera of a state is drawn into side by side.
//!
//! What a frame costs on a software renderer is geometry, not pixels (BENCHMARKS.md, "Where a
//! frame's time goes"): robosuite's Panda alone has 168 000 visual triangles, every one processed
//! on the CPU for every camera. So this renderer
//! - draws every camera of a state into one buffer, one tile each, and reads it back once: one
//!   multisample resolve and one pipeline flush per state instead of per camera;
//! - leaves out the geoms a camera cannot see (bounding sphere wholly outside its view frustum,
//!   also when mirrored in the reflecting floor), which GL would clip anyway: the pixels are the
//!   same, the wrist camera's frame costs a fraction.
//!
//! A GL context belongs to the thread that made it, so the caller keeps one of these per thread.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; render flags index MuJoCo's fixed-size flag arrays by their enum"
)]

use std::num::NonZeroU32;

use glutin::api::egl::context::PossiblyCurrentContext;
use glutin::api::egl::device::Device;
use glutin::api::egl::display::Display;
use glutin::api::egl::surface::Surface;
use glutin::config::{ConfigSurfaceTypes, ConfigTemplateBuilder};
use glutin::context::{ContextApi, ContextAttributesBuilder, GlProfile, Version};
use glutin::prelude::{GlDisplay, NotCurrentGlContext, PossiblyCurrentGlContext};
use glutin::surface::{PbufferSurface, SurfaceAttributesBuilder};
use mujoco_rs::mujoco_c::{mjtGeom, mjtRndFlag, mjvGLCamera, mjvGeom};
use mujoco_rs::prelude::*;
use mujoco_rs::wrappers::mj_rendering::MjrContext;
use mujoco_rs::wrappers::mj_visualization::{MjvPerturb, MjvScene};

/// The EGL context and its pbuffer surface (the context draws into MuJoCo's own framebuffer
/// objects; the surface only makes it current).
struct Gl {
    context: PossiblyCurrentContext,
    surface: Surface<PbufferSurface>,
}

/// How a state's cameras are drawn. Every choice gives the same pixels but `reflection: false`
/// (a probe for benchmarks: the floor without the scene mirrored in it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// All cameras into one buffer side by side, read back once (else one read-back per camera).
    pub tile: bool,
    /// Leave out the geoms a camera cannot see.
    pub cull: bool,
    /// Mirror the scene in the reflecting floor, as MuJoCo and robosuite do.
    pub reflection: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self { tile: true, cull: true, reflection: true }
    }
}

/// One thread's renderer for one model and tile size.
pub(crate) struct Offscreen {
    // Field order is drop order: MuJoCo's context frees its GL objects while the GL context
    // (dropped last) is still alive and current on this thread.
    context: MjrContext,
    scene: MjvScene,
    gl: Gl,
    options: MjvOption,
    tile: (usize, usize),
    tiles: usize,
    how: RenderOptions,
    rgb: Vec<u8>,
    one_rgb: Vec<u8>,
    one_depth: Vec<f32>,
    depth: Vec<f32>,
}

impl std::fmt::Debug for Offscreen {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Offscreen").field("tile", &self.tile).field("tiles", &self.tiles).finish_non_exhaustive()
    }
}

/// Opens an offscreen context on the first EGL device that gives one.
fn open_gl() -> Result<Gl, String> {
    let devices = Device::query_devices().map_err(|e| format!("no EGL: {e}"))?;
    let mut last = String::from("no EGL device");
    for device in devices {
        match open_on(&device) {
            Ok(gl) => return Ok(gl),
            Err(e) => last = e.to_string(),
        }
    }
    Err(last)
}

fn open_on(device: &Device) -> glutin::error::Result<Gl> {
    #[allow(unsafe_code)]
    // SAFETY: `device` came from `Device::query_devices`; no native display is passed.
    let display = unsafe { Display::with_device(device, None)? };
    let template = ConfigTemplateBuilder::new()
        .with_surface_type(ConfigSurfaceTypes::PBUFFER)
        .with_alpha_size(0)
        .with_depth_size(24)
        .with_stencil_size(8)
        .build();
    #[allow(unsafe_code)]
    // SAFETY: `display` is a live EGL display; the template asks only for standard attributes.
    let config =
        unsafe { display.find_configs(template)? }.next().ok_or(glutin::error::ErrorKind::NotSupported("no pbuffer configuration"))?;
    // MuJoCo's classic renderer is fixed-function OpenGL: a compatibility profile.
    let attributes = ContextAttributesBuilder::new()
        .with_profile(GlProfile::Compatibility)
        .with_context_api(ContextApi::OpenGl(Some(Version::new(2, 0))))
        .build(None);
    #[allow(unsafe_code)]
    // SAFETY: `config` belongs to `display`.
    let context = unsafe { display.create_context(&config, &attributes)? };
    let one = NonZeroU32::MIN;
    #[allow(unsafe_code)]
    // SAFETY: `config` belongs to `display`; a 1 x 1 pbuffer (MuJoCo draws into its own buffers).
    let surface = unsafe { display.create_pbuffer_surface(&config, &SurfaceAttributesBuilder::<PbufferSurface>::new().build(one, one))? };
    let context = context.make_current(&surface)?;
    Ok(Gl { context, surface })
}

impl Offscreen {
    /// A renderer for `model` drawing `tiles` images of `tile` (width, height) side by side; the
    /// model's offscreen buffer (`<visual><global offwidth offheight>`) must hold them.
    ///
    /// # Errors
    /// A message when no EGL context can be made.
    pub(crate) fn new(model: &MjModel, options: MjvOption, tile: (usize, usize), tiles: usize, how: RenderOptions) -> Result<Self, String> {
        let gl = open_gl()?;
        #[allow(unsafe_code)]
        // SAFETY: `open_gl` made its context current on this thread.
        let mut context = unsafe { MjrContext::new(model) };
        context.offscreen();
        let scene = MjvScene::new(model, usize::try_from(model.ffi().ngeom).unwrap_or_default() + 100);
        let pixels = tile.0 * tile.1 * tiles;
        Ok(Self {
            context,
            scene,
            gl,
            options,
            tile,
            tiles,
            how,
            rgb: vec![0; pixels * 3],
            depth: Vec::new(),
            one_rgb: Vec::new(),
            one_depth: Vec::new(),
        })
    }

    /// Draws `data`'s state from each of `cameras` (at most the tile count), and reads the frame
    /// back: the RGB images (and depth buffer values when `depth`) upright, one per camera.
    ///
    /// # Errors
    /// A message when the GL context cannot be made current or the pixels cannot be read.
    pub(crate) fn render(
        &mut self,
        data: &mut MjData<std::sync::Arc<MjModel>>,
        cameras: &[usize],
        depth: bool,
    ) -> Result<Frame<'_>, String> {
        self.gl.context.make_current(&self.gl.surface).map_err(|e| format!("making the GL context current: {e}"))?;
        let (w, h) = self.tile;
        let (wi, hi) = (i32::try_from(w).unwrap_or(i32::MAX), i32::try_from(h).unwrap_or(i32::MAX));
        let n = cameras.len().min(self.tiles);
        self.rgb.resize(n * w * h * 3, 0);
        if depth {
            self.depth.resize(n * w * h, 0.0);
        }
        for (i, &id) in cameras.iter().take(n).enumerate() {
            let mut camera = MjvCamera::new_fixed(id);
            self.scene.update(data, &self.options, &MjvPerturb::default(), &mut camera);
            if !self.how.reflection {
                #[allow(unsafe_code)]
                // SAFETY: a render flag of the scene, read by MuJoCo's renderer only.
                unsafe {
                    self.scene.ffi_mut().flags[mjtRndFlag::mjRND_REFLECTION as usize] = 0;
                }
            }
            if self.how.cull {
                cull_invisible(&mut self.scene, w, h);
            }
            if self.how.tile {
                let left = i32::try_from(i).unwrap_or(i32::MAX).saturating_mul(wi);
                self.scene.render(&MjrRectangle::new(left, 0, wi, hi), &self.context);
                continue;
            }
            // One camera at a time, read back each (MuJoCo's renderer as robosuite drives it).
            let one = MjrRectangle::new(0, 0, wi, hi);
            self.scene.render(&one, &self.context);
            self.one_rgb.resize(w * h * 3, 0);
            self.one_depth.resize(if depth { w * h } else { 0 }, 0.0);
            let depth_buffer = depth.then_some(self.one_depth.as_mut_slice());
            self.context.read_pixels(Some(&mut self.one_rgb), depth_buffer, &one).map_err(|e| format!("reading the pixels back: {e:?}"))?;
            place_tile(&self.one_rgb, &mut self.rgb, 3, self.tile, n, i);
            if depth {
                place_tile(&self.one_depth, &mut self.depth, 1, self.tile, n, i);
            }
        }
        if self.how.tile {
            let all = MjrRectangle::new(0, 0, i32::try_from(n * w).unwrap_or(i32::MAX), hi);
            let depth_buffer = depth.then_some(self.depth.as_mut_slice());
            self.context.read_pixels(Some(&mut self.rgb), depth_buffer, &all).map_err(|e| format!("reading the pixels back: {e:?}"))?;
        }
        Ok(Frame { rgb: &self.rgb, depth: depth.then_some(self.depth.as_slice()), tile: self.tile, tiles: n })
    }
}

/// The pixels of one state's cameras as OpenGL left them: rows bottom-up, the cameras' tiles
/// side by side.
pub(crate) struct Frame<'a> {
    rgb: &'a [u8],
    depth: Option<&'a [f32]>,
    tile: (usize, usize),
    tiles: usize,
}

impl Frame<'_> {
    /// Camera `i`'s RGB image, rows top-down, appended to `out`.
    pub(crate) fn rgb_into(&self, i: usize, out: &mut Vec<u8>) {
        copy_tile(self.rgb, 3, self.tile, self.tiles, i, out);
    }

    /// Camera `i`'s depth buffer values (0 near to 1 far, robosuite's), rows top-down, appended to
    /// `out`. Nothing when depth was not read.
    pub(crate) fn depth_into(&self, i: usize, out: &mut Vec<f32>) {
        if let Some(depth) = self.depth {
            let start = out.len();
            copy_tile(depth, 1, self.tile, self.tiles, i, out);
            out[start..].iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        }
    }
}

/// Copies one image (`w` x `h`, bottom-up) into tile `i` of a buffer of `tiles` tiles side by side.
fn place_tile<T: Copy>(image: &[T], buffer: &mut [T], channels: usize, (w, h): (usize, usize), tiles: usize, i: usize) {
    let row = w * channels;
    for y in 0..h {
        let to = y * row * tiles + i * row;
        if let (Some(from), Some(into)) = (image.get(y * row..(y + 1) * row), buffer.get_mut(to..to + row)) {
            into.copy_from_slice(from);
        }
    }
}

/// Appends tile `i` of a bottom-up buffer of `tiles` tiles side by side, flipped upright.
fn copy_tile<T: Copy>(buffer: &[T], channels: usize, (w, h): (usize, usize), tiles: usize, i: usize, out: &mut Vec<T>) {
    let row = w * channels;
    let stride = row * tiles;
    for y in (0..h).rev() {
        let start = y * stride + i * row;
        if let Some(pixels) = buffer.get(start..start + row) {
            out.extend_from_slice(pixels);
        }
    }
}

/// Removes from `scene` the geoms whose bounding sphere lies wholly outside the view frustum of
/// its camera drawn at `width` x `height`, and outside it mirrored in the scene's reflecting plane
/// (MuJoCo mirrors the scene in its first reflecting plane or box top). Planes, reflecting geoms
/// and geoms without a bound are kept, and the kept ones stay in order. GL would clip every removed geom; removing them first spares the vertex work.
fn cull_invisible(scene: &mut MjvScene, width: usize, height: usize) {
    let (camera, mirror) = {
        let ffi = scene.ffi();
        let view = average_camera(&ffi.camera[0], &ffi.camera[1]);
        let n = usize::try_from(ffi.ngeom).unwrap_or_default();
        let mirror = if ffi.flags[mjtRndFlag::mjRND_REFLECTION as usize] != 0 {
            geoms(scene).iter().take(n).find(|g| reflects(g)).map(mirror_plane)
        } else {
            None
        };
        (Frustum::new(&view, width, height), mirror)
    };
    let keep = |g: &mjvGeom| {
        let radius = g.modelrbound;
        if g.type_ == mjtGeom::mjGEOM_PLANE as i32 || radius <= 0.0 || reflects(g) {
            return true;
        }
        camera.may_see(g.pos, radius) || mirror.is_some_and(|(point, normal)| camera.may_see(reflect(g.pos, point, normal), radius))
    };
    #[allow(unsafe_code)]
    // SAFETY: only geoms already in the scene are moved, within its first `ngeom`, and the count
    // is lowered to what is kept; the scene's other arrays are rebuilt by MuJoCo on the next update.
    let ffi = unsafe { scene.ffi_mut() };
    let n = usize::try_from(ffi.ngeom).unwrap_or_default();
    #[allow(unsafe_code)]
    // SAFETY: `geoms` points at `maxgeom >= ngeom` geoms MuJoCo allocated for this scene.
    let all = unsafe { std::slice::from_raw_parts_mut(ffi.geoms, n) };
    let mut kept = 0;
    for i in 0..n {
        if keep(&all[i]) {
            all.swap(kept, i);
            kept += 1;
        }
    }
    ffi.ngeom = i32::try_from(kept).unwrap_or(i32::MAX);
}

/// The camera MuJoCo draws a mono image from: the mean of the scene's two eyes (which stand half
/// the model's `ipd` to either side), its forward and up made unit and orthogonal again.
fn average_camera(a: &mjvGLCamera, b: &mjvGLCamera) -> mjvGLCamera {
    let mean = |x: [f32; 3], y: [f32; 3]| std::array::from_fn(|k| 0.5 * (x[k] + y[k]));
    let unit = |v: [f32; 3]| {
        let n = dot(v, v).sqrt();
        if n > 0.0 { v.map(|c| c / n) } else { v }
    };
    let forward = unit(mean(a.forward, b.forward));
    let up = mean(a.up, b.up);
    let along = dot(up, forward);
    let up = unit(std::array::from_fn(|k| up[k] - along * forward[k]));
    mjvGLCamera {
        pos: mean(a.pos, b.pos),
        forward,
        up,
        frustum_center: 0.5 * (a.frustum_center + b.frustum_center),
        frustum_width: 0.5 * (a.frustum_width + b.frustum_width),
        frustum_bottom: 0.5 * (a.frustum_bottom + b.frustum_bottom),
        frustum_top: 0.5 * (a.frustum_top + b.frustum_top),
        frustum_near: 0.5 * (a.frustum_near + b.frustum_near),
        frustum_far: 0.5 * (a.frustum_far + b.frustum_far),
        orthographic: a.orthographic,
    }
}

/// The scene's geoms (its first `ngeom`).
fn geoms(scene: &MjvScene) -> &[mjvGeom] {
    let ffi = scene.ffi();
    let n = usize::try_from(ffi.ngeom).unwrap_or_default();
    if ffi.geoms.is_null() || n == 0 {
        return &[];
    }
    #[allow(unsafe_code)]
    // SAFETY: MuJoCo's scene holds `ngeom` initialised geoms at `geoms`.
    unsafe {
        std::slice::from_raw_parts(ffi.geoms, n)
    }
}

/// Whether MuJoCo's renderer mirrors the scene in `g` (a plane, or a box's top, that reflects).
fn reflects(g: &mjvGeom) -> bool {
    (g.type_ == mjtGeom::mjGEOM_PLANE as i32 || g.type_ == mjtGeom::mjGEOM_BOX as i32) && g.reflectance > 0.0 && g.rgba[3] >= 0.995
}

/// The mirror of a reflecting geom: a point on it and its normal (the geom's z axis; a box's top).
fn mirror_plane(g: &mjvGeom) -> ([f32; 3], [f32; 3]) {
    let normal = [g.mat[2], g.mat[5], g.mat[8]];
    let lift = if g.type_ == mjtGeom::mjGEOM_BOX as i32 { g.size[2] } else { 0.0 };
    (std::array::from_fn(|k| g.pos[k] + lift * normal[k]), normal)
}

/// `p` mirrored in the plane through `point` with unit `normal`.
fn reflect(p: [f32; 3], point: [f32; 3], normal: [f32; 3]) -> [f32; 3] {
    let d = dot(sub(p, point), normal);
    std::array::from_fn(|k| p[k] - 2.0 * d * normal[k])
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// A camera's view frustum as MuJoCo's renderer sets it (`setView`: the half width from the
/// viewport's aspect when the camera gives none).
struct Frustum {
    eye: [f32; 3],
    forward: [f32; 3],
    up: [f32; 3],
    right: [f32; 3],
    near: f32,
    /// Left, right, bottom and top edges at the near plane.
    edges: [f32; 4],
    orthographic: bool,
}

impl Frustum {
    fn new(c: &mjvGLCamera, width: usize, height: usize) -> Self {
        let half = if c.frustum_width == 0.0 {
            0.5 * width as f32 / height.max(1) as f32 * (c.frustum_top - c.frustum_bottom)
        } else {
            c.frustum_width
        };
        Self {
            eye: c.pos,
            forward: c.forward,
            up: c.up,
            right: cross(c.forward, c.up),
            near: c.frustum_near,
            edges: [c.frustum_center - half, c.frustum_center + half, c.frustum_bottom, c.frustum_top],
            orthographic: c.orthographic != 0,
        }
    }

    /// False only when a sphere at `center` of `radius` is wholly outside the frustum (behind the
    /// near plane or beyond a side); the far plane is not tested.
    fn may_see(&self, center: [f32; 3], radius: f32) -> bool {
        let d = sub(center, self.eye);
        let (x, y, z) = (dot(d, self.right), dot(d, self.up), dot(d, self.forward));
        if z < self.near - radius {
            return false;
        }
        let [left, right, bottom, top] = self.edges;
        if self.orthographic {
            return x >= left - radius && x <= right + radius && y >= bottom - radius && y <= top + radius;
        }
        // A side plane through the eye and the near plane's edge at `e` along an axis: the point's
        // signed distance inside it is (near * a - e * z) / hypot(near, e) (a its coordinate on
        // that axis), negated for the far edge.
        let n = self.near;
        let inside = |a: f32, e: f32, sign: f32| sign * (n * a - e * z) / n.hypot(e) >= -radius;
        inside(x, left, 1.0) && inside(x, right, -1.0) && inside(y, bottom, 1.0) && inside(y, top, -1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Frustum {
        // The eye at the origin looking along +x, up +z, a 90 degree field of view (edges at
        // +-near).
        Frustum {
            eye: [0.0; 3],
            forward: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            right: cross([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            near: 0.1,
            edges: [-0.1, 0.1, -0.1, 0.1],
            orthographic: false,
        }
    }

    #[test]
    fn a_sphere_is_culled_only_when_wholly_outside_the_frustum() {
        let f = camera();
        assert!(f.may_see([2.0, 0.0, 0.0], 0.01), "straight ahead");
        assert!(!f.may_see([-1.0, 0.0, 0.0], 0.5), "behind the eye");
        assert!(f.may_see([-0.2, 0.0, 0.0], 0.5), "behind, but reaching past the near plane");
        // 45 degrees is the edge: a point at (1, 1.2) is 0.2 / sqrt 2 = 0.141 outside it.
        let right = f.right;
        let at = |along: f32, side: f32| [along, side * right[1], 0.0];
        assert!(!f.may_see(at(1.0, 1.2), 0.14));
        assert!(f.may_see(at(1.0, 1.2), 0.15));
        assert!(!f.may_see(at(1.0, -1.2), 0.14));
        assert!(f.may_see(at(1.0, -1.2), 0.15));
        assert!(!f.may_see([1.0, 0.0, 1.2], 0.14), "above");
        assert!(f.may_see([1.0, 0.0, -1.2], 0.15), "below, touching");
    }

    #[test]
    fn a_point_is_mirrored_in_a_plane() {
        let p = reflect([0.3, -0.2, 1.5], [0.0, 0.0, 0.5], [0.0, 0.0, 1.0]);
        assert!((p[0] - 0.3).abs() < 1e-6 && (p[1] + 0.2).abs() < 1e-6 && (p[2] + 0.5).abs() < 1e-6, "{p:?}");
    }

    #[test]
    fn an_image_placed_in_a_tile_is_cut_out_again() {
        let mut buffer = vec![0u8; 2 * 3 * 3 * 3];
        let image: Vec<u8> = (1..=18).collect();
        place_tile(&image, &mut buffer, 3, (2, 3), 3, 2);
        let mut back = Vec::new();
        copy_tile(&buffer, 3, (2, 3), 3, 2, &mut back);
        // Upright: the last row first.
        assert_eq!(back, [13, 14, 15, 16, 17, 18, 7, 8, 9, 10, 11, 12, 1, 2, 3, 4, 5, 6]);
        let mut first = Vec::new();
        copy_tile(&buffer, 3, (2, 3), 3, 0, &mut first);
        assert!(first.iter().all(|&v| v == 0), "the other tiles are untouched");
    }

    #[test]
    fn tiles_are_cut_out_and_turned_upright() {
        // Two 2 x 2 single-channel tiles side by side, rows bottom-up: row 0 = [a0 a1 b0 b1].
        let buffer = [1, 2, 5, 6, 3, 4, 7, 8];
        let mut a = Vec::new();
        copy_tile(&buffer, 1, (2, 2), 2, 0, &mut a);
        let mut b = Vec::new();
        copy_tile(&buffer, 1, (2, 2), 2, 1, &mut b);
        assert_eq!((a, b), (vec![3, 4, 1, 2], vec![7, 8, 5, 6]));
    }
}
