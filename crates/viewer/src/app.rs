//! The window: winit events in, softbuffer pixels out. Rendering happens on the event
//! thread between events (each frame is spread over every core by rayon), so what is
//! shown is always the newest finished frame.

use crate::control::{blit, Adaptive, CameraController, NavMode, Plan};
use crate::font::draw_text;
use glam::Vec3;
use lucent_render::progressive::Progressive;
use lucent_render::{
    denoise, render_aovs, render_region, Camera, DenoiseSettings, Film, Integrator, PathSettings, Region, RegionFilm, RenderSettings,
    Temporal, VplSettings, WhittedSettings, World,
};
use rend3r_machine::{render_frame, FrameSettings, Processor, Step};
use std::collections::HashSet;
use std::num::NonZeroU32;
use std::path::PathBuf;
use std::rc::Rc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// Errors of the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// No display to open a window on.
    #[error("cannot open a window: {0}. `lucent view` needs an X11 display (set DISPLAY, or run it under Xvfb); every other command works without one")]
    NoDisplay(String),
    /// The window system failed later.
    #[error("window system error: {0}")]
    Window(String),
}

/// Viewer options.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// Window size.
    pub size: (u32, u32),
    /// Frame rate to hold while moving.
    pub target_fps: f64,
    /// Samples per pixel of a converged still image.
    pub max_samples: u32,
    /// Linear resolution scale while moving at start (0.5 = a quarter of the pixels).
    pub moving_scale: f64,
    /// Where screenshots go.
    pub screenshot_dir: PathBuf,
    /// Print a line per second of frame rates, and when a still image converges.
    pub report: bool,
    /// Close after this many seconds (for measurements and tests).
    pub quit_after: Option<f64>,
    /// The integrator shown first (key 4 cycles): 0 Whitted, 1 path, 2 VPL, 3 eye light,
    /// 4 normals.
    pub view: usize,
}

/// Renders the viewer's passes somewhere else: other processes, for `lucent view --mpi`
/// (a display wall driven from one window). Given the world (posed at `time` if it is
/// animated) and a pass's camera, settings and region, it returns what
/// [`lucent_render::render_region`] would (the same sums, bit for bit) and the rays traced.
pub trait PassRenderer {
    /// Renders one pass.
    fn render(&mut self, world: &World, time: Option<f32>, camera: &Camera, settings: &RenderSettings, region: Region)
        -> (RegionFilm, u64);
}

/// What the window shows.
pub enum Content {
    /// A scene: fly through it.
    Scene {
        /// The world.
        world: Box<World>,
        /// Its camera.
        home: lucent_scene::CameraDesc,
        /// Scene statistics for the heads-up line.
        stats: String,
        /// Title.
        name: String,
    },
    /// A REND3R program: each `nf` is shown as a frame.
    Program {
        /// The processor.
        processor: Box<Processor>,
        /// Frame settings (size follows the window).
        settings: FrameSettings,
        /// Title.
        name: String,
    },
}

struct Program {
    p: Box<Processor>,
    fs: FrameSettings,
    frames: u64,
    halted: bool,
    paused: bool,
    last: Option<Film>,
}

struct Gfx {
    window: Rc<Window>,
    surface: softbuffer::Surface<Rc<Window>, Rc<Window>>,
}

/// How many integrators key 4 cycles through.
const VIEWS: usize = 5;

/// Samples per pixel at which the denoised image has faded out (path tracer and VPL).
const DENOISE_FADE_SPP: f32 = 64.0;

/// The most frames a moving pixel's history holds (see [`Temporal`]): at 20 frames per
/// second, the last 0.4 s.
const TEMPORAL_FRAMES: f32 = 8.0;

