//! # lucent_fuzzing
//!
//! One harness per reader of untrusted bytes: each takes any bytes and must return, never
//! panic, hang or allocate beyond a bound. The cargo-fuzz targets in `fuzz/` (nightly) call
//! these functions; `tests/replay.rs` (stable, part of `cargo test`) runs every committed
//! seed and every input a campaign found (`fuzz/regressions/<target>/`) through the same
//! functions, so CI checks the findings without nightly. `scripts/fuzz --minutes N` runs a
//! campaign.
//!
//! Bounds the campaign enforces (libFuzzer's `-rss_limit_mb` / `-malloc_limit_mb`, and
//! `-timeout`): [`MALLOC_LIMIT_MB`] per allocation and in all, [`TIMEOUT_S`] per input.
#![deny(missing_docs)]

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

/// The most memory one input may take (MB), as the campaign runs libFuzzer.
pub const MALLOC_LIMIT_MB: usize = 2048;
/// The longest one input may run (seconds, release build), as the campaign runs libFuzzer.
pub const TIMEOUT_S: u64 = 10;

/// A harness: any bytes in, nothing out (errors are fine, panics are findings).
pub type Harness = fn(&[u8]);

/// Every target: its name (the cargo-fuzz binary, the corpus and regression folder) and
/// its harness.
pub const TARGETS: &[(&str, Harness)] = &[
    ("obj", obj),
    ("mtl", mtl),
    ("ply", ply),
    ("gltf", gltf),
    ("glb", glb),
    ("image", image),
    ("asm", asm),
    ("mem", mem),
    ("decode", decode),
    ("net", net),
    ("ws", websocket),
    ("http", http),
    ("xml", mitsuba),
    ("serialized", serialized),
    ("cluster", cluster),
];

/// The harness of target `name`.
#[must_use]
pub fn harness(name: &str) -> Option<Harness> {
    TARGETS.iter().find(|t| t.0 == name).map(|t| t.1)
}

/// Builds every mesh `scene` gave with the default build, so what a loader lets through
/// also meets the builder.
fn build_all(scene: &lucent_scene::Scene) {
    let _ = scene.stats();
    for m in &scene.meshes {
        if let Ok(bvh) = lucent_accel::MeshBvh::build(&m.positions, &m.indices, lucent_accel::MeshOptions::default()) {
            let _ = bvh.intersect(&lucent_accel::Ray::new(lucent_accel::glam::Vec3::splat(-1.0), lucent_accel::glam::Vec3::ONE));
        }
    }
}

/// A folder that does not exist: what an in-memory input names beside it is missing.
const NOWHERE: &str = "/nonexistent/lucent-fuzz";

/// Wavefront OBJ, in memory (an `mtllib` or texture it names is missing: a warning).
pub fn obj(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(scene) = lucent_scene::parse_obj(Path::new("fuzz.obj"), Path::new(NOWHERE), text) {
        build_all(&scene);
    }
}

/// An MTL file, read through an OBJ that names it and uses its first material, in memory
/// (PERF: written to files and loaded from there, the target ran 1,200 inputs a second).
/// Text that is not UTF-8 is refused as the file loader refuses it.
pub fn mtl(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let name = text.lines().find_map(|l| l.trim().strip_prefix("newmtl ").map(str::trim)).unwrap_or("m").replace(['\n', '\r'], "");
    let obj = format!("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl {name}\nf 1/1 2/2 3/3\n");
    let mut read = |p: &Path| {
        if p.file_name() == Some(std::ffi::OsStr::new("m.mtl")) {
            Ok(text.to_string())
        } else {
            Err(std::io::Error::from(std::io::ErrorKind::NotFound))
        }
    };
    if let Ok(scene) = lucent_scene::parse_obj_with(Path::new("m.obj"), Path::new(NOWHERE), &obj, &mut read) {
        build_all(&scene);
    }
}

/// A Mitsuba 3 XML scene, in memory (the files it names are missing: errors or
/// warnings), then its meshes built.
pub fn mitsuba(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(scene) = lucent_scene::parse_mitsuba(Path::new("fuzz.xml"), Path::new(NOWHERE), text) {
        build_all(&scene);
    }
}

/// Mitsuba's `.serialized` meshes, in memory: the first and the second mesh of the file,
/// then built.
pub fn serialized(data: &[u8]) {
    for index in 0..2 {
        if let Ok(m) = lucent_scene::parse_serialized(data, index) {
            if let Ok(bvh) = lucent_accel::MeshBvh::build(&m.positions, &m.indices, lucent_accel::MeshOptions::default()) {
                let _ = bvh.intersect(&lucent_accel::Ray::new(lucent_accel::glam::Vec3::splat(-1.0), lucent_accel::glam::Vec3::ONE));
            }
        }
    }
}

