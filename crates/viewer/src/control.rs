//! The viewer's logic without a window: the fly/orbit camera, the adaptive-resolution
//! planner (Pixel-Planes 5: reduced resolution while moving, full resolution and then
//! progressive refinement when still) and the sample accumulator. All of it is tested
//! without a display.

use glam::Vec3;
use lucent_scene::CameraDesc;

/// How the mouse moves the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NavMode {
    /// Mouse turns the view; W/A/S/D/Q/E move.
    Fly,
    /// Mouse turns the camera around a target point; W/S move toward/away from it.
    Orbit,
}

/// A fly/orbit camera over a scene's home camera.
#[derive(Clone, Debug)]
pub struct CameraController {
    home: CameraDesc,
    /// Eye position.
    pub eye: Vec3,
    yaw: f32,
    pitch: f32,
    up: Vec3,
    f0: Vec3,
    r0: Vec3,
    /// Orbit target.
    pub target: Vec3,
    /// Units per second.
    pub speed: f32,
    home_speed: f32,
    /// Orthographic projection.
    pub ortho: bool,
    /// Fly or orbit.
    pub mode: NavMode,
}

impl CameraController {
    /// Starts at `home`; `scene_size` (the bounds' diagonal) sets the speed.
    #[must_use]
    pub fn new(home: CameraDesc, scene_size: f32) -> Self {
        let speed = (scene_size * 0.25).max(1e-3);
        let mut c = Self {
            home,
            eye: home.eye,
            yaw: 0.0,
            pitch: 0.0,
            up: Vec3::Y,
            f0: -Vec3::Z,
            r0: Vec3::X,
            target: home.look_at,
            speed,
            home_speed: speed,
            ortho: home.ortho_height.is_some(),
            mode: NavMode::Fly,
        };
        c.reset();
        c
    }

    /// Back to the scene's camera (Home).
    pub fn reset(&mut self) {
        let h = self.home;
        self.up = h.up.normalize_or(Vec3::Y);
        let f = (h.look_at - h.eye).normalize_or(-Vec3::Z);
        let flat = (f - self.up * f.dot(self.up)).normalize_or(self.up.any_orthonormal_vector());
        self.f0 = flat;
        self.r0 = flat.cross(self.up).normalize_or(Vec3::X);
        self.yaw = 0.0;
        self.pitch = f.dot(self.up).clamp(-1.0, 1.0).asin();
        self.eye = h.eye;
        self.target = h.look_at;
        self.speed = self.home_speed;
        self.ortho = h.ortho_height.is_some();
    }

    /// Takes `desc` as the new home camera and moves there (following a scene's animated
    /// camera); speed and navigation mode stay.
    pub fn follow(&mut self, desc: CameraDesc) {
        let (speed, mode, ortho) = (self.speed, self.mode, self.ortho);
        self.home = CameraDesc { ortho_height: None, ..desc };
        self.reset();
        self.speed = speed;
        self.mode = mode;
        self.ortho = ortho;
    }