struct App {
    opts: ViewOptions,
    /// Where passes are rendered, when not here.
    passes: Option<Box<dyn PassRenderer>>,
    name: String,
    world: Option<Box<World>>,
    program: Option<Program>,
    stats: String,
    cam: Option<CameraController>,
    adaptive: Adaptive,
    acc: Progressive,
    whitted: WhittedSettings,
    /// Which integrator shows (key 4 cycles): see [`App::integrator`].
    view: usize,
    /// Denoise path-traced and VPL images (key 5).
    denoise: bool,
    /// What the window shows instead of the accumulated image: the denoised one.
    shown: Option<Film>,
    /// The denoiser's guides, and the camera and size they were made for.
    guides: Option<(lucent_scene::CameraDesc, (u32, u32), lucent_render::Aovs)>,
    /// Milliseconds the last denoise took (guides included).
    denoise_ms: f64,
    /// Moving frames blended with the ones before, reprojected (key 6), and how many
    /// frames the last one held on average.
    temporal: Temporal,
    temporal_on: bool,
    temporal_frames: f64,
    gfx: Option<Gfx>,
    error: Option<ViewerError>,
    keys: HashSet<KeyCode>,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    mouse_delta: (f32, f32),
    last_tick: Instant,
    // Statistics.
    fps_frames: u32,
    fps_rays: u64,
    fps_since: Instant,
    fps: f64,
    mrays: f64,
    still_since: Option<Instant>,
    reported_converged: bool,
    started: Instant,
    shots: u32,
    dirty: bool,
    last_plan: Option<Plan>,
    pending: Option<(Plan, bool, Instant)>,
    /// Animated scene: (first, last key time).
    anim_range: Option<(f32, f32)>,
    anim_time: f32,
    anim_playing: bool,
    /// The camera follows the scene's animated camera until the user moves.
    follow: bool,
}

const DEPTHS: [u32; 6] = [0, 1, 2, 4, 6, 10];

impl App {
    /// The integrator shown: Whitted with the keys' settings, the path tracer or the VPL
    /// integrator (which accumulate while the camera is still, and show one sample per
    /// pixel at the reduced resolution, denoised, while it moves), the eye light, or
    /// normals.
    fn integrator(&self) -> Integrator {
        match self.view % VIEWS {
            0 => Integrator::Whitted(self.whitted),
            1 => Integrator::Path(PathSettings::default()),
            2 => Integrator::Vpl(VplSettings::default()),
            3 => Integrator::EyeLight,
            _ => Integrator::Normals,
        }
    }

    /// Whether the image shown is denoised.
    fn denoising(&self) -> bool {
        self.denoise && matches!(self.integrator(), Integrator::Path(_) | Integrator::Vpl(_))
    }

    /// The denoised image of the accumulated one, faded toward it as samples grow (fully
    /// denoised at one sample, not at all from [`DENOISE_FADE_SPP`]).
    /// While `moving`, the frame is first blended with the frames before it (key 6).
    fn denoise_shown(&mut self, camera: &lucent_scene::CameraDesc, size: (u32, u32), moving: bool) {
        self.shown = None;
        // (The blend needs the guides, made here for the denoiser.)
        let blend = moving && self.temporal_on && self.denoising();
        if !blend {
            self.temporal.reset();
            self.temporal_frames = 0.0;
        }
        if !self.denoising() {
            return;
        }
        let spp = self.acc.passes() as f32;
        let keep = (1.0 - (spp - 1.0) / (DENOISE_FADE_SPP - 1.0)).clamp(0.0, 1.0);
        if keep <= 0.0 {
            return;
        }
        let Some(world) = self.world.as_ref() else { return };
        let t = Instant::now();
        let fresh = !matches!(&self.guides, Some((d, s, _)) if d == camera && *s == size);
        if fresh {
            let c = Camera::new(camera, size.0, size.1);
            self.guides = Some((*camera, size, render_aovs(world, &c, size.0, size.1)));
        }
        let Some((_, _, aovs)) = &self.guides else { return };
        let raw = self.acc.image();
        if (raw.width, raw.height) != size {
            return;
        }
        let blended;
        let raw = if blend {
            let (f, stats) = self.temporal.add(&Camera::new(camera, size.0, size.1), raw, aovs);
            self.temporal_frames = stats.mean_frames;
            blended = f;
            &blended
        } else {
            raw
        };
        let mut d = denoise(raw, aovs, &DenoiseSettings::default());
        if keep < 1.0 {
            for (o, r) in d.pixels.iter_mut().zip(&raw.pixels) {
                *o = *o * keep + *r * (1.0 - keep);
            }
        }
        self.shown = Some(d);
        self.denoise_ms = t.elapsed().as_secs_f64() * 1e3;
    }

