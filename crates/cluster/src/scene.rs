//! What every rank renders: the same scene (checked by its digest), cut into tiles, each
//! rendered by a [`SceneRenderer`] that poses the world at the frame's time.

use crate::wire::FrameSpec;
use crate::worker::Renderer;
use lucent_render::{Region, World};

/// A digest of what a world renders (counts and bounds of its geometry, lights and
/// materials): ranks that loaded different files, or the same file differently, differ.
#[must_use]
pub fn scene_digest(w: &World) -> u64 {
    let s = w.scene();
    let st = s.stats();
    let mut words: Vec<u64> = vec![
        st.triangles as u64,
        st.vertices as u64,
        st.meshes as u64,
        st.instances as u64,
        st.materials as u64,
        st.textures as u64,
        w.lights().len() as u64,
        u64::from(s.environment.is_some()),
    ];
    if let Some((lo, hi)) = s.bounds() {
        words.extend(lo.to_array().into_iter().chain(hi.to_array()).map(|x| u64::from(x.to_bits())));
    }
    words.extend(s.background.to_array().map(|x| u64::from(x.to_bits())));
    // FNV-1a over the words' bytes.
    words.iter().flat_map(|w| w.to_le_bytes()).fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The `tile` × `tile` regions of a `width` × `height` image, samples `s0..s1`, row by row
/// (the last row and column of tiles cut at the image's edge).
#[must_use]
pub fn tiles(width: u32, height: u32, tile: u32, s0: u32, s1: u32) -> Vec<Region> {
    let t = tile.max(1);
    let mut v = Vec::new();
    for y0 in (0..height).step_by(t as usize) {
        for x0 in (0..width).step_by(t as usize) {
            v.push(Region { x0, y0, x1: (x0 + t).min(width), y1: (y0 + t).min(height), s0, s1 });
        }
    }
    v
}

/// The world a [`SceneRenderer`] renders.
pub enum WorldRef<'a> {
    /// Posed by its owner (the viewer poses it before each pass).
    Shared(&'a World),
    /// Posed here, at each frame's time.
    Owned(&'a mut World),
}

/// Renders regions of a world, posing it at each frame's time and choosing the camera as
/// `lucent animate` does when the frame carries none.
pub struct SceneRenderer<'a> {
    world: WorldRef<'a>,
    /// The time the world is posed at.
    posed: Option<f32>,
    /// The camera the world's animation gave at that time.
    animated: Option<lucent_scene::CameraDesc>,
    /// A camera that overrides the animation's (`--camera`).
    pub fixed: Option<lucent_scene::CameraDesc>,
    /// The camera when there is neither.
    pub fallback: lucent_scene::CameraDesc,
}

impl<'a> SceneRenderer<'a> {
    /// A renderer of `world`; frames without a camera use `fixed`, else the animation's,
    /// else `fallback`.
    #[must_use]
    pub fn new(world: WorldRef<'a>, fixed: Option<lucent_scene::CameraDesc>, fallback: lucent_scene::CameraDesc) -> Self {
        Self { world, posed: None, animated: None, fixed, fallback }
    }
}

impl Renderer for SceneRenderer<'_> {
    fn render(&mut self, frame: &FrameSpec, region: Region) -> Result<(lucent_render::RegionFilm, u64), String> {
        if let (Some(t), WorldRef::Owned(w)) = (frame.time, &mut self.world) {
            if self.posed != Some(t) {
                self.animated = w.set_time(t).map_err(|e| format!("cannot pose the scene at {t} s: {e}"))?;
                self.posed = Some(t);
            }
        }
        let world: &World = match &self.world {
            WorldRef::Shared(w) => w,
            WorldRef::Owned(w) => w,
        };
        let s = &frame.settings;
        let camera = frame
            .camera
            .unwrap_or_else(|| lucent_render::Camera::new(&self.fixed.or(self.animated).unwrap_or(self.fallback), s.width, s.height));
        Ok(lucent_render::render_region(world, &camera, s, region, &|_| {}))
    }
}