    /// Unit view direction.
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        (self.f0 * cy + self.r0 * sy) * cp + self.up * sp
    }

    fn right(&self) -> Vec3 {
        self.forward().cross(self.up).normalize_or(self.r0)
    }

    /// Moves by `local` (x right, y up, z forward) × speed × `dt` seconds.
    pub fn fly(&mut self, local: Vec3, dt: f32) {
        if local == Vec3::ZERO {
            return;
        }
        let step = self.speed * dt;
        match self.mode {
            NavMode::Fly => {
                let d = self.right() * local.x + self.up * local.y + self.forward() * local.z;
                self.eye += d * step;
                self.target += d * step;
            }
            NavMode::Orbit => {
                // Forward/back: toward the target (never through it); sideways: orbit.
                let to = self.target - self.eye;
                let dist = to.length();
                let nd = (dist - local.z * step).max(dist * 0.05).max(1e-4);
                self.eye = self.target - to.normalize_or(self.forward()) * nd;
                self.orbit(local.x * 200.0 * dt, -local.y * 200.0 * dt);
            }
        }
    }

    /// Turns the view by a mouse motion in pixels (fly), or orbits the target (orbit).
    pub fn look(&mut self, dx: f32, dy: f32) {
        match self.mode {
            NavMode::Fly => {
                self.yaw += dx * 0.004;
                self.pitch = (self.pitch - dy * 0.004).clamp(-1.55, 1.55);
                self.target = self.eye + self.forward() * (self.target - self.eye).length().max(1e-3);
            }
            NavMode::Orbit => self.orbit(dx, dy),
        }
    }

    fn orbit(&mut self, dx: f32, dy: f32) {
        let dist = (self.target - self.eye).length().max(1e-4);
        self.yaw += dx * 0.005;
        self.pitch = (self.pitch - dy * 0.005).clamp(-1.55, 1.55);
        self.eye = self.target - self.forward() * dist;
    }

    /// Scroll: faster (positive) or slower.
    pub fn scroll(&mut self, lines: f32) {
        self.speed = (self.speed * 1.25f32.powf(lines)).clamp(self.home_speed * 1e-3, self.home_speed * 1e3);
    }

    /// Switches between fly and orbit (orbit keeps the point looked at).
    pub fn toggle_mode(&mut self) {
        self.mode = match self.mode {
            NavMode::Fly => NavMode::Orbit,
            NavMode::Orbit => NavMode::Fly,
        };
    }

    /// The camera to render.
    #[must_use]
    pub fn desc(&self) -> CameraDesc {
        let dist = (self.target - self.eye).length().max(1e-3);
        CameraDesc {
            eye: self.eye,
            look_at: self.eye + self.forward() * dist,
            up: self.up,
            vfov_deg: self.home.vfov_deg,
            ortho_height: self.ortho.then(|| 2.0 * dist * (self.home.vfov_deg.to_radians() * 0.5).tan()),
        }
    }
}

/// One render the planner asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    /// Render width.
    pub width: u32,
    /// Render height.
    pub height: u32,
    /// Sample index (0 = pixel centre).
    pub sample: u32,
    /// Add to the accumulated image (false: start a new one).
    pub accumulate: bool,
}

/// Adaptive resolution: while moving, a fraction of the pixels chosen to hold the target
/// frame rate (a quarter by default); when still, full resolution, then one more sample
/// per pixel per frame until `max_samples`.
#[derive(Clone, Debug)]
pub struct Adaptive {
    /// Frames per second to hold while moving.
    pub target_fps: f64,
    /// Linear scale of the moving resolution (0.5 = a quarter of the pixels).
    pub scale: f64,
    /// Smallest scale (0.125: a 64th of the pixels).
    pub min_scale: f64,
    /// Samples per pixel at which a still image counts as converged.
    pub max_samples: u32,
    samples: u32,
}

impl Adaptive {
    /// A planner; `initial_scale` 0.5 means a quarter of the pixels while moving.
    #[must_use]
    pub fn new(target_fps: f64, max_samples: u32, initial_scale: f64) -> Self {
        Self {
            target_fps: target_fps.max(1.0),
            scale: initial_scale.clamp(0.125, 1.0),
            min_scale: 0.125,
            max_samples: max_samples.max(1),
            samples: 0,
        }
    }

    /// What to render next at window size `full`; `None` when still and converged.
    pub fn plan(&mut self, moving: bool, full: (u32, u32)) -> Option<Plan> {
        if moving {
            self.samples = 0;
            let w = ((f64::from(full.0) * self.scale).round() as u32).clamp(1, full.0.max(1));
            let h = ((f64::from(full.1) * self.scale).round() as u32).clamp(1, full.1.max(1));
            return Some(Plan { width: w, height: h, sample: 0, accumulate: false });
        }
        if self.samples >= self.max_samples {
            return None;
        }
        Some(Plan { width: full.0.max(1), height: full.1.max(1), sample: self.samples, accumulate: self.samples > 0 })
    }