    /// True while the picture changes: the user steers or an animation plays.
    fn moving(&self) -> bool {
        self.steering() || (self.anim_playing && self.program.is_none())
    }

    /// True while the user steers the camera.
    fn steering(&self) -> bool {
        const MOVE: [KeyCode; 6] = [KeyCode::KeyW, KeyCode::KeyA, KeyCode::KeyS, KeyCode::KeyD, KeyCode::KeyQ, KeyCode::KeyE];
        MOVE.iter().any(|k| self.keys.contains(k)) || self.mouse_delta != (0.0, 0.0)
    }

    /// Advances an animated scene by `dt` seconds (looping) and poses the world.
    fn animate(&mut self, dt: f32) {
        let Some((lo, hi)) = self.anim_range else { return };
        if self.steering() {
            self.follow = false;
        }
        if self.anim_playing {
            self.anim_time += dt.min(0.25);
            if self.anim_time > hi {
                self.anim_time = lo + (self.anim_time - hi) % (hi - lo).max(1e-3);
            }
        }
        let Some(world) = self.world.as_mut() else { return };
        match world.set_time(self.anim_time) {
            Ok(Some(cam)) if self.follow => {
                if let Some(c) = self.cam.as_mut() {
                    c.follow(cam);
                }
            }
            Ok(_) => {}
            Err(e) => {
                tracing::error!("the animation cannot be posed at {:.3} s: {e}", self.anim_time);
                self.anim_playing = false;
            }
        }
    }

    fn size(&self) -> (u32, u32) {
        self.gfx.as_ref().map_or(self.opts.size, |g| {
            let s = g.window.inner_size();
            (s.width.max(1), s.height.max(1))
        })
    }

    /// Applies held keys and mouse motion to the camera.
    fn navigate(&mut self, dt: f32) {
        let Some(cam) = self.cam.as_mut() else { return };
        let k = |c| f32::from(u8::from(self.keys.contains(&c)));
        let local =
            Vec3::new(k(KeyCode::KeyD) - k(KeyCode::KeyA), k(KeyCode::KeyE) - k(KeyCode::KeyQ), k(KeyCode::KeyW) - k(KeyCode::KeyS));
        cam.fly(local, dt.min(0.25));
        let (dx, dy) = self.mouse_delta;
        if (dx, dy) != (0.0, 0.0) {
            cam.look(dx, dy);
        }
    }

    fn key(&mut self, code: KeyCode, el: &ActiveEventLoop) {
        let mut changed = true;
        match code {
            KeyCode::Escape => el.exit(),
            KeyCode::Home => {
                if let Some(c) = self.cam.as_mut() {
                    c.reset();
                }
                // Back to the scene's (animated) camera.
                self.follow = self.world.as_ref().and_then(|w| w.scene().animation.as_ref()).is_some_and(|a| a.camera.is_some());
            }
            KeyCode::Tab => {
                if let Some(c) = self.cam.as_mut() {
                    c.toggle_mode();
                }
            }
            KeyCode::Digit1 => self.whitted.shadows = !self.whitted.shadows,
            KeyCode::Digit2 => {
                let i = DEPTHS.iter().position(|&d| d == self.whitted.max_depth).map_or(0, |i| (i + 1) % DEPTHS.len());
                self.whitted.max_depth = DEPTHS[i];
            }
            KeyCode::Digit3 => {
                if let Some(c) = self.cam.as_mut() {
                    c.ortho = !c.ortho;
                }
            }
            KeyCode::Digit4 => self.view = (self.view + 1) % VIEWS,
            KeyCode::Digit5 => self.denoise = !self.denoise,
            KeyCode::Digit6 => self.temporal_on = !self.temporal_on,
            KeyCode::Space => {
                if let Some(p) = self.program.as_mut() {
                    p.paused = !p.paused;
                }
                if self.anim_range.is_some() {
                    self.anim_playing = !self.anim_playing;
                }
            }
            KeyCode::F12 | KeyCode::KeyP => {
                self.screenshot();
                changed = false;
            }
            _ => changed = false,
        }
        if changed {
            self.adaptive.restart();
            self.dirty = true;
        }
    }

