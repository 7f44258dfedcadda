//! Writes the seed corpora of every fuzz target: `cargo run --release -p lucent_fuzzing
//! --example seeds -- OUT SHARED`, with `OUT` the corpus folder (`fuzz/corpus`, one folder
//! per target) and `SHARED` the `shared/` folder beside the checkout. Scene and program
//! files come from `SHARED/scenes` and `SHARED/rend3r` (at most [`MAX_SEED`] bytes each;
//! gzipped OBJ files unpacked); the binary protocols' seeds are made with lucent's own
//! encoders. `scripts/fuzz` runs this before a campaign.

use std::io::Read;
use std::path::{Path, PathBuf};

/// The largest file taken as a seed (bytes): libFuzzer mutates small inputs far faster.
const MAX_SEED: u64 = 256 * 1024;

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(out), Some(shared)) = (args.get(1), args.get(2)) else {
        return Err("usage: seeds OUT SHARED (the corpus folder and the shared/ folder)".into());
    };
    let (out, shared) = (PathBuf::from(out), PathBuf::from(shared));
    let mut counts = std::collections::BTreeMap::<&str, usize>::new();
    let mut put = |target: &'static str, name: String, data: &[u8]| -> std::io::Result<()> {
        let dir = out.join(target);
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join(name.replace(['/', '\\'], "_")), data)?;
        *counts.entry(target).or_default() += 1;
        Ok(())
    };
    let mut files = Vec::new();
    walk(&shared.join("scenes"), &mut files);
    walk(&shared.join("rend3r"), &mut files);
    // Mitsuba scenes: the repository's own.
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    walk(&repo.join("tools/mitsuba/scenes"), &mut files);
    files.sort();
    for f in &files {
        let len = std::fs::metadata(f)?.len();
        let rel = f.strip_prefix(&shared).or_else(|_| f.strip_prefix(&repo)).unwrap_or(f).display().to_string();
        let name = f.file_name().map(|n| n.to_string_lossy().to_lowercase()).unwrap_or_default();
        if name.ends_with(".obj.gz") {
            // Unpacked, cut to the first 256 KB of lines.
            let mut text = Vec::new();
            flate2::read::GzDecoder::new(std::fs::File::open(f)?).take(MAX_SEED).read_to_end(&mut text)?;
            let cut = text.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
            put("obj", rel, &text[..cut])?;
            continue;
        }
        if len > MAX_SEED {
            continue;
        }
        let Some(target) = lucent_fuzzing::target_for(f) else { continue };
        let data = std::fs::read(f)?;
        if target == "image" {
            // Small re-encodings of each texture: a 1024² PNG decodes ~20 times a second
            // under the sanitizer, a 24² one thousands of times. (The replay test still runs
            // every full-size file through the harness.)
            for (i, small) in small_images(&data).iter().enumerate() {
                put("image", format!("{rel}.{i}"), small)?;
            }
            continue;
        }
        put(target, rel.clone(), &data)?;
        if target == "mem" {
            // The same program as raw big-endian words (the binary decoder's input) and in
            // the wire protocol.
            if let Ok(words) = rend3r_isa::from_mem(&String::from_utf8_lossy(&data)) {
                let bytes = rend3r_isa::to_bin(&words);
                put("decode", rel.clone(), &bytes)?;
                put("mem", format!("{rel}.bin"), &bytes)?;
                let hello = rend3r_net::Hello {
                    input: rend3r_net::Input::Words,
                    format: rend3r_net::PixelFormat::Rgb565,
                    old_camera_table: false,
                    width: 64,
                    height: 48,
                    mode: rend3r_net::WireMode::Default,
                };
                let mut wire = hello.encode().to_vec();
                for chunk in words.chunks(64) {
                    rend3r_net::protocol::write_message(&mut wire, 1, &rend3r_net::protocol::words_to_bytes(chunk))?;
                }
                put("net", rel.clone(), &wire)?;
                put("ws", format!("{rel}.bin"), &ws_frame(2, &rend3r_net::protocol::words_to_bytes(&words), true))?;
            }
        }
        if target == "asm" && data.len() < 60_000 {
            put("ws", rel, &ws_frame(1, &data, true))?;
        }
    }
    // Small PLY files of each encoding, and HTTP heads the page server sees.
    let tri = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    put("ply", "ascii.ply".into(), format!("ply\nformat ascii 1.0\n{tri}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").as_bytes())?;
    for (name, le) in [("binary_le.ply", true), ("binary_be.ply", false)] {
        let fmt = if le { "binary_little_endian" } else { "binary_big_endian" };
        let mut b = format!("ply\nformat {fmt} 1.0\n{tri}").into_bytes();
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            b.extend(if le { v.to_le_bytes() } else { v.to_be_bytes() });
        }
        b.push(3);
        for i in [0i32, 1, 2] {
            b.extend(if le { i.to_le_bytes() } else { i.to_be_bytes() });
        }
        put("ply", name.into(), &b)?;
    }
    for (i, head) in [
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
        "GET /ws HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
        "GET /programs/rt_spheres.rdr?x=1 HTTP/1.1\r\n\r\n",
    ]
    .iter()
    .enumerate()
    {
        put("http", format!("head{i}"), head.as_bytes())?;
    }
    // Messages between MPI ranks, made by lucent's own encoder.
    {
        use lucent_cluster::{FrameSpec, Msg};
        use lucent_render::{Camera, Integrator, PathSettings, Region, RegionFilm, RenderSettings, VplSettings};
        let desc = lucent_scene::CameraDesc::from_view(&[0.0, 1.0, 4.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 40.0]);
        let mut film = RegionFilm::new(Region { x0: 8, y0: 4, x1: 12, y1: 7, s0: 0, s1: 2 });
        film.add(9, 5, lucent_accel::glam::Vec3::new(0.5, 0.25, 1.0), 2.0);
        let mut msgs = vec![
            Msg::Hello { digest: 42, threads: 2 },
            Msg::Job { id: 3, region: Region { x0: 0, y0: 0, x1: 64, y1: 64, s0: 0, s1: 16 } },
            Msg::Done { id: 3, rays: 1000, seconds: 0.01, film },
            Msg::Heartbeat,
            Msg::Failed { id: Some(1), message: "cannot pose the scene".into() },
            Msg::Stop,
        ];
        for (k, integrator) in
            [Integrator::default(), Integrator::Path(PathSettings::default()), Integrator::Vpl(VplSettings::default()), Integrator::Normals]
                .into_iter()
                .enumerate()
        {
            let settings = RenderSettings { spp: 4, integrator, ..RenderSettings::new(64, 48) };
            let camera = (k % 2 == 0).then(|| Camera::new(&desc, 64, 48));
            msgs.push(Msg::Frame(FrameSpec { id: k as u32, time: (k == 1).then_some(0.5), settings, camera }));
        }
        for (i, m) in msgs.iter().enumerate() {
            put("cluster", format!("msg{i}"), &m.encode())?;
        }
    }
    for (t, n) in &counts {
        println!("{t:8} {n} seeds");
    }
    Ok(())
}

