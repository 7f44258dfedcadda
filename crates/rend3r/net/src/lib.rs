//! # rend3r_net
//!
//! REND3R as a networked device: `lucent serve` and `lucent send`. Clients stream
//! instruction words (or assembly text) over TCP, UDP or a WebSocket; each `nf` comes
//! back as a frame. The wire protocol is in `docs/protocol.md` and [`protocol`]; the
//! device semantics for streamed programs in [`device`]; the endpoints, limits and
//! timeouts in [`server`]; the page in [`http`]; a client in [`client`].
//!
//! Threads, not async: one reader and one writer per TCP connection, one thread per
//! WebSocket, one per device, all bounded by `--max-connections`; frames are rendered on
//! the shared rayon pool.
#![deny(missing_docs)]

pub mod client;
mod context;
pub mod device;
pub mod encode;
pub mod http;
pub mod protocol;
pub mod server;

pub use client::{Client, Event};
pub use context::{ServerConfig, HELLO_TIMEOUT};
pub use device::{DeviceFrame, DeviceLimits};
pub use protocol::{ErrorMessage, Hello, Input, PixelFormat, WireMode};
pub use server::Server;
