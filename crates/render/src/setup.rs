//! From a loaded scene to a render that is ready to run, the way `lucent render` does it:
//! the integrator a name stands for (with the scene file's hints), a white sky for a scene
//! with no light at all, the camera (given, the scene's, or one framing it; the file's clip
//! planes and lens), the world with a headlight where nothing lights it. The command line
//! and the Python package both go through [`prepare`], so they render the same image.

use crate::camera::{framing_camera, Camera};
use crate::integrator::{Integrator, PathSettings, VplSettings, WhittedSettings};
use crate::render::RenderSettings;
use crate::tiles::Traversal;
use crate::world::{World, WorldError};
use lucent_accel::MeshOptions;
use lucent_scene::{CameraDesc, Scene};

/// The integrators [`integrator_named`] knows.
pub const INTEGRATORS: [&str; 6] = ["whitted", "path", "path-scalar", "vpl", "eye-light", "normals"];

/// What can stop [`prepare`].
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// A scene with nothing to frame and no camera.
    #[error("the scene is empty: nothing to frame")]
    Empty,
    /// A camera given as numbers that are not finite.
    #[error("the camera needs 10 finite numbers EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV")]
    Camera,
    /// An image side of 0 or above 16,384, or 0 samples per pixel.
    #[error("image size {0}x{1}: each side must be 1..=16384")]
    Size(u32, u32),
    /// Building the world failed.
    #[error(transparent)]
    World(#[from] WorldError),
}

/// The integrator `name` (one of [`INTEGRATORS`]; `None` for another) with these settings,
/// or the scene file's where not given: the most path segments (`max_depth`, as Mitsuba
/// counts them, or Whitted's generations), the roulette depth (else 5), hidden emitters;
/// Whitted without shadows.
#[must_use]
pub fn integrator_named(
    name: &str,
    scene: &Scene,
    max_depth: Option<u32>,
    rr_depth: Option<u32>,
    hide_emitters: bool,
    no_shadows: bool,
) -> Option<Integrator> {
    let hints = scene.hints;
    let max_depth = max_depth.or(hints.and_then(|h| h.max_depth));
    Some(match name {
        "eye-light" => Integrator::EyeLight,
        "vpl" => Integrator::Vpl(VplSettings { max_depth: max_depth.unwrap_or(u32::MAX), ..VplSettings::default() }),
        "normals" => Integrator::Normals,
        "path" | "path-scalar" => Integrator::Path(PathSettings {
            max_depth: max_depth.unwrap_or(u32::MAX),
            rr_depth: rr_depth.or(hints.map(|h| h.rr_depth)).unwrap_or(5),
            hide_emitters: hide_emitters || hints.is_some_and(|h| h.hide_emitters),
            sampling: match hints.map(|h| h.strategies) {
                Some(lucent_scene::Strategies::Emitters) => crate::integrator::path::LightSampling::Nee,
                Some(lucent_scene::Strategies::Bsdf) => crate::integrator::path::LightSampling::Bsdf,
                _ => crate::integrator::path::LightSampling::Mis,
            },
            lanes: name == "path",
            ..PathSettings::default()
        }),
        "whitted" => Integrator::Whitted(WhittedSettings {
            max_depth: max_depth.unwrap_or(WhittedSettings::default().max_depth),
            shadows: !no_shadows,
        }),
        _ => return None,
    })
}

/// The camera: `view` (eye, look-at, up, vertical field of view in degrees), else the
/// scene's, else one framing its bounds; `ortho` makes it orthographic with the view
/// height the perspective one has at the look-at point.
pub fn camera_desc(scene: &Scene, view: Option<&[f32; 10]>, ortho: bool) -> Result<CameraDesc, SetupError> {
    let mut desc = match view {
        Some(v) if v.iter().all(|x| x.is_finite()) => CameraDesc::from_view(v),
        Some(_) => return Err(SetupError::Camera),
        None => match (scene.camera, scene.bounds()) {
            (Some(c), _) => c,
            (None, Some((lo, hi))) => framing_camera(lo, hi),
            (None, None) => return Err(SetupError::Empty),
        },
    };
    if ortho {
        let dist = (desc.look_at - desc.eye).length();
        desc.ortho_height = Some(2.0 * dist * (desc.vfov_deg.to_radians() * 0.5).tan());
    }
    Ok(desc)
}

/// How to render a scene: the integrator (see [`integrator_named`]), the image size and
/// samples per pixel (else the scene file's, else 1024 × 768 and 16 for path tracing, 1
/// for the others), the camera (see [`camera_desc`]), the index's build options and the
/// traversal.
#[derive(Clone, Debug)]
pub struct Recipe {
    /// What the rays compute.
    pub integrator: Integrator,
    /// Image size.
    pub size: Option<(u32, u32)>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// The camera as numbers, in place of the scene's.
    pub view: Option<[f32; 10]>,
    /// Orthographic projection.
    pub ortho: bool,
    /// The acceleration structure's build.
    pub mesh: MeshOptions,
    /// Camera rays in packets (the same image either way).
    pub packets: bool,
    /// The reconstruction filter, in place of the scene file's (else a box).
    pub filter: Option<lucent_scene::PixelFilter>,
}

