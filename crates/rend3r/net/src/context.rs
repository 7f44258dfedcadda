//! What every connection of a server shares: its configuration, the count of open
//! connections, the shared device, and each connection's clock of last traffic.

use crate::device::{self, DeviceLimits, In};
use crate::protocol::WireMode;
use crossbeam_channel::Sender;
use rend3r_machine::{FrameSettings, Mode, SetKind};
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How long a new connection may take to send its hello.
pub const HELLO_TIMEOUT: Duration = Duration::from_secs(10);
/// Everything `lucent serve` can be told.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// TCP address of the device protocol.
    pub listen: SocketAddr,
    /// UDP address (fire-and-forget batches), if any.
    pub udp: Option<SocketAddr>,
    /// HTTP address of the page and its WebSocket, if any.
    pub http: Option<SocketAddr>,
    /// Default frame size.
    pub width: u32,
    /// Default frame height.
    pub height: u32,
    /// Default mode.
    pub mode: Mode,
    /// One device for every client, all receiving its frames.
    pub shared: bool,
    /// Largest message payload (bytes).
    pub max_message: u32,
    /// Largest frame (pixels).
    pub max_frame_pixels: u64,
    /// Most simultaneous connections (TCP + HTTP) and UDP sessions.
    pub max_connections: usize,
    /// Close a connection with no traffic either way for this long.
    pub idle_timeout: Duration,
    /// Close a connection that does not take a frame within this long.
    pub write_timeout: Duration,
    /// Payload bytes of a UDP frame chunk.
    pub udp_chunk: usize,
    /// Per-device limits.
    pub device: DeviceLimits,
    /// Folder of example `.rdr` programs listed on the page.
    pub examples: Option<PathBuf>,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 7878)),
            udp: None,
            http: None,
            width: 512,
            height: 384,
            mode: Mode::Raytrace,
            shared: false,
            max_message: 1 << 20,
            max_frame_pixels: 4096 * 4096,
            max_connections: 256,
            idle_timeout: Duration::from_secs(300),
            write_timeout: Duration::from_secs(10),
            udp_chunk: 1200,
            device: DeviceLimits::default(),
            examples: None,
        }
    }
}

/// Shared server state.
pub(crate) struct Ctx {
    pub(crate) cfg: ServerConfig,
    pub(crate) conns: AtomicUsize,
    pub(crate) next_id: AtomicU64,
    pub(crate) shared: Option<Sender<In>>,
    pub(crate) stop: AtomicBool,
    pub(crate) epoch: Instant,
    /// Words accepted by all devices (for `lucent bench net`).
    pub(crate) words_in: AtomicU64,
}

/// Decrements the connection count when a connection ends.
pub(crate) struct ConnGuard(Arc<Ctx>);

impl Drop for ConnGuard {
    fn drop(&mut self) {
        self.0.conns.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Ctx {
    pub(crate) fn admit(self: &Arc<Self>) -> Option<ConnGuard> {
        let n = self.conns.fetch_add(1, Ordering::SeqCst);
        if n >= self.cfg.max_connections {
            self.conns.fetch_sub(1, Ordering::SeqCst);
            return None;
        }
        Some(ConnGuard(Arc::clone(self)))
    }
    pub(crate) fn id(&self) -> u64 {
        self.next_id.fetch_add(1, Ordering::Relaxed)
    }
    fn now_ms(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_millis()).unwrap_or(u64::MAX)
    }
    /// A device for a new client: the shared one, or a new one of its own.
    pub(crate) fn device(&self, fs: FrameSettings, id: u64) -> io::Result<Sender<In>> {
        match &self.shared {
            Some(d) => Ok(d.clone()),
            None => device::spawn(fs, self.cfg.device, format!("device-{id}")),
        }
    }
    pub(crate) fn frame_settings(&self, width: u32, height: u32, mode: Mode) -> FrameSettings {
        frame_settings(width, height, mode)
    }
    /// Resolves a requested frame size and mode against the defaults and limits.
    pub(crate) fn resolve(&self, w: u16, h: u16, mode: WireMode) -> Result<(u32, u32, Mode), String> {
        if self.shared.is_some() {
            return Ok((self.cfg.width, self.cfg.height, self.cfg.mode));
        }
        let w = if w == 0 { self.cfg.width } else { u32::from(w) };
        let h = if h == 0 { self.cfg.height } else { u32::from(h) };
        if u64::from(w) * u64::from(h) > self.cfg.max_frame_pixels {
            return Err(format!("a {w}x{h} frame is over this server's limit of {} pixels (--max-frame)", self.cfg.max_frame_pixels));
        }
        let mode = match mode {
            WireMode::Default => self.cfg.mode,
            WireMode::Raytrace => Mode::Raytrace,
            WireMode::Raster => Mode::Raster,
        };
        Ok((w, h, mode))
    }
}

/// Frame settings of a device: `lucent run`'s (words read as shapes when ray tracing, as
/// triangles when rasterizing; one sample; z-buffer).
pub(crate) fn frame_settings(width: u32, height: u32, mode: Mode) -> FrameSettings {
    FrameSettings { width, height, mode, sets: SetKind::for_mode(mode), painter: false, spp: 1 }
}

/// Time of the last traffic on a connection, either way.
#[derive(Clone)]
pub(crate) struct Activity(Arc<AtomicU64>, Arc<Ctx>);

impl Activity {
    pub(crate) fn new(ctx: &Arc<Ctx>) -> Self {
        Self(Arc::new(AtomicU64::new(ctx.now_ms())), Arc::clone(ctx))
    }
    pub(crate) fn touch(&self) {
        self.0.store(self.1.now_ms(), Ordering::Relaxed);
    }
    pub(crate) fn idle(&self) -> Duration {
        Duration::from_millis(self.1.now_ms().saturating_sub(self.0.load(Ordering::Relaxed)))
    }
}
