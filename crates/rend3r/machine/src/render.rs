//! A frame of the device, drawn by the renderer its settings choose: lucent's Whitted ray
//! tracer over the scene the state describes ([`crate::frame::scene`]), or the
//! rasterizer ([`crate::raster`]).

use crate::frame::{camera, scene, FrameInfo, FrameSettings, Mode};
use crate::processor::DeviceState;
use crate::raster::rasterize;
use lucent_accel::MeshOptions;
use lucent_render::{render, Film, Integrator, RenderSettings, WhittedSettings, World, WorldError};

/// Renders one frame of the state.
pub fn render_frame(state: &DeviceState, fs: &FrameSettings) -> Result<(Film, FrameInfo), WorldError> {
    let cam = camera(state, fs.width, fs.height);
    match fs.mode {
        Mode::Raytrace => {
            let (scene, skipped) = scene(state, fs.sets);
            let info = FrameInfo { shapes: scene.instances.len(), lights: scene.lights.len(), skipped, rays: 0 };
            let world = World::new(scene, MeshOptions::default())?;
            let rs = RenderSettings {
                spp: fs.spp.max(1),
                integrator: Integrator::Whitted(WhittedSettings { max_depth: 5, shadows: true }),
                ..RenderSettings::new(fs.width, fs.height)
            };
            let (film, rays) = render(&world, &cam, &rs, &|_| {});
            Ok((film, FrameInfo { rays, ..info }))
        }
        Mode::Raster => Ok(rasterize(state, &cam, fs)),
    }
}
