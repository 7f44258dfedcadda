//! Mitsuba's `.serialized` triangle meshes (the format of Mitsuba 0.6, still read by
//! Mitsuba 3; its documentation's material-preview scene is one). Little-endian:
//!
//! - per mesh, `u16` 0x041C and a `u16` version (3 or 4), then a zlib stream holding a
//!   `u32` of flags (0x1 vertex normals, 0x2 texture coordinates, 0x8 vertex colours,
//!   0x10 face normals, 0x1000 / 0x2000 single / double precision), the mesh's name as a
//!   NUL-terminated string (version 4 only), `u64` vertex and triangle counts, then the
//!   positions, normals, texture coordinates and colours present (3, 3, 2, 3 numbers a
//!   vertex) and three `u32` indices a triangle;
//! - meshes one after another, then the offset of each (`u64` in version 4, `u32` in 3)
//!   and a `u32` count: the file's last bytes.
//!
//! Vertex colours are skipped, as Mitsuba 3 does. Every count is checked against what the
//! stream holds before memory is taken for it, so a damaged file is an error naming the
//! byte offset or the element, never a large allocation.

use flate2::read::ZlibDecoder;
use glam::{Vec2, Vec3};
use std::io::Read;

/// A mesh read from a `.serialized` file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SerializedMesh {
    /// The name version 4 stores (empty in version 3).
    pub name: String,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex normals (empty when the file has none).
    pub normals: Vec<Vec3>,
    /// Texture coordinates (empty when the file has none).
    pub uvs: Vec<Vec2>,
    /// Triangles.
    pub indices: Vec<[u32; 3]>,
    /// The file asks for face normals (flag 0x10).
    pub face_normals: bool,
}

const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x1;
const HAS_UVS: u32 = 0x2;
const HAS_COLORS: u32 = 0x8;
const FACE_NORMALS: u32 = 0x10;
const DOUBLE: u32 = 0x2000;
/// The most bytes one mesh's stream may unpack to (1 GiB): a bound on memory for any
/// input, far above real meshes (a 20-million-triangle mesh is about 0.5 GiB).
const MAX_STREAM_BYTES: u64 = 1 << 30;
/// The longest mesh name read.
const MAX_NAME: usize = 4096;

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

/// The number of meshes in a `.serialized` file (from its end-of-file dictionary).
pub fn serialized_count(bytes: &[u8]) -> Result<u32, String> {
    let (_, count) = header_and_count(bytes)?;
    Ok(count)
}

/// The file's version (3 or 4) and mesh count.
fn header_and_count(bytes: &[u8]) -> Result<(u16, u32), String> {
    let magic = u16_at(bytes, 0).ok_or("the file is shorter than its 4-byte header")?;
    if magic != MAGIC {
        return Err(format!("byte 0: 0x{magic:04X} is not the .serialized format's 0x041C"));
    }
    let version = u16_at(bytes, 2).ok_or("the file is shorter than its 4-byte header")?;
    if !matches!(version, 3 | 4) {
        return Err(format!("byte 2: format version {version}; Mitsuba writes 3 or 4"));
    }
    let count = bytes.len().checked_sub(4).and_then(|at| u32_at(bytes, at)).ok_or("the file has no end-of-file dictionary")?;
    Ok((version, count))
}

/// Reads mesh `shape_index` of a `.serialized` file held in `bytes`.
pub fn parse_serialized(bytes: &[u8], shape_index: u32) -> Result<SerializedMesh, String> {
    let (version, count) = header_and_count(bytes)?;
    let start = if shape_index == 0 {
        0
    } else {
        if shape_index >= count {
            return Err(format!("shape_index {shape_index}: the file holds {count} meshes (0 to {})", count.saturating_sub(1)));
        }
        // The dictionary: `count` offsets, then the count.
        let width = if version == 4 { 8 } else { 4 };
        let table = (bytes.len() - 4).checked_sub(width * count as usize).ok_or("the end-of-file dictionary is longer than the file")?;
        let at = table + width * shape_index as usize;
        let offset = if version == 4 { u64_at(bytes, at) } else { u32_at(bytes, at).map(u64::from) }.unwrap_or(u64::MAX);
        if offset > table as u64 {
            return Err(format!("byte {at}: mesh {shape_index}'s offset {offset} is past the meshes' data"));
        }
        let offset = offset as usize;
        match (u16_at(bytes, offset), u16_at(bytes, offset + 2)) {
            (Some(MAGIC), Some(v)) if v == version => {}
            _ => return Err(format!("byte {offset}: mesh {shape_index} does not start with the format's header")),
        }
        offset
    };
    read_mesh(&bytes[start + 4..], version).map_err(|e| format!("mesh {shape_index} (at byte {start}): {e}"))
}