    fn screenshot(&mut self) {
        let film = match &self.program {
            Some(p) => p.last.clone(),
            None => Some(self.shown.clone().unwrap_or_else(|| self.acc.image().clone())),
        };
        let Some(film) = film else { return };
        let _ = std::fs::create_dir_all(&self.opts.screenshot_dir);
        loop {
            self.shots += 1;
            let path = self.opts.screenshot_dir.join(format!("lucent-view-{:04}.png", self.shots));
            if path.exists() {
                continue;
            }
            // Written beside, then renamed: whoever watches the folder never sees half a file.
            let part = self.opts.screenshot_dir.join(format!(".lucent-view-{:04}.part.png", self.shots));
            match film.save(&part).map_err(|e| e.to_string()).and_then(|()| std::fs::rename(&part, &path).map_err(|e| e.to_string())) {
                Ok(()) => println!("screenshot: {} ({}x{})", path.display(), film.width, film.height),
                Err(e) => tracing::error!("screenshot failed: {e}"),
            }
            break;
        }
    }

    /// Renders what is due; returns false when nothing needed rendering.
    fn render(&mut self) -> bool {
        let full = self.size();
        if self.program.is_some() {
            return self.render_program(full);
        }
        let now = Instant::now();
        let dt = now.duration_since(self.last_tick).as_secs_f32();
        self.last_tick = now;
        let moving = self.moving();
        if self.anim_playing || self.dirty {
            self.animate(dt);
        }
        self.navigate(dt);
        self.mouse_delta = (0.0, 0.0);
        if moving {
            self.still_since = None;
            self.reported_converged = false;
        } else if self.still_since.is_none() {
            self.still_since = Some(now);
        }
        // The planner hears how long a moving frame took, from its start to the start of the
        // next one (render, display and events: everything that sets the frame rate).
        if let Some((p, m, t)) = self.pending.take() {
            self.adaptive.finished(&p, now.duration_since(t).as_secs_f64(), m);
        }
        let Some(plan) = self.adaptive.plan(moving, full) else {
            if self.opts.report && !self.reported_converged {
                if let Some(t) = self.still_since {
                    println!(
                        "converged: {} samples per pixel at {}x{} in {:.2} s",
                        self.adaptive.samples(),
                        full.0,
                        full.1,
                        t.elapsed().as_secs_f64()
                    );
                }
                self.reported_converged = true;
            }
            return std::mem::take(&mut self.dirty);
        };
        let (Some(world), Some(cam)) = (self.world.as_ref(), self.cam.as_ref()) else { return false };
        let desc = cam.desc();
        let camera = Camera::new(&desc, plan.width, plan.height);
        // The first pass is the one-sample image (pixel centres); the passes after it add the
        // jittered samples 1, 2, ... of the image of `max_samples` samples.
        let spp = if plan.sample == 0 { 1 } else { self.adaptive.max_samples };
        let rs = RenderSettings { spp, integrator: self.integrator(), ..RenderSettings::new(plan.width, plan.height) };
        let region = Region::full(plan.width, plan.height, plan.sample, plan.sample + 1);
        let time = self.anim_range.map(|_| self.anim_time);
        let (film, rays) = match self.passes.as_mut() {
            Some(p) => p.render(world, time, &camera, &rs, region),
            None => render_region(world, &camera, &rs, region, &|_| {}),
        };
        if moving {
            self.pending = Some((plan, moving, now));
        } else {
            self.adaptive.finished(&plan, 0.0, false);
        }
        self.acc.add(film, plan.accumulate);
        self.denoise_shown(&desc, (plan.width, plan.height), moving);
        self.count(rays, moving, plan);
        true
    }