/// A message between MPI ranks (`lucent_cluster::Msg`): decoded, re-encoded, and a small
/// result merged into an image that holds it.
pub fn cluster(data: &[u8]) {
    use lucent_cluster::Msg;
    let Ok(m) = Msg::decode(data) else { return };
    let again = m.encode();
    assert!(Msg::decode(&again).is_ok_and(|x| x.encode() == again), "a decoded message re-encodes to itself");
    if let Msg::Done { film, .. } = m {
        let r = film.region;
        // (An image that holds the region, when it is small: a large one would measure the
        // allocator, not the merge.)
        if u64::from(r.x1) * u64::from(r.y1) <= 1 << 16 {
            let mut acc = lucent_render::FilmAccumulator::new(r.x1, r.y1);
            let _ = acc.merge(film);
            let _ = acc.resolve(lucent_accel::glam::Vec3::ZERO);
        }
    }
}

/// PLY, ASCII or binary (the header says which), in memory.
pub fn ply(data: &[u8]) {
    if let Ok(scene) = lucent_scene::parse_ply(Path::new("fuzz.ply"), data) {
        build_all(&scene);
    }
}

/// glTF JSON, in memory (buffers and images as data URIs; files it names are missing).
/// Read strictly (every rule of the specification, and the data checks) and as by
/// default (warnings, reading what can be read).
pub fn gltf(data: &[u8]) {
    // Decoder panics unwind to `decode_image`, which contains them (any other panic still
    // reaches libFuzzer's hook: a finding).
    lucent_scene::contain_decoder_panics();
    let strict = lucent_scene::LoadOptions { strict: true };
    let _ = lucent_scene::parse_gltf_with(Path::new("fuzz.gltf"), Path::new(NOWHERE), data, &strict);
    if let Ok(scene) = lucent_scene::parse_gltf(Path::new("fuzz.gltf"), Path::new(NOWHERE), data) {
        build_all(&scene);
    }
}

/// GLB, in memory: JSON chunk, binary chunk, embedded images. (The glTF reader tells GLB
/// from JSON by the first bytes, so the targets differ only in their corpora.)
pub fn glb(data: &[u8]) {
    gltf(data);
}

/// An image as a texture: decoded as the glTF loader decodes embedded images
/// ([`lucent_scene::decode_image`], PNG or JPEG, within the texture limits), then turned into
/// a texture.
pub fn image(data: &[u8]) {
    // Decoder panics unwind to `decode_image`, which contains them (any other panic still
    // reaches libFuzzer's hook: a finding).
    lucent_scene::contain_decoder_panics();
    if let Ok(img) = lucent_scene::decode_image(data) {
        let t = lucent_scene::texture_from_image("fuzz".into(), img, lucent_scene::Wrap::Repeat, lucent_scene::Wrap::Repeat, true);
        let _ = t.texel_at(0, 0);
    }
}

/// REND3R assembly: whatever assembles must disassemble and reassemble to the same words.
pub fn asm(data: &[u8]) {
    use rend3r_isa::{assemble_words, disassemble, AsmOptions, DisasmOptions};
    let Ok(src) = std::str::from_utf8(data) else { return };
    if let Ok(words) = assemble_words(src, AsmOptions::default()) {
        let text = disassemble(&words, DisasmOptions::default()).expect("assembled words decode");
        assert_eq!(assemble_words(&text, AsmOptions::default()).expect("disassembly assembles"), words);
    }
}

/// `.mem` text and raw binary programs, then the words through the processor.
pub fn mem(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(words) = rend3r_isa::from_mem(text) {
            run_words(&words);
        }
    }
    if let Ok(words) = rend3r_isa::from_bin(data) {
        run_words(&words);
    }
}

/// Runs `words` through a processor for a bounded number of steps (no frames rendered).
fn run_words(words: &[u32]) {
    if let Ok(mut p) = rend3r_machine::Processor::new(words.to_vec(), rend3r_isa::CameraTable::Final) {
        run_steps(&mut p);
    }
}

