//! `lucent bench rays DIR`: traces the rays the Embree harness dumped (see
//! `shared/bench/README.md` for the file formats) and prints one JSON line per
//! (kind, kernel, thread count), in the harness's schema.

use anyhow::{bail, Context, Result};
use lucent_accel::glam::Vec3;
use lucent_accel::{Kernel, MeshBvh, MeshOptions, Ray, TriangleTest, Width};
use saarcor::kd::{Exact, KdMesh, KdOptions};
use std::path::Path;
use std::time::Instant;

/// A triangle mesh as dumped: positions and index triples.
pub struct DumpMesh {
    pub positions: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
}

/// Eight rays in SoA form, as dumped.
#[derive(Clone, Copy)]
pub struct Block {
    pub o: [[f32; 8]; 3],
    pub d: [[f32; 8]; 3],
    pub tfar: [f32; 8],
    pub valid: [i32; 8],
    pub pixel: [i32; 8],
}

/// A batch of ray blocks.
pub struct Batch {
    pub width: u32,
    pub height: u32,
    pub active: u32,
    pub blocks: Vec<Block>,
}

fn u32_at(b: &[u8], off: usize, what: &str) -> Result<u32> {
    let s = b.get(off..off + 4).with_context(|| format!("{what}: file ends at byte {} (wanted 4 bytes at {off})", b.len()))?;
    Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// Reads `mesh.bin`.
pub fn read_mesh(path: &Path) -> Result<DumpMesh> {
    let b = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let name = path.display().to_string();
    if b.get(..8) != Some(b"RTBMESH1") {
        bail!("{name}: not a mesh dump (no RTBMESH1 magic)");
    }
    let nv = u32_at(&b, 8, &name)? as usize;
    let nt = u32_at(&b, 12, &name)? as usize;
    let need = 16 + nv * 12 + nt * 12;
    if b.len() < need {
        bail!("{name}: {} bytes, but {nv} vertices and {nt} triangles need {need}", b.len());
    }
    let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let positions = (0..nv).map(|i| Vec3::new(f(16 + i * 12), f(20 + i * 12), f(24 + i * 12))).collect();
    let base = 16 + nv * 12;
    let mut indices = Vec::with_capacity(nt);
    for t in 0..nt {
        let g = |k: usize| u32_at(&b, base + t * 12 + k * 4, &name);
        indices.push([g(0)?, g(1)?, g(2)?]);
    }
    Ok(DumpMesh { positions, indices })
}

/// Reads a `rays_KIND.bin`.
pub fn read_rays(path: &Path) -> Result<Batch> {
    let b = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let name = path.display().to_string();
    if b.get(..8) != Some(b"RTBRAYS1") {
        bail!("{name}: not a ray dump (no RTBRAYS1 magic)");
    }
    let width = u32_at(&b, 8, &name)?;
    let height = u32_at(&b, 12, &name)?;
    let nb = u32_at(&b, 16, &name)? as usize;
    let active = u32_at(&b, 20, &name)?;
    if b.len() < 24 + nb * 288 {
        bail!("{name}: {} bytes, but {nb} blocks need {}", b.len(), 24 + nb * 288);
    }
    let mut blocks = Vec::with_capacity(nb);
    for k in 0..nb {
        let base = 24 + k * 288;
        let row = |r: usize| -> [u32; 8] {
            std::array::from_fn(|l| u32::from_le_bytes(b[base + r * 32 + l * 4..base + r * 32 + l * 4 + 4].try_into().unwrap_or([0; 4])))
        };
        let fr = |r: usize| row(r).map(f32::from_bits);
        let ir = |r: usize| row(r).map(|x| x as i32);
        blocks.push(Block { o: [fr(0), fr(1), fr(2)], d: [fr(3), fr(4), fr(5)], tfar: fr(6), valid: ir(7), pixel: ir(8) });
    }
    Ok(Batch { width, height, active, blocks })
}

impl Block {
    fn ray(&self, l: usize) -> Ray {
        Ray {
            org: Vec3::new(self.o[0][l], self.o[1][l], self.o[2][l]),
            dir: Vec3::new(self.d[0][l], self.d[1][l], self.d[2][l]),
            tmin: 0.0,
            tmax: self.tfar[l],
        }
    }
}

/// Options of `bench rays`.
pub struct RaysOptions {
    pub name: String,
    pub threads: Vec<usize>,
    pub frames: usize,
    pub warmup: usize,
    pub kinds: Vec<String>,
    pub width: Width,
    pub test: TriangleTest,
    pub kernel: Kernel,
    /// Build quality.
    pub quality: lucent_accel::Quality,
    /// Kernels to time, one JSON line each.
    pub apis: Vec<Api>,
    /// Pin each worker to its own CPU.
    pub pin: bool,
    /// Write the per-pixel primary hit ids here (i32 little-endian, like `embree_bench --dump-ids`).
    pub dump_ids: Option<std::path::PathBuf>,
    /// Trace SaarCOR's kd-tree (`saarcor::kd`) instead of the BVH.
    pub kd: bool,
}

/// The index `bench rays` traces.
enum Index {
    Bvh(MeshBvh),
    /// SaarCOR's kd-tree: single rays, and packets of 4 (each 8-ray block is two packets,
    /// its rows of 4 pixels).
    Kd(KdMesh),
}

impl Index {
    /// One ray: the hit's triangle (-1 for none), or 1/0 for occluded/free.
    #[inline]
    fn single(&self, r: &Ray, shadow: bool) -> i32 {
        match (self, shadow) {
            (Self::Bvh(b), true) => i32::from(b.occluded(r)),
            (Self::Bvh(b), false) => b.intersect(r).map_or(-1, |h| h.prim as i32),
            (Self::Kd(k), true) => i32::from(k.occluded_with::<Exact, ()>(r, &mut ())),
            (Self::Kd(k), false) => k.intersect(r).map_or(-1, |h| h.prim as i32),
        }
    }

    /// The blocks' rays as packets, answers into `hits` or `occ` (8 per block).
    #[inline]
    fn packets(&self, blocks: &[lucent_accel::RayBlock], shadow: bool, hits: &mut [Option<lucent_accel::Hit>], occ: &mut [bool]) {
        match self {
            Self::Bvh(b) if shadow => b.occluded_blocks(blocks, occ),
            Self::Bvh(b) => b.intersect_blocks(blocks, hits),
            Self::Kd(k) => {
                for (bi, b) in blocks.iter().enumerate() {
                    for half in 0..2 {
                        let rays: [Ray; 4] = std::array::from_fn(|i| {
                            let l = 4 * half + i;
                            Ray {
                                org: Vec3::new(b.org[0][l], b.org[1][l], b.org[2][l]),
                                dir: Vec3::new(b.dir[0][l], b.dir[1][l], b.dir[2][l]),
                                tmin: b.tmin[l],
                                tmax: b.tmax[l],
                            }
                        });
                        let at = bi * 8 + 4 * half;
                        if shadow {
                            occ[at..at + 4].copy_from_slice(&k.occluded4_with::<Exact, ()>(&rays, &mut ()));
                        } else {
                            hits[at..at + 4].copy_from_slice(&k.intersect4_with::<Exact, ()>(&rays, &mut ()));
                        }
                    }
                }
            }
        }
    }
}

const CHUNK_BLOCKS: usize = 32;

/// How rays are handed to the kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Api {
    /// One ray at a time.
    Single,
    /// 8-ray packets (one 4×2-pixel block).
    Packet8,
    /// 64-ray packets (one 8×8-pixel tile).
    Packet64,
}