    fn render_program(&mut self, full: (u32, u32)) -> bool {
        let Some(p) = self.program.as_mut() else { return false };
        if p.paused || p.halted {
            return std::mem::take(&mut self.dirty);
        }
        match p.p.run_to_frame(50_000_000) {
            Step::Frame => {
                let fs = FrameSettings { width: full.0, height: full.1, ..p.fs };
                match render_frame(&p.p.state, &fs) {
                    Ok((film, info)) => {
                        p.frames += 1;
                        p.last = Some(film);
                        let rays = info.rays;
                        self.count(rays, false, Plan { width: full.0, height: full.1, sample: 0, accumulate: false });
                    }
                    Err(e) => {
                        tracing::error!("frame {} could not be rendered: {e}", p.frames + 1);
                        p.halted = true;
                    }
                }
            }
            Step::Busy => {
                tracing::error!("the program runs a loop without nf: stopped");
                p.halted = true;
            }
            Step::Halt | Step::Continue => p.halted = true,
        }
        true
    }

    fn count(&mut self, rays: u64, moving: bool, plan: Plan) {
        self.fps_frames += 1;
        self.fps_rays += rays;
        self.last_plan = Some(plan);
        let el = self.fps_since.elapsed().as_secs_f64();
        if el >= 1.0 {
            self.fps = f64::from(self.fps_frames) / el;
            self.mrays = self.fps_rays as f64 / el / 1e6;
            if self.opts.report {
                println!(
                    "{}: {:.1} fps, {:.1} Mrays/s at {}x{}",
                    if self.program.is_some() {
                        "program"
                    } else if moving {
                        "moving"
                    } else {
                        "still"
                    },
                    self.fps,
                    self.mrays,
                    plan.width,
                    plan.height
                );
            }
            self.fps_frames = 0;
            self.fps_rays = 0;
            self.fps_since = Instant::now();
        }
    }

    fn hud(&self, full: (u32, u32)) -> String {
        let res = self.last_plan.map_or(String::new(), |p| {
            let pct = 100.0 * f64::from(p.width * p.height) / f64::from((full.0 * full.1).max(1));
            format!("{}x{} ({pct:.0}%)", p.width, p.height)
        });
        if let Some(p) = &self.program {
            return format!(
                "{:.1} fps | {:.1} Mrays/s | {res} | REND3R frame {} {}| {} sets, {} lights | space: pause",
                self.fps,
                self.mrays,
                p.frames,
                if p.paused {
                    "paused "
                } else if p.halted {
                    "halted "
                } else {
                    ""
                },
                p.p.state.used_sets(),
                p.p.state.used_lights()
            );
        }
        let (mode, proj) = self
            .cam
            .as_ref()
            .map_or(("", ""), |c| (if c.mode == NavMode::Fly { "fly" } else { "orbit" }, if c.ortho { "ortho" } else { "persp" }));
        let anim = match self.anim_range {
            Some(_) => format!(" | t {:.2} s {}", self.anim_time, if self.anim_playing { "playing" } else { "paused" }),
            None => String::new(),
        };
        let integrator = match self.integrator() {
            Integrator::Vpl(v) => format!("vpl {} VPLs {}x{}", v.count, v.interleave, v.interleave),
            i => i.name().to_string(),
        };
        let denoise = if self.shown.is_some() && self.temporal_frames > 1.0 {
            format!(" | {:.1} frames, denoised ({:.0} ms)", self.temporal_frames, self.denoise_ms)
        } else if self.shown.is_some() {
            format!(" | denoised ({:.0} ms)", self.denoise_ms)
        } else if self.denoising() {
            " | denoise faded".to_string()
        } else {
            String::new()
        };
        format!(
            "{:.1} fps | {:.1} Mrays/s | {res} | {}/{} spp | {integrator}{denoise} | shadows {} | depth {} | {proj} | {mode} | {}{anim}",
            self.fps,
            self.mrays,
            self.adaptive.samples(),
            self.adaptive.max_samples,
            if self.whitted.shadows { "on" } else { "off" },
            self.whitted.max_depth,
            self.stats
        )
    }

