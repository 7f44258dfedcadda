//! Bad input gets a clear error that names the file and the place, never a panic.

use lucent_scene::{load, ImportError};
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, body: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, body).expect("write");
    p
}

fn err_of(p: &Path) -> String {
    match load(p) {
        Ok(_) => panic!("{} loaded but should not", p.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn truncated_obj() {
    let d = tempfile::tempdir().expect("tmp");
    let p = write(d.path(), "cut.obj", b"v 0 0 0\nv 1 0 0\nv 0 1\n");
    let e = err_of(&p);
    assert!(e.contains("cut.obj:3:") && e.contains("needs 3 numbers, found 2"), "{e}");
    let p = write(d.path(), "cut2.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2");
    let e = err_of(&p);
    assert!(e.contains("cut2.obj:4:") && e.contains("at least 3 corners"), "{e}");
    let p = write(d.path(), "bad.obj", b"v 0 0 zero\n");
    assert!(err_of(&p).contains("bad.obj:1: 'v' record: 'zero' is not a number"));
}

#[test]
fn obj_index_out_of_range() {
    let d = tempfile::tempdir().expect("tmp");
    let p = write(d.path(), "oor.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n");
    let e = err_of(&p);
    assert!(e.contains("oor.obj:5:") && e.contains("vertex index 4 out of range (there are 3 so far)"), "{e}");
    let p = write(d.path(), "neg.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
    assert!(err_of(&p).contains("vertex index -4 out of range"));
    let p = write(d.path(), "zero.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    assert!(err_of(&p).contains("index 0"));
}

#[test]
fn obj_good_with_relative_indices_and_missing_mtl() {
    let d = tempfile::tempdir().expect("tmp");
    let p = write(d.path(), "ok.obj", b"mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf -4/1 -3/1 -1/1 -2/1\n");
    let s = load(&p).expect("loads with a warning");
    assert_eq!(s.meshes[0].indices, vec![[0, 1, 3], [0, 3, 2]]);
}

#[test]
fn missing_texture_is_a_warning() {
    let d = tempfile::tempdir().expect("tmp");
    write(d.path(), "m.mtl", b"newmtl a\nKd 0.5 0.25 1\nmap_Kd -bm 1 missing.png\n");
    let p = write(d.path(), "t.obj", b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n");
    let s = load(&p).expect("loads");
    let m = &s.materials[s.meshes[0].material[0] as usize];
    assert_eq!(m.diffuse_tex, None);
    assert_eq!(m.diffuse.to_array(), [0.5, 0.25, 1.0]);
}

#[test]
fn bad_ply_header() {
    let d = tempfile::tempdir().expect("tmp");
    let p = write(d.path(), "bad.ply", b"ply\nformat ascii 1.0\nelement vertex three\nend_header\n");
    let e = err_of(&p);
    assert!(e.starts_with(&format!("{}:", p.display())), "{e}");
    let p = write(d.path(), "nomagic.ply", b"plx\nformat ascii 1.0\nend_header\n");
    err_of(&p);
    let p = write(d.path(), "oor.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    let e = err_of(&p);
    assert!(e.contains("face 0") && e.contains("vertex index 7 out of range"), "{e}");
    // Truncated binary payload.
    let mut b =
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
            .to_vec();
    b.extend_from_slice(&[0u8; 20]);
    let p = write(d.path(), "short.ply", &b);
    err_of(&p);
}

#[test]
fn gltf_with_missing_buffer() {
    let d = tempfile::tempdir().expect("tmp");
    let json = br#"{"asset":{"version":"2.0"},"buffers":[{"uri":"gone.bin","byteLength":36}],
        "bufferViews":[{"buffer":0,"byteLength":36}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0}"#;
    let p = write(d.path(), "m.gltf", json);
    let e = err_of(&p);
    assert!(e.contains("m.gltf") && e.contains("/buffers/0") && e.contains("gone.bin"), "{e}");
    // The same file with the buffer present but too short.
    write(d.path(), "gone.bin", &[0u8; 12]);
    let e = err_of(&p);
    assert!(e.contains("/buffers/0") && e.contains("byteLength"), "{e}");
    // And complete: it loads one triangle.
    let mut bin = Vec::new();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    write(d.path(), "gone.bin", &bin);
    let s = load(&p).expect("loads");
    assert_eq!(s.stats().triangles, 1);
    // Broken JSON.
    let p = write(d.path(), "broken.gltf", b"{\"asset\":");
    assert!(matches!(load(&p), Err(ImportError::Invalid { .. })));
}

#[test]
fn unknown_format_and_missing_file() {
    assert!(matches!(load(Path::new("scene.xyz")), Err(ImportError::UnknownFormat(_))));
    let e = err_of(Path::new("/nonexistent/dir/x.obj"));
    assert!(e.contains("/nonexistent/dir/x.obj"), "{e}");
}

#[test]
fn random_bytes_never_panic() {
    // A cheap in-test fuzz: seeded garbage and mutated real headers through every importer.
    let d = tempfile::tempdir().expect("tmp");
    let mut x = 0x1234_5678_9abc_def0u64;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let seeds: [&[u8]; 3] = [
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
        br#"{"asset":{"version":"2.0"},"meshes":[]}"#,
    ];
    for (k, ext) in ["obj", "ply", "gltf", "glb"].iter().enumerate() {
        for i in 0..200 {
            let mut b = seeds[k.min(2)].to_vec();
            for _ in 0..(next() % 8) {
                let n = b.len().max(1);
                let pos = (next() as usize) % n;
                match next() % 3 {
                    0 => b.insert(pos, next() as u8),
                    1 if !b.is_empty() => {
                        b.remove(pos.min(b.len() - 1));
                    }
                    _ => b.truncate(pos),
                }
            }
            let p = write(d.path(), &format!("f{i}.{ext}"), &b);
            let _ = load(&p);
        }
    }
}

/// Peak resident memory of this process so far (kB), from /proc (Linux); None elsewhere.
fn peak_rss_kib() -> Option<u64> {
    std::fs::read_to_string("/proc/self/status")
        .ok()?
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:")?.trim().strip_suffix("kB")?.trim().parse().ok())
}

/// Sizes claimed by a header are checked against the data before anything that size is
/// allocated: a PLY header of 10^9 vertices, a glTF accessor larger than its buffer view, a
/// texture of 10^5 × 10^5 pixels each get a clear error (the texture a warning and the plain
/// colour), and the process stays small.
#[test]
fn claimed_sizes_are_checked_before_allocating() {
    let d = tempfile::tempdir().expect("tmp");
    let before = peak_rss_kib();
    for (name, fmt) in [("big_binary.ply", "binary_little_endian"), ("big_ascii.ply", "ascii")] {
        let head = format!("ply\nformat {fmt} 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n");
        let e = err_of(&write(d.path(), name, head.as_bytes()));
        assert!(e.contains(name) && e.contains("1000000000"), "{e}");
    }
    let gltf = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":12,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAA"}],
        "bufferViews":[{"buffer":0,"byteLength":12}],"accessors":[{"bufferView":0,"componentType":5126,"count":1000000000,"type":"VEC3"}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}]}"#;
    let e = err_of(&write(d.path(), "big_accessor.gltf", gltf.as_bytes()));
    assert!(e.contains("/accessors/0") && e.contains("do not fit buffer view 0"), "{e}");
    let no_view = gltf.replace(r#""bufferView":0,"#, "");
    let e = err_of(&write(d.path(), "big_zeros.gltf", no_view.as_bytes()));
    assert!(e.contains("/accessors/0") && e.contains("exceed the limit"), "{e}");
    // A PNG whose header claims 100,000 × 100,000 RGBA pixels.
    let chunk = |t: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend(t);
        c.extend(data);
        c.extend(crc32(&[t, data].concat()).to_be_bytes());
        c
    };
    let mut ihdr = 100_000u32.to_be_bytes().to_vec();
    ihdr.extend(100_000u32.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(b"IEND", b""));
    let e = lucent_scene::decode_image(&png).expect_err("a 10^5 x 10^5 texture is refused");
    assert!(e.to_string().to_lowercase().contains("limit"), "{e}");
    // Within the side limit, but more texels than its bytes could hold (a truncated file:
    // the decoder would fill 1 GB of missing rows): refused too. A small real image
    // (a thumbnail of a shared texture) still decodes.
    let mut ihdr = 16_000u32.to_be_bytes().to_vec();
    ihdr.extend(16_000u32.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    let mut truncated = b"\x89PNG\r\n\x1a\n".to_vec();
    truncated.extend(chunk(b"IHDR", &ihdr));
    truncated.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]));
    let e = lucent_scene::decode_image(&truncated).expect_err("16,000² pixels from 60 bytes are refused");
    assert!(e.to_string().to_lowercase().contains("limit"), "{e}");
    let mut small = std::io::Cursor::new(Vec::new());
    image::RgbaImage::from_pixel(300, 200, image::Rgba([9, 8, 7, 255])).write_to(&mut small, image::ImageFormat::Png).expect("encode");
    let img = lucent_scene::decode_image(small.get_ref()).expect("a flat 300 x 200 PNG decodes");
    assert_eq!((img.width(), img.height()), (300, 200));
    write(d.path(), "huge.png", &png);
    write(d.path(), "huge.mtl", b"newmtl m\nmap_Kd huge.png\n");
    let p = write(d.path(), "huge.obj", b"mtllib huge.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n");
    let s = load(&p).expect("loads without its texture");
    assert!(s.textures.is_empty() && s.materials.iter().all(|m| m.diffuse_tex.is_none()));
    if let (Some(a), Some(b)) = (before, peak_rss_kib()) {
        assert!(b.saturating_sub(a) < 256 * 1024, "peak memory grew by {} MB", (b - a) / 1024);
    }
}

/// CRC-32 (ISO-HDLC, as PNG uses), bit by bit.
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}