impl Api {
    fn rays(self) -> usize {
        match self {
            Api::Single => 1,
            Api::Packet8 => 8,
            Api::Packet64 => 64,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Api::Single => "single",
            Api::Packet8 => "packet8",
            Api::Packet64 => "packet64",
        }
    }
}

/// Runs the benchmark and prints JSON lines.
pub fn rays(dir: &Path, o: &RaysOptions) -> Result<()> {
    let mesh = read_mesh(&dir.join("mesh.bin"))?;
    let tris = mesh.indices.len();
    let opts = MeshOptions { width: o.width, test: o.test, quality: o.quality, ..MeshOptions::default() };
    let bvh_label = if o.kd {
        "kd".to_string()
    } else {
        format!(
            "{}{}",
            if o.width == Width::W8 { "bvh8" } else { "bvh4" },
            if o.test == TriangleTest::Watertight { "-watertight" } else { "" }
        )
    };
    let build = |p: &rayon::ThreadPool| -> Result<Index> {
        Ok(if o.kd {
            Index::Kd(p.install(|| KdMesh::build(&mesh.positions, &mesh.indices, KdOptions::default()))?)
        } else {
            Index::Bvh(p.install(|| MeshBvh::build(&mesh.positions, &mesh.indices, opts))?)
        })
    };
    let mut index = None;
    for &threads in &o.threads {
        let p = crate::threads::pool(threads, o.pin)?;
        // One untimed warm-up build first, as the Embree harness does (on a fresh pool the
        // first builds of a small mesh read half again as slow: museum, 2 threads, median of
        // 9 builds without it 3.0 ms, with it 2.1 ms).
        drop(build(&p)?);
        let mut times = Vec::new();
        for _ in 0..o.frames.max(1) {
            let t0 = Instant::now();
            let b = build(&p)?;
            times.push(t0.elapsed().as_secs_f64());
            index = Some(b);
        }
        let (nodes, sah, wide_sah, bytes) = match &index {
            Some(Index::Bvh(b)) => {
                let st = b.stats();
                (st.nodes, st.sah, st.wide_sah, st.bytes)
            }
            Some(Index::Kd(k)) => {
                let st = k.tree().stats();
                (st.nodes, 0.0, 0.0, k.bytes())
            }
            None => (0, 0.0, 0.0, 0),
        };
        println!(
            "{{\"kind\":\"build\",\"tracer\":\"lucent\",\"scene\":\"{}\",\"tris\":{tris},\"quality\":\"{}\",\"bvh\":\"{bvh_label}\",\"threads\":{threads},\"median_ms\":{:.2},\"nodes\":{nodes},\"sah\":{sah:.2},\"sah_embree_convention\":{wide_sah:.2},\"bytes\":{bytes},\"bytes_per_tri\":{:.1}}}",
            o.name,
            match o.quality {
                _ if o.kd => "kd-sah",
                lucent_accel::Quality::Sah => "sah",
                lucent_accel::Quality::Spatial => "spatial",
                lucent_accel::Quality::High => "high",
            },
            1e3 * crate::stats::median(&mut times),
            bytes as f64 / tris.max(1) as f64
        );
    }
    let Some(mut index) = index else { bail!("no thread count given") };
    let kname = match &mut index {
        Index::Bvh(bvh) => {
            bvh.set_kernel(o.kernel);
            match bvh.kernel() {
                Kernel::Scalar => "scalar",
                k => k.name(),
            }
        }
        Index::Kd(_) => "kd",
    };
    let ref_ids = std::fs::read(dir.join("ref_ids.bin"))
        .ok()
        .map(|b| b.chunks_exact(4).map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect::<Vec<i32>>());
    for kind in &o.kinds {
        let path = dir.join(format!("rays_{kind}.bin"));
        let batch = read_rays(&path)?;
        let shadow = kind == "shadow";
        // The blocks as the kernels take them (outside the timing, as the harness's own).
        let soa: Vec<lucent_accel::RayBlock> = batch
            .blocks
            .iter()
            .map(|b| lucent_accel::RayBlock {
                org: b.o,
                dir: b.d,
                tmin: [0.0; 8],
                tmax: std::array::from_fn(|l| if b.valid[l] != 0 { b.tfar[l] } else { f32::NEG_INFINITY }),
            })
            .collect();
        let mut apis: Vec<(&str, usize)> = o.apis.iter().map(|&a| (a.name(), a.rays())).collect();
        if o.kd {
            // The kd-tree's packets are SaarCOR's 4 rays, handed over in blocks of 8.
            apis = apis.into_iter().map(|(n, per)| if per == 1 { (n, 1) } else { ("packet4", 8) }).collect();
            apis.dedup();
        }
        for (api, per) in apis {
            let api = format!("{api}-{kname}");
            for &threads in &o.threads {
                let p = crate::threads::pool(threads, o.pin)?;
                // Like the Embree harness: every worker pulls chunks of 32 blocks (4 tiles, 256
                // rays) from an atomic counter, so both tracers pay the same scheduling cost.
                let out_cells: Vec<std::sync::atomic::AtomicI32> =
                    (0..batch.blocks.len() * 8).map(|_| std::sync::atomic::AtomicI32::new(-1)).collect();
                let pass = || {
                    let next = std::sync::atomic::AtomicUsize::new(0);
                    let nchunks = batch.blocks.len().div_ceil(CHUNK_BLOCKS);
                    rayon::broadcast(|_| {
                        let mut claimed = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        loop {
                            let c = claimed;
                            if c >= nchunks {
                                break;
                            }
                            // The next chunk is claimed before this one is traced, so its first
                            // packet's rays can be asked for from memory while this one runs.
                            claimed = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let b0 = c * CHUNK_BLOCKS;
                            let b1 = (b0 + CHUNK_BLOCKS).min(batch.blocks.len());
                            if per == 1 {
                                for bi in b0..b1 {
                                    let b = &batch.blocks[bi];
                                    for l in 0..8 {
                                        if b.valid[l] == 0 {
                                            continue;
                                        }
                                        let v = index.single(&b.ray(l), shadow);
                                        out_cells[bi * 8 + l].store(v, std::sync::atomic::Ordering::Relaxed);
                                    }
                                }
                                continue;
                            }
                            // Packets of `per` rays: consecutive blocks (a tile is 8 blocks), handed
                            // over in the SoA layout they were dumped in; invalid lanes have an empty
                            // range and are skipped by the kernel.
                            let mut hits = [None; lucent_accel::MAX_PACKET];
                            let mut occ = [false; lucent_accel::MAX_PACKET];
                            let bpp = per / 8;
                            for pb in (b0..b1).step_by(bpp) {
                                let pe = (pb + bpp).min(b1);
                                let n = (pe - pb) * 8;
                                // A stream of packets: the next packet's blocks are asked for
                                // before this one is traced (else 64-ray shadow packets that end at
                                // their first leaf spend a quarter of their time waiting on them).
                                let ahead = if pe < b1 { pe } else { claimed.saturating_mul(CHUNK_BLOCKS) };
                                lucent_accel::prefetch_blocks(soa.get(ahead..(ahead + bpp).min(soa.len())).unwrap_or(&[]));
                                index.packets(&soa[pb..pe], shadow, &mut hits[..n], &mut occ[..n]);
                                for k in 0..n {
                                    let v = if shadow { occ[k] as i32 } else { hits[k].map_or(-1, |h| h.prim as i32) };
                                    out_cells[pb * 8 + k].store(v, std::sync::atomic::Ordering::Relaxed);
                                }
                            }
                        }
                    });
                };
                let mut times: Vec<f64> = p.install(|| {
                    for _ in 0..o.warmup {
                        pass();
                    }
                    (0..o.frames.max(1))
                        .map(|_| {
                            let t0 = Instant::now();
                            pass();
                            t0.elapsed().as_secs_f64()
                        })
                        .collect()
                });
                let med = crate::stats::median(&mut times);
                let out: Vec<i32> = out_cells.iter().map(|c| c.load(std::sync::atomic::Ordering::Relaxed)).collect();
                let npix = (batch.width * batch.height) as usize;
                let mut px = vec![-1i32; npix];
                for (bi, b) in batch.blocks.iter().enumerate() {
                    for l in 0..8 {
                        if let Some(slot) = usize::try_from(b.pixel[l]).ok().filter(|&p| p < npix) {
                            px[slot] = if b.valid[l] != 0 { out[bi * 8 + l] } else { -1 };
                        }
                    }
                }
                let mut line = format!(
                "{{\"kind\":\"{kind}\",\"tracer\":\"lucent\",\"scene\":\"{}\",\"tris\":{tris},\"bvh\":\"{bvh_label}\",\"api\":\"{api}\",\"threads\":{threads},\"width\":{},\"height\":{},\"rays\":{},\"median_ms\":{:.3},\"mrays_s\":{:.2}",
                o.name,
                batch.width,
                batch.height,
                batch.active,
                1e3 * med,
                batch.active as f64 / med * 1e-6
            );
                if shadow {
                    line += &format!(",\"occluded\":{}", px.iter().filter(|&&v| v == 1).count());
                } else {
                    line += &format!(",\"hits\":{}", px.iter().filter(|&&v| v >= 0).count());
                    if kind == "primary" {
                        if let Some(path) = &o.dump_ids {
                            let bytes: Vec<u8> = px.iter().flat_map(|v| v.to_le_bytes()).collect();
                            std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
                        }
                        if let Some(r) = &ref_ids {
                            let diff = px.iter().zip(r.iter()).filter(|(a, b)| a != b).count();
                            line += &format!(",\"diff_px_vs_ref\":{diff}");
                        }
                    }
                }
                println!("{line}}}");
            }
        }
    }
    Ok(())
}