    fn present(&mut self) {
        let full = self.size();
        let hud = self.hud(full);
        let state = match &self.program {
            Some(p) => format!("program, frame {}{}", p.frames, if p.paused { ", paused" } else { "" }),
            None => String::new(),
        };
        let title = format!(
            "lucent view: {} [{}]",
            self.name,
            if self.program.is_some() {
                state.as_str()
            } else if self.anim_range.is_some() && !self.anim_playing && self.adaptive.converged() {
                "paused, converged"
            } else if self.adaptive.converged() {
                "converged"
            } else if self.moving() {
                "moving"
            } else {
                "refining"
            }
        );
        let Some(g) = self.gfx.as_mut() else { return };
        if g.window.title() != title {
            g.window.set_title(&title);
        }
        let (Some(w), Some(h)) = (NonZeroU32::new(full.0), NonZeroU32::new(full.1)) else { return };
        if let Err(e) = g.surface.resize(w, h) {
            self.error = Some(ViewerError::Window(e.to_string()));
            return;
        }
        let mut buf = match g.surface.buffer_mut() {
            Ok(b) => b,
            Err(e) => {
                self.error = Some(ViewerError::Window(e.to_string()));
                return;
            }
        };
        if buf.len() != (full.0 * full.1) as usize {
            return;
        }
        match self.program.as_ref() {
            Some(p) => match &p.last {
                Some(f) => crate::control::blit(&f.pixels, f.width, f.height, 1.0, &mut buf, full.0, full.1),
                None => buf.fill(0),
            },
            None => match &self.shown {
                Some(f) => crate::control::blit(&f.pixels, f.width, f.height, 1.0, &mut buf, full.0, full.1),
                None => {
                    let img = self.acc.image();
                    blit(&img.pixels, img.width, img.height, 1.0, &mut buf, full.0, full.1);
                }
            },
        }
        let scale = if full.0 >= 900 { 2 } else { 1 };
        draw_text(&mut buf, full.0 as usize, 4, 4, scale, &hud, 0x00ff_ff80);
        if let Err(e) = buf.present() {
            self.error = Some(ViewerError::Window(e.to_string()));
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        let attrs = Window::default_attributes()
            .with_title(format!("lucent view: {}", self.name))
            .with_inner_size(winit::dpi::PhysicalSize::new(self.opts.size.0, self.opts.size.1));
        let window = match el.create_window(attrs) {
            Ok(w) => Rc::new(w),
            Err(e) => {
                self.error = Some(ViewerError::NoDisplay(e.to_string()));
                el.exit();
                return;
            }
        };
        let surface = softbuffer::Context::new(Rc::clone(&window)).and_then(|c| softbuffer::Surface::new(&c, Rc::clone(&window)));
        match surface {
            Ok(surface) => self.gfx = Some(Gfx { window, surface }),
            Err(e) => {
                self.error = Some(ViewerError::Window(e.to_string()));
                el.exit();
            }
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(_) => {
                self.adaptive.restart();
                self.dirty = true;
            }
            WindowEvent::KeyboardInput { event, .. } => {
                tracing::debug!(key = ?event.physical_key, state = ?event.state, repeat = event.repeat, "key");
                if let PhysicalKey::Code(code) = event.physical_key {
                    match event.state {
                        ElementState::Pressed => {
                            // X11 (XInput2) sometimes reports one press twice, neither as a
                            // repeat: a key already down is not pressed again, so toggles
                            // such as Space do not flip back.
                            if !event.repeat && !self.keys.contains(&code) {
                                self.key(code, el);
                            }
                            self.keys.insert(code);
                        }
                        ElementState::Released => {
                            self.keys.remove(&code);
                        }
                    }
                }
            }
            WindowEvent::MouseInput { state, button: MouseButton::Left | MouseButton::Right, .. } => {
                self.dragging = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let Some((x, y)) = self.cursor {
                    if self.dragging {
                        self.mouse_delta.0 += (position.x - x) as f32;
                        self.mouse_delta.1 += (position.y - y) as f32;
                    }
                }
                self.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                if let Some(c) = self.cam.as_mut() {
                    c.scroll(lines);
                }
            }
            WindowEvent::Focused(false) => self.keys.clear(),
            WindowEvent::RedrawRequested => {
                if self.render() {
                    self.present();
                }
                if self.error.is_some() {
                    el.exit();
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, el: &ActiveEventLoop) {
        if self.opts.quit_after.is_some_and(|s| self.started.elapsed().as_secs_f64() >= s) {
            el.exit();
            return;
        }
        if let Some(p) = &self.program {
            // A REND3R program plays at the target frame rate (a looping one would
            // otherwise redraw the same picture as fast as the cores allow).
            if !(p.paused || p.halted) || self.dirty {
                let next = self.last_tick + Duration::from_secs_f64(1.0 / self.opts.target_fps.max(1.0));
                if Instant::now() >= next {
                    self.last_tick = Instant::now();
                    if let Some(g) = &self.gfx {
                        g.window.request_redraw();
                    }
                    el.set_control_flow(ControlFlow::WaitUntil(
                        Instant::now() + Duration::from_secs_f64(1.0 / self.opts.target_fps.max(1.0)),
                    ));
                } else {
                    el.set_control_flow(ControlFlow::WaitUntil(next));
                }
            } else {
                el.set_control_flow(ControlFlow::WaitUntil(Instant::now() + Duration::from_millis(250)));
            }
            return;
        }
        if self.moving() || !self.adaptive.converged() || self.dirty {
            if let Some(g) = &self.gfx {
                g.window.request_redraw();
            }
            el.set_control_flow(ControlFlow::Poll);
        } else {
            // Idle until an event, but wake now and then for --quit-after.
            el.set_control_flow(ControlFlow::WaitUntil(Instant::now() + Duration::from_millis(250)));
        }
    }
}

/// Opens the window and runs until it is closed.
pub fn run(content: Content, opts: ViewOptions) -> Result<(), ViewerError> {
    run_with(content, opts, None)
}

/// [`run`], with the passes rendered by `passes` (when given).
pub fn run_with(content: Content, opts: ViewOptions, passes: Option<Box<dyn PassRenderer>>) -> Result<(), ViewerError> {
    if std::env::var_os("DISPLAY").is_none_or(|d| d.is_empty()) && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        return Err(ViewerError::NoDisplay("DISPLAY is not set".into()));
    }
    let event_loop = EventLoop::new().map_err(|e| ViewerError::NoDisplay(e.to_string()))?;
    let now = Instant::now();
    let adaptive = Adaptive::new(opts.target_fps, opts.max_samples, opts.moving_scale);
    let view = opts.view % VIEWS;
    let mut app = App {
        opts,
        passes,
        name: String::new(),
        world: None,
        program: None,
        stats: String::new(),
        cam: None,
        adaptive,
        acc: Progressive::default(),
        whitted: WhittedSettings::default(),
        view,
        denoise: true,
        shown: None,
        guides: None,
        denoise_ms: 0.0,
        temporal: Temporal::new(TEMPORAL_FRAMES),
        temporal_on: true,
        temporal_frames: 0.0,
        gfx: None,
        error: None,
        keys: HashSet::new(),
        dragging: false,
        cursor: None,
        mouse_delta: (0.0, 0.0),
        last_tick: now,
        fps_frames: 0,
        fps_rays: 0,
        fps_since: now,
        fps: 0.0,
        mrays: 0.0,
        still_since: None,
        reported_converged: false,
        started: now,
        shots: 0,
        dirty: true,
        last_plan: None,
        pending: None,
        anim_range: None,
        anim_time: 0.0,
        anim_playing: false,
        follow: false,
    };
    match content {
        Content::Scene { world, home, stats, name } => {
            if let Some(a) = world.scene().animation.as_ref().filter(|a| a.is_animated()) {
                let r = a.time_range();
                app.anim_range = Some(r);
                app.anim_time = r.0;
                app.anim_playing = true;
                app.follow = a.camera.is_some();
            }
            app.cam = Some(CameraController::new(home, world.scale()));
            app.world = Some(world);
            app.stats = stats;
            app.name = name;
        }
        Content::Program { processor, settings, name } => {
            app.program = Some(Program { p: processor, fs: settings, frames: 0, halted: false, paused: false, last: None });
            app.name = name;
        }
    }
    event_loop.run_app(&mut app).map_err(|e| ViewerError::Window(e.to_string()))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}
