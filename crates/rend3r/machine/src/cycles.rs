//! REND3R's cycle model (its paper's Table IV): what a frame costs the board at 100 MHz.
//!
//! - **Ray tracing**: the shape unit tests one shape a cycle, and a ray costs the shapes
//!   plus a fixed 205-cycle latency (camera ray generation, the root's divide and square
//!   root, shading: SPEC §5–§6); each pixel casts one camera ray and one ray per light,
//!   so the paper's worst case is `(shapes + 205) × (lights + 1)` cycles a pixel.
//!   The board casts its light rays only from pixels whose camera ray hit a shape: the
//!   cycles it really spends are `(shapes + 205) × (1 + lights × hit)` summed over pixels.
//! - **Rasterization**: every triangle costs 63 cycles of set-up (the colour pipe), 4 of
//!   vertex fetch and one per pixel of the screen (the edge tests scan the whole frame):
//!   `63 + 4 + width × height` a triangle. The board has no bounding-box cut-off, so the
//!   worst case is what it spends.
//!
//! The paper's own figures, kept here to stand beside the model: Table IV's 0.405 s for
//! one sphere without lights and 16.9 s for 4,096 spheres with one light (both at
//! 512×384), and its measured frame of 2 shapes and 1 light: 45,766,350 cycles against
//! the formula's 81,395,712.

/// The board's clock.
pub const CLOCK_HZ: f64 = 100e6;
/// Fixed cycles of one ray besides one cycle per shape.
pub const RAY_LATENCY: u64 = 205;
/// Cycles of the rasterizer's per-triangle set-up (colour pipe) and vertex fetch.
pub const RASTER_SETUP: u64 = 63 + 4;

/// A row of the paper's Table IV or its measured frame: (shapes, lights, seconds at
/// 512×384, what the paper says of it). Only the figures the paper prints are here.
pub const PAPER_ROWS: [(u64, u64, f64, &str); 8] = [
    (1, 0, 0.405, "Table IV, 1 sphere, no light"),
    (16, 0, 0.435, "Table IV, 16 spheres, no light"),
    (256, 0, 0.906, "Table IV, 256 spheres, no light"),
    (4096, 0, 8.456, "Table IV, 4,096 spheres, no light"),
    (1, 1, 0.810, "Table IV, 1 sphere, 1 light"),
    (16, 1, 0.869, "Table IV, 16 spheres, 1 light"),
    (256, 1, 1.813, "Table IV, 256 spheres, 1 light"),
    (4096, 1, 16.912, "Table IV, 4,096 spheres, 1 light"),
];
/// The measured frame of 2 shapes and 1 light at 512×384: cycles on the board, and the
/// formula's cycles the paper sets beside it.
pub const PAPER_MEASURED: (u64, u64, u64, u64) = (2, 1, 45_766_350, 81_395_712);

/// Cycles of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cycles {
    /// The paper's worst case (every pixel casts its light rays).
    pub worst: u64,
    /// What the board spends (light rays only where the camera ray hit).
    pub board: u64,
}

impl Cycles {
    /// Seconds at [`CLOCK_HZ`].
    #[must_use]
    pub fn seconds(self) -> (f64, f64) {
        (self.worst as f64 / CLOCK_HZ, self.board as f64 / CLOCK_HZ)
    }
}

/// Cycles of one ray against `shapes` shapes.
#[must_use]
pub fn ray_cycles(shapes: u64) -> u64 {
    shapes + RAY_LATENCY
}

/// Ray-traced frame of `pixels` pixels of which `hit_pixels` had a camera-ray hit.
#[must_use]
pub fn ray_traced(shapes: u64, lights: u64, pixels: u64, hit_pixels: u64) -> Cycles {
    let ray = ray_cycles(shapes);
    Cycles { worst: pixels * ray * (lights + 1), board: pixels * ray + hit_pixels.min(pixels) * ray * lights }
}

/// Rasterized frame of `triangles` triangles over `pixels` pixels.
#[must_use]
pub fn rasterized(triangles: u64, pixels: u64) -> Cycles {
    let c = triangles * (RASTER_SETUP + pixels);
    Cycles { worst: c, board: c }
}

/// Cycles of one frame of `state` as REND3R would spend them: the set records and lights
/// the program wrote, and, for the board, the pixels whose
/// camera ray (through the pixel centre, lucent's camera) hits a shape. Returns the
/// cycles and the number of pixels hit.
///
/// # Errors
/// When the scene cannot be built (as [`crate::render_frame`]).
pub fn frame_cycles(state: &crate::DeviceState, fs: &crate::FrameSettings) -> Result<(Cycles, u64), lucent_render::WorldError> {
    let pixels = u64::from(fs.width) * u64::from(fs.height);
    match fs.mode {
        crate::Mode::Raster => Ok((rasterized(state.used_sets() as u64, pixels), 0)),
        crate::Mode::Raytrace => {
            let cam = crate::camera(state, fs.width, fs.height);
            let (scene, _) = crate::scene(state, fs.sets);
            // Every written record costs the shape unit a cycle, shape or triangle.
            let shapes = state.used_sets() as u64;
            let lights = state.used_lights() as u64;
            let world = lucent_render::World::new(scene, lucent_accel::MeshOptions::default())?;
            let hits = hit_pixels(&world, &cam, fs.width, fs.height);
            Ok((ray_traced(shapes, lights, pixels, hits), hits))
        }
    }
}

/// Pixels of a `w`×`h` frame whose centre ray hits something.
#[must_use]
pub fn hit_pixels(world: &lucent_render::World, cam: &lucent_render::Camera, w: u32, h: u32) -> u64 {
    use rayon::prelude::*;
    (0..h)
        .into_par_iter()
        .map(|y| (0..w).filter(|&x| world.intersect(&cam.ray(x as f32 + 0.5, y as f32 + 0.5)).is_some()).count() as u64)
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    const PX: u64 = 512 * 384;

    /// The formula gives the paper's printed figures: Table IV's first and last rows
    /// (to the paper's rounding) and the formula side of the measured 2-shape frame.
    #[test]
    fn formula_matches_the_paper() {
        for (shapes, lights, seconds, what) in PAPER_ROWS {
            let c = ray_traced(shapes, lights, PX, PX);
            let s = c.seconds().0;
            let digits = 1e3;
            assert_eq!((s * digits).round() / digits, seconds, "{what}");
        }
        let (shapes, lights, _, formula) = PAPER_MEASURED;
        assert_eq!(ray_traced(shapes, lights, PX, PX).worst, formula);
    }

    /// Hand-counted: 2 shapes, 1 light, 10 pixels of which 3 hit: 10 camera rays and 3
    /// light rays of 207 cycles; the worst case casts 20.
    #[test]
    fn board_casts_light_rays_only_from_hits() {
        assert_eq!(ray_traced(2, 1, 10, 3), Cycles { worst: 20 * 207, board: 13 * 207 });
        assert_eq!(ray_traced(2, 0, 10, 3), Cycles { worst: 10 * 207, board: 10 * 207 });
        assert_eq!(ray_traced(0, 3, 4, 4).board, 4 * 205 * 4);
    }

    #[test]
    fn raster_scans_the_screen_per_triangle() {
        assert_eq!(rasterized(1, PX).worst, 63 + 4 + 196_608);
        assert_eq!(rasterized(10, PX).board, 10 * 196_675);
        assert_eq!(rasterized(0, PX).worst, 0);
    }
}