/// At most 16 frames of at most 4,096 words each (a busy loop is stopped): enough to reach
/// every instruction, `lr` loops and `nr` resets, while an endless loop costs 65,536 steps.
fn run_steps(p: &mut rend3r_machine::Processor) {
    use rend3r_machine::Step;
    for _ in 0..16 {
        match p.run_to_frame(4_096) {
            Step::Frame => {}
            Step::Busy => p.stop(),
            _ => break,
        }
    }
}

/// Big-endian words through the decoders and the disassembler (whatever disassembles
/// reassembles to the same words).
pub fn decode(data: &[u8]) {
    use rend3r_isa::{assemble_words, decode, disassemble, AsmOptions, DisasmOptions};
    let words: Vec<u32> = data.chunks_exact(4).map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]])).collect();
    let _ = decode(&words);
    if let Ok(text) = disassemble(&words, DisasmOptions::default()) {
        assert_eq!(assemble_words(&text, AsmOptions::default()).expect("disassembly assembles"), words);
    }
}

/// The TCP/UDP wire protocol: a hello, then messages whose payloads are run as
/// instruction batches by a streaming processor, plus every server-message decoder.
pub fn net(data: &[u8]) {
    use rend3r_machine::Processor;
    use rend3r_net::protocol::{self, Chunk, Done, ErrorMessage, FrameHeader, Hello, Welcome, HELLO_LEN};
    if data.len() >= HELLO_LEN {
        let mut h = [0u8; HELLO_LEN];
        h.copy_from_slice(&data[..HELLO_LEN]);
        let _ = Hello::parse(&h);
    }
    let _ = (ErrorMessage::decode(data), Done::decode(data), FrameHeader::decode(data), Welcome::decode(data), Chunk::decode(data));
    let Ok(mut p) = Processor::new(Vec::new(), rend3r_isa::CameraTable::Final) else { return };
    let mut r = data.get(HELLO_LEN.min(data.len())..).unwrap_or(&[]);
    while let Ok(Some((_, payload))) = protocol::read_message(&mut r, 4096) {
        let words = protocol::words_from_bytes(&payload);
        if rend3r_isa::decode(&words).is_ok() && p.push(&words).is_ok() {
            run_steps(&mut p);
        }
    }
}

/// A client's side of a WebSocket as the server reads it: bytes in, writes discarded.
struct Duplex<'a>(&'a [u8]);

impl Read for Duplex<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for Duplex<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// WebSocket frames as the server reads them (the server's message size limits), each
/// message handled as the page's are: text assembled, binary decoded as words, both run.
pub fn websocket(data: &[u8]) {
    use tungstenite::protocol::{Role, WebSocketConfig};
    use tungstenite::{Message, WebSocket};
    let max = rend3r_net::ServerConfig::default().max_message as usize;
    let config = WebSocketConfig::default().max_message_size(Some(max)).max_frame_size(Some(max));
    let mut ws = WebSocket::from_raw_socket(Duplex(data), Role::Server, Some(config));
    for _ in 0..1024 {
        match ws.read() {
            Ok(Message::Text(t)) => {
                if let Ok(words) = rend3r_isa::assemble_words(t.as_str(), rend3r_isa::AsmOptions::default()) {
                    run_words(&words);
                }
            }
            Ok(Message::Binary(b)) => run_words(&rend3r_net::protocol::words_from_bytes(&b)),
            Ok(_) => {}
            Err(_) => break,
        }
    }
}

/// An HTTP request head as the page server parses it.
pub fn http(data: &[u8]) {
    let r = rend3r_net::http::parse_head(data);
    let _ = (r.header("upgrade"), r.header("sec-websocket-key"), r.path.split('?').next());
}

/// The fuzz target that reads a shared file, by its name (`None`: none reads it). The
/// replay test runs every shared file through its target; the seed corpora are made
/// from the same files (`examples/seeds.rs`).
#[must_use]
pub fn target_for(path: &Path) -> Option<&'static str> {
    let name = path.file_name()?.to_string_lossy().to_lowercase();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    Some(match stem.rsplit('.').next()? {
        "obj" => "obj",
        "mtl" => "mtl",
        "ply" => "ply",
        "gltf" => "gltf",
        "glb" => "glb",
        "png" | "jpg" | "jpeg" => "image",
        "rdr" | "asm" | "s" => "asm",
        "mem" => "mem",
        "xml" => "xml",
        "serialized" => "serialized",
        _ => return None,
    })
}

/// The files below `dir` (one level), sorted: a corpus or a regression folder.
#[must_use]
pub fn inputs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> =
        std::fs::read_dir(dir).map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file()).collect()).unwrap_or_default();
    v.sort();
    v
}