/// A render ready to run: the world, its camera, the settings.
pub struct Prepared {
    /// The scene with its index.
    pub world: World,
    /// The camera as described (before the image size).
    pub desc: CameraDesc,
    /// The camera for the image.
    pub camera: Camera,
    /// Size, samples, integrator, traversal.
    pub settings: RenderSettings,
    /// A white sky was added: the scene had no light, emitter or environment.
    pub sky: bool,
    /// A headlight at the camera was added: nothing else lights the scene.
    pub headlight: bool,
    /// The window of the image to keep (x, y, width, height): the scene file's crop, unless
    /// the recipe gives its own size.
    pub crop: Option<[u32; 4]>,
}

/// Prepares `scene` for rendering by `recipe`, as `lucent render` does.
pub fn prepare(mut scene: Scene, recipe: &Recipe) -> Result<Prepared, SetupError> {
    let hints = scene.hints;
    let emits = scene.materials.iter().any(|m| m.emission.max_element() > 0.0);
    let sky = matches!(recipe.integrator, Integrator::Path(_) | Integrator::Vpl(_))
        && scene.lights.is_empty()
        && scene.environment.is_none()
        && !emits;
    if sky {
        scene.environment = Some(lucent_scene::Environment { scale: glam::Vec3::ONE, image: None, to_world: glam::Affine3A::IDENTITY });
    }
    let (w, h) = recipe.size.or(hints.map(|h| (h.width, h.height))).unwrap_or((1024, 768));
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(SetupError::Size(w, h));
    }
    let spp = recipe.spp.or(hints.map(|h| h.spp)).unwrap_or(if matches!(recipe.integrator, Integrator::Path(_)) { 16 } else { 1 });
    let desc = camera_desc(&scene, recipe.view.as_ref(), recipe.ortho)?;
    let mut world = World::new(scene, recipe.mesh)?;
    // (Whitted and the debug views light with point lights; the path and VPL integrators
    // sample the scene's own lights, or the white sky above.)
    let headlight = !matches!(recipe.integrator, Integrator::Path(_) | Integrator::Vpl(_)) && world.ensure_light(desc.eye);
    let settings = RenderSettings {
        spp: spp.max(1),
        integrator: recipe.integrator,
        traversal: Traversal { packets: recipe.packets },
        filter: recipe.filter.or(hints.map(|h| h.filter)).unwrap_or_default(),
        ..RenderSettings::new(w, h)
    };
    let mut camera = Camera::new(&desc, w, h);
    if recipe.view.is_none() {
        if let Some(h) = hints {
            camera = camera.with_clip(h.clip.0, h.clip.1);
            if let Some((r, f)) = h.lens {
                camera = camera.with_lens(r, f);
            }
        }
    }
    let crop = if recipe.size.is_none() { hints.and_then(|h| h.crop) } else { None };
    let settings = RenderSettings { window: crop, ..settings };
    Ok(Prepared { world, desc, camera, settings, sky, headlight, crop })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every name of the list is an integrator, and only those.
    #[test]
    fn every_listed_name_is_an_integrator() {
        let scene = lucent_scene::demo_scene();
        for name in INTEGRATORS {
            assert!(integrator_named(name, &scene, None, None, false, false).is_some(), "{name}");
        }
        assert!(integrator_named("pathtracer", &scene, None, None, false, false).is_none());
    }

    /// A scene with nothing lighting it gets a white sky for the path tracer, and a
    /// headlight for Whitted; an empty scene without a camera is refused.
    #[test]
    fn a_dark_scene_is_lit_and_an_empty_one_refused() {
        let mut scene = lucent_scene::demo_scene();
        scene.lights.clear();
        for m in &mut scene.materials {
            m.emission = glam::Vec3::ZERO;
        }
        scene.environment = None;
        let recipe = |name| Recipe {
            integrator: integrator_named(name, &scene, None, None, false, false).expect("an integrator"),
            size: Some((8, 6)),
            spp: None,
            view: None,
            ortho: false,
            mesh: MeshOptions::default(),
            packets: true,
            filter: None,
        };
        let p = prepare(scene.clone(), &recipe("path")).expect("prepared");
        assert!(p.sky && !p.headlight && p.settings.spp == 16);
        let w = prepare(scene.clone(), &recipe("whitted")).expect("prepared");
        assert!(!w.sky && w.headlight && w.settings.spp == 1);
        let empty = prepare(Scene::default(), &recipe("path"));
        assert!(matches!(empty, Err(SetupError::Empty)));
    }
}