/// The image cut down to at most 24 pixels a side, as PNG in several colour types (grey,
/// grey + alpha, RGB, RGBA, 16-bit) and as baseline JPEG.
fn small_images(data: &[u8]) -> Vec<Vec<u8>> {
    use image::{DynamicImage, ImageFormat};
    let Ok(img) = image::load_from_memory(data) else { return Vec::new() };
    let img = img.thumbnail(24, 24);
    let variants = [
        DynamicImage::ImageLuma8(img.to_luma8()),
        DynamicImage::ImageLumaA8(img.to_luma_alpha8()),
        DynamicImage::ImageRgb8(img.to_rgb8()),
        DynamicImage::ImageRgba8(img.to_rgba8()),
        DynamicImage::ImageRgb16(img.to_rgb16()),
    ];
    let mut out = Vec::new();
    for (v, format) in variants.iter().map(|v| (v, ImageFormat::Png)).chain([(&variants[2], ImageFormat::Jpeg)]) {
        let mut bytes = std::io::Cursor::new(Vec::new());
        if v.write_to(&mut bytes, format).is_ok() {
            out.push(bytes.into_inner());
        }
    }
    out
}

/// One masked client frame (RFC 6455 §5.2): `opcode` 1 text, 2 binary.
fn ws_frame(opcode: u8, payload: &[u8], fin: bool) -> Vec<u8> {
    let mut f = vec![if fin { 0x80 } else { 0 } | opcode];
    let n = payload.len();
    if n < 126 {
        f.push(0x80 | n as u8);
    } else if n < 65_536 {
        f.push(0x80 | 126);
        f.extend((n as u16).to_be_bytes());
    } else {
        f.push(0x80 | 127);
        f.extend((n as u64).to_be_bytes());
    }
    let mask = [0x37, 0xfa, 0x21, 0x3d];
    f.extend(mask);
    f.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
    f
}