/// One mesh's zlib stream.
fn read_mesh(stream: &[u8], version: u16) -> Result<SerializedMesh, String> {
    let mut z = ZlibDecoder::new(stream).take(MAX_STREAM_BYTES);
    let mut word = [0u8; 8];
    let mut read = |z: &mut dyn Read, n: usize, what: &str| -> Result<u64, String> {
        z.read_exact(&mut word[..n]).map_err(|e| format!("the stream ends in the {what} ({e})"))?;
        Ok(if n == 4 { u64::from(u32::from_le_bytes([word[0], word[1], word[2], word[3]])) } else { u64::from_le_bytes(word) })
    };
    let flags = read(&mut z, 4, "flags")? as u32;
    let mut name = Vec::new();
    if version == 4 {
        loop {
            let mut c = [0u8];
            z.read_exact(&mut c).map_err(|e| format!("the stream ends in the mesh's name ({e})"))?;
            if c[0] == 0 {
                break;
            }
            if name.len() >= MAX_NAME {
                return Err(format!("the mesh's name is longer than {MAX_NAME} bytes (no NUL)"));
            }
            name.push(c[0]);
        }
    }
    let vertices = read(&mut z, 8, "vertex count")?;
    let triangles = read(&mut z, 8, "triangle count")?;
    let double = flags & DOUBLE != 0;
    let real = if double { 8 } else { 4 };
    let per_vertex = 3
        + if flags & HAS_NORMALS != 0 { 3 } else { 0 }
        + if flags & HAS_UVS != 0 { 2 } else { 0 }
        + if flags & HAS_COLORS != 0 { 3 } else { 0 };
    let need = vertices.checked_mul(per_vertex * real).and_then(|v| triangles.checked_mul(12).and_then(|t| v.checked_add(t)));
    match need {
        Some(n) if n <= MAX_STREAM_BYTES => {}
        _ => return Err(format!("{vertices} vertices and {triangles} triangles: more than lucent reads from one mesh (1 GiB)")),
    }
    if vertices > u64::from(u32::MAX) {
        return Err(format!("{vertices} vertices: more than 32-bit indices reach"));
    }
    let (nv, nt) = (vertices as usize, triangles as usize);
    let positions: Vec<Vec3> = reals::<3>(&mut z, nv, double, "positions")?.into_iter().map(Vec3::from).collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i}'s position is not finite"));
    }
    let normals = if flags & HAS_NORMALS != 0 {
        reals::<3>(&mut z, nv, double, "normals")?.into_iter().map(Vec3::from).collect()
    } else {
        Vec::new()
    };
    let uvs = if flags & HAS_UVS != 0 {
        reals::<2>(&mut z, nv, double, "texture coordinates")?.into_iter().map(Vec2::from).collect()
    } else {
        Vec::new()
    };
    if flags & HAS_COLORS != 0 {
        reals::<3>(&mut z, nv, double, "vertex colours")?;
    }
    let mut indices = Vec::new();
    chunks(&mut z, nt * 12, "triangles", |b| {
        indices.extend(
            b.chunks_exact(12).map(|t| std::array::from_fn(|k| u32::from_le_bytes([t[4 * k], t[4 * k + 1], t[4 * k + 2], t[4 * k + 3]]))),
        );
    })?;
    // The stream ends here (its checksum checked): more data means the counts are wrong.
    match z.read(&mut word) {
        Ok(0) => {}
        Ok(_) => return Err(format!("the stream holds more than {vertices} vertices and {triangles} triangles")),
        Err(e) => return Err(format!("the stream's end is damaged ({e})")),
    }
    if let Some((t, idx)) = indices.iter().enumerate().find(|(_, idx)| idx.iter().any(|&i| i as usize >= nv)) {
        return Err(format!("triangle {t} names vertex {} of {nv}", idx.iter().max().copied().unwrap_or(0)));
    }
    Ok(SerializedMesh {
        name: String::from_utf8_lossy(&name).into_owned(),
        positions,
        normals,
        uvs,
        indices,
        face_normals: flags & FACE_NORMALS != 0,
    })
}