    /// Reports how long the frame of `plan` took, in seconds: from its start to the start
    /// of the next frame (render, display and event handling).
    pub fn finished(&mut self, plan: &Plan, seconds: f64, moving: bool) {
        if moving {
            // Pixels scale with scale², time with pixels: aim at the frame budget, smoothed
            // so one slow frame does not halve the resolution.
            let budget = 1.0 / self.target_fps;
            let ideal = self.scale * (budget / seconds.max(1e-5)).sqrt();
            let s = 0.6 * self.scale + 0.4 * ideal;
            self.scale = s.clamp(self.min_scale, 1.0);
        } else {
            self.samples = plan.sample + 1;
        }
    }

    /// Samples per pixel accumulated so far (0 while moving).
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// True when the still image has all its samples.
    #[must_use]
    pub fn converged(&self) -> bool {
        self.samples >= self.max_samples
    }

    /// Starts refining again (a setting changed).
    pub fn restart(&mut self) {
        self.samples = 0;
    }
}

/// Writes `pixels` (`width`×`height`, linear, times `scale`), scaled to `w`×`h` (nearest
/// pixel), as 0RGB sRGB into `out`; black when there is nothing. Pixels are converted once
/// at their own resolution (through a table), then copied, so a quarter-resolution frame
/// costs a quarter of the conversions.
pub fn blit(pixels: &[Vec3], width: u32, height: u32, scale: f32, out: &mut [u32], w: u32, h: u32) {
    use rayon::prelude::*;
    let sw = width as usize;
    if pixels.is_empty() || pixels.len() < sw * height as usize || width == 0 || height == 0 || out.len() < (w as usize) * (h as usize) {
        out.fill(0);
        return;
    }
    // The film's own exact 8-bit sRGB codes, so the window shows the bytes a PNG would hold.
    let table = lucent_render::color::srgb8_table();
    let q = |c: f32| u32::from(table.encode(c));
    let src: Vec<u32> = pixels
        .par_iter()
        .map(|p| {
            let p = *p * scale;
            q(p.x) << 16 | q(p.y) << 8 | q(p.z)
        })
        .collect();
    let xs: Vec<usize> = (0..w).map(|x| ((u64::from(x) * u64::from(width)) / u64::from(w.max(1))) as usize).collect();
    out[..(w as usize) * (h as usize)].par_chunks_mut(w as usize).enumerate().for_each(|(y, dst)| {
        let sy = (y as u64 * u64::from(height) / u64::from(h.max(1))) as usize;
        let row = &src[sy * sw..(sy + 1) * sw];
        for (d, &sx) in dst.iter_mut().zip(&xs) {
            *d = row[sx];
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_render::{Region, RegionFilm};

    #[test]
    fn the_window_shows_the_bytes_a_png_would_hold() {
        // A fine ramp through every 8-bit code (many values near each threshold) and past
        // both ends, at its own size.
        let n = 40_000;
        let mut film = lucent_render::Film::new(n, 1);
        for (i, p) in film.pixels.iter_mut().enumerate() {
            let c = i as f32 / (n - 800) as f32 - 0.01;
            *p = Vec3::new(c, c * c, 1.0 - c);
        }
        let mut out = vec![0u32; n as usize];
        blit(&film.pixels, n, 1, 1.0, &mut out, n, 1);
        let bytes = film.to_srgb8();
        for (i, &o) in out.iter().enumerate() {
            let want = u32::from(bytes[3 * i]) << 16 | u32::from(bytes[3 * i + 1]) << 8 | u32::from(bytes[3 * i + 2]);
            assert_eq!(o, want, "pixel {i}");
        }
    }

    #[test]
    fn moving_renders_a_quarter_then_adapts_to_the_frame_budget() {
        let mut a = Adaptive::new(30.0, 16, 0.5);
        let p = a.plan(true, (1024, 768)).expect("a plan");
        assert_eq!((p.width, p.height, p.accumulate), (512, 384, false), "a quarter of the pixels");
        // Frames four times over budget: the resolution drops until the time fits.
        let mut t = 4.0 / 30.0;
        for _ in 0..30 {
            let p = a.plan(true, (1024, 768)).expect("a plan");
            a.finished(&p, t, true);
            // Time is proportional to the pixels rendered.
            let q = a.plan(true, (1024, 768)).expect("a plan");
            t = (4.0 / 30.0) * f64::from(q.width * q.height) / (512.0 * 384.0);
        }
        assert!((t - 1.0 / 30.0).abs() < 0.004, "converged to the budget: {t}");
        // Fast frames: the resolution climbs back, at most to full.
        for _ in 0..40 {
            let p = a.plan(true, (1024, 768)).expect("a plan");
            a.finished(&p, 0.001, true);
        }
        assert_eq!(a.plan(true, (1024, 768)).map(|p| p.width), Some(1024));
    }

    #[test]
    fn still_refines_at_full_resolution_until_converged() {
        let mut a = Adaptive::new(30.0, 4, 0.5);
        let mut seen = Vec::new();
        while let Some(p) = a.plan(false, (640, 480)) {
            assert_eq!((p.width, p.height), (640, 480));
            seen.push((p.sample, p.accumulate));
            a.finished(&p, 0.5, false);
        }
        assert_eq!(seen, vec![(0, false), (1, true), (2, true), (3, true)]);
        assert!(a.converged());
        // Moving again starts over.
        assert!(a.plan(true, (640, 480)).is_some());
        assert_eq!(a.samples(), 0);
        assert_eq!(a.plan(false, (640, 480)).map(|p| p.sample), Some(0));
    }

    /// A pass of one sample per pixel.
    fn pass(w: u32, h: u32, sample: u32, pixels: &[Vec3]) -> RegionFilm {
        let mut f = RegionFilm::new(Region::full(w, h, sample, sample + 1));
        for (i, p) in pixels.iter().enumerate() {
            f.add(i as u32 % w, i as u32 / w, *p, 1.0);
        }
        f
    }

    /// The viewer's passes go into the library's progressive image; blitting shows its
    /// mean in sRGB, scaled to the window.
    #[test]
    fn accumulated_passes_blit_to_the_window() {
        let mut acc = lucent_render::progressive::Progressive::default();
        acc.add(pass(2, 1, 0, &[Vec3::ONE, Vec3::ZERO]), false);
        acc.add(pass(2, 1, 1, &[Vec3::ZERO, Vec3::ZERO]), true);
        assert_eq!(acc.passes(), 2);
        let img = acc.image();
        assert_eq!(img.pixels[0], Vec3::splat(0.5));
        let mut out = vec![0u32; 4 * 2];
        blit(&img.pixels, img.width, img.height, 1.0, &mut out, 4, 2);
        // 0.5 linear is 188 in sRGB; the left half of every row is pixel 0.
        assert_eq!(out[0], 188 << 16 | 188 << 8 | 188);
        assert_eq!(out[1], out[0]);
        assert_eq!(out[2], 0);
        assert_eq!(out[4], out[0]);
    }

    #[test]
    fn camera_moves_turns_orbits_and_resets() {
        let home = CameraDesc { eye: Vec3::new(0.0, 0.0, 5.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov_deg: 45.0, ortho_height: None };
        let mut c = CameraController::new(home, 8.0);
        assert!((c.forward() - -Vec3::Z).length() < 1e-6);
        c.fly(Vec3::Z, 1.0);
        assert!((c.eye - Vec3::new(0.0, 0.0, 3.0)).length() < 1e-5, "forward by speed 2: {}", c.eye);
        c.fly(Vec3::X, 0.5);
        assert!((c.eye.x - 1.0).abs() < 1e-5, "right: {}", c.eye);
        c.look(100.0, 0.0);
        assert!(c.forward().x > 0.3, "turned right: {}", c.forward());
        c.reset();
        assert_eq!(c.eye, home.eye);
        c.toggle_mode();
        c.look(0.0, 0.0);
        for _ in 0..10 {
            c.look(50.0, 0.0);
            assert!(((c.eye - c.target).length() - 5.0).abs() < 1e-3, "orbit keeps the distance");
            assert!((c.desc().look_at - c.target).length() < 1e-3, "orbit looks at the target");
        }
        c.ortho = true;
        assert!(c.desc().ortho_height.is_some());
        c.scroll(2.0);
        assert!((c.speed - 2.0 * 1.5625).abs() < 1e-4);
    }
}