/// `len` bytes of the stream, handed to `f` in pieces of whole records (the buffer grows
/// only as the stream delivers, so a count the stream does not back costs no memory).
fn chunks(z: &mut impl Read, len: usize, what: &str, mut f: impl FnMut(&[u8])) -> Result<(), String> {
    // (A multiple of 8, 12, 16 and 24 bytes: pieces hold whole records of every kind.)
    const PIECE: usize = 48 << 11;
    let mut buf = vec![0u8; PIECE.min(len)];
    let mut left = len;
    while left > 0 {
        let n = PIECE.min(left);
        z.read_exact(&mut buf[..n]).map_err(|e| format!("the stream ends in the {what}, {} of {len} bytes read ({e})", len - left))?;
        f(&buf[..n]);
        left -= n;
    }
    Ok(())
}

/// `count` records of `D` reals (f32 or f64, stored as f32).
fn reals<const D: usize>(z: &mut impl Read, count: usize, double: bool, what: &str) -> Result<Vec<[f32; D]>, String> {
    let size = if double { 8 } else { 4 };
    let mut out = Vec::new();
    let mut flat = Vec::with_capacity(D);
    chunks(z, count * D * size, what, |b| {
        for x in b.chunks_exact(size) {
            let v = if double {
                f64::from_le_bytes([x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]]) as f32
            } else {
                f32::from_le_bytes([x[0], x[1], x[2], x[3]])
            };
            flat.push(v);
            if flat.len() == D {
                out.push(std::array::from_fn(|k| flat[k]));
                flat.clear();
            }
        }
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::{write::ZlibEncoder, Compression};
    use std::io::Write;

    /// A file of meshes written the way Mitsuba lays them out (each a header and a zlib
    /// stream, then the dictionary).
    fn file(version: u16, streams: &[Vec<u8>]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for s in streams {
            offsets.push(out.len() as u64);
            out.extend(MAGIC.to_le_bytes());
            out.extend(version.to_le_bytes());
            let mut e = ZlibEncoder::new(Vec::new(), Compression::default());
            e.write_all(s).expect("zlib");
            out.extend(e.finish().expect("zlib"));
        }
        for o in &offsets {
            if version == 4 {
                out.extend(o.to_le_bytes());
            } else {
                out.extend((*o as u32).to_le_bytes());
            }
        }
        out.extend((streams.len() as u32).to_le_bytes());
        out
    }

    fn triangle_stream(version: u16, flags: u32, shift: f64) -> Vec<u8> {
        let mut s = flags.to_le_bytes().to_vec();
        if version == 4 {
            s.extend(b"tri\0");
        }
        s.extend(3u64.to_le_bytes());
        s.extend(1u64.to_le_bytes());
        let mut put = |v: f64| {
            if flags & DOUBLE != 0 {
                s.extend(v.to_le_bytes());
            } else {
                s.extend((v as f32).to_le_bytes());
            }
        };
        for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            p.iter().for_each(|&c| put(c + shift));
        }
        if flags & HAS_NORMALS != 0 {
            (0..3).for_each(|_| [0.0, 0.0, 1.0].iter().for_each(|&c| put(c)));
        }
        if flags & HAS_UVS != 0 {
            [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]].iter().for_each(|uv| uv.iter().for_each(|&c| put(c)));
        }
        if flags & HAS_COLORS != 0 {
            (0..9).for_each(|_| put(0.5));
        }
        for i in [0u32, 1, 2] {
            s.extend(i.to_le_bytes());
        }
        s
    }

    #[test]
    fn reads_both_versions_precisions_and_indices() {
        for version in [3, 4] {
            for flags in [0x1000, 0x1003, 0x200B, 0x1010] {
                let f = file(version, &[triangle_stream(version, flags, 0.0), triangle_stream(version, flags, 5.0)]);
                assert_eq!(serialized_count(&f), Ok(2));
                let m = parse_serialized(&f, 1).expect("mesh 1");
                assert_eq!(m.positions, vec![Vec3::splat(5.0), Vec3::new(6.0, 5.0, 5.0), Vec3::new(5.0, 6.0, 5.0)]);
                assert_eq!(m.indices, vec![[0, 1, 2]]);
                assert_eq!(m.normals.len(), if flags & HAS_NORMALS != 0 { 3 } else { 0 });
                assert_eq!(m.uvs.len(), if flags & HAS_UVS != 0 { 3 } else { 0 });
                assert_eq!(m.face_normals, flags & FACE_NORMALS != 0);
                assert_eq!(m.name, if version == 4 { "tri" } else { "" });
                assert_eq!(parse_serialized(&f, 0).expect("mesh 0").positions[0], Vec3::ZERO);
            }
        }
    }

    /// A mesh whose arrays span several of the reader's pieces (98,304 bytes), records
    /// straddling their ends.
    #[test]
    fn large_meshes_read_whole() {
        let (nv, nt) = (30_001u64, 20_000u64);
        let mut s = 0x1000u32.to_le_bytes().to_vec();
        s.extend(b"big\0");
        s.extend(nv.to_le_bytes());
        s.extend(nt.to_le_bytes());
        for i in 0..nv * 3 {
            s.extend((i as f32).to_le_bytes());
        }
        for t in 0..nt as u32 {
            for k in 0..3 {
                s.extend(((t + k * 7) % nv as u32).to_le_bytes());
            }
        }
        let m = parse_serialized(&file(4, &[s]), 0).expect("mesh");
        assert_eq!((m.positions.len(), m.indices.len()), (nv as usize, nt as usize));
        assert!(m.positions.iter().enumerate().all(|(i, p)| *p == Vec3::new(3.0 * i as f32, 3.0 * i as f32 + 1.0, 3.0 * i as f32 + 2.0)));
        assert!(m.indices.iter().enumerate().all(|(t, idx)| *idx == [t as u32, t as u32 + 7, t as u32 + 14]));
    }

    #[test]
    fn damaged_files_are_errors_that_say_where() {
        let good = file(4, &[triangle_stream(4, 0x1003, 0.0)]);
        let e = parse_serialized(&good, 1).expect_err("no mesh 1");
        assert!(e.contains("holds 1 meshes"), "{e}");
        let mut bad = good.clone();
        bad[0] = 0;
        assert!(parse_serialized(&bad, 0).expect_err("bad magic").contains("byte 0"));
        // Every cut into the mesh's data is an error, never a panic (past it, only the
        // dictionary is cut, which mesh 0 does not need).
        for cut in 0..good.len() - 12 {
            let mut f = good[..cut].to_vec();
            f.extend(1u32.to_le_bytes());
            assert!(parse_serialized(&f, 0).is_err(), "cut at {cut}");
        }
        // A count the stream does not back.
        let mut s = triangle_stream(4, 0x1000, 0.0);
        s[8..16].copy_from_slice(&(1u64 << 40).to_le_bytes());
        assert!(parse_serialized(&file(4, &[s]), 0).expect_err("damaged").contains("more than lucent reads"));
        let mut s = triangle_stream(4, 0x1000, 0.0);
        s[8..16].copy_from_slice(&(1u64 << 20).to_le_bytes());
        assert!(parse_serialized(&file(4, &[s]), 0).expect_err("damaged").contains("the stream ends in the positions"));
        // An index past the vertices.
        let mut s = triangle_stream(4, 0x1000, 0.0);
        let n = s.len();
        s[n - 4..].copy_from_slice(&7u32.to_le_bytes());
        assert!(parse_serialized(&file(4, &[s]), 0).expect_err("damaged").contains("triangle 0 names vertex 7 of 3"));
    }
}
