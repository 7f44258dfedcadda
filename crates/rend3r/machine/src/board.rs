//! `--compat board`: what REND3R's FPGA board would have shown (SPEC.md §4–§7 and the bugs
//! of §10 that change pictures). Kept apart from lucent's main path, which implements the
//! paper. Modelled:
//! - program memory of 32 words (ray-tracing build) or 128 (rasterization build, `main`):
//!   later words are dropped and the PC wraps; 2 shapes and 2 lights (ray tracing), 8
//!   triangles (raster), indices wrapping around;
//! - ray tracer: the camera is never rotated; pixel directions stepped in binary16
//!   (SPEC §5), +y towards the bottom of the screen; shapes transformed and intersected in
//!   binary16 in the hardware's operation order with subnormals flushed to zero (§6.2–6.4);
//!   one shadow ray toward light 0's forward, excluding the hit shape (§6.5); the
//!   fixed-point Lambert shading of light 0 as a white directional light (§6.6); background
//!   = the board switches (a setting, default 0);
//! - bugs B1 (stale closest-hit comparison), B2 (cone root choice: t1 taken without
//!   ordering), B3 (|cosθ|·2^14 overflows a 13-bit signed fixed value: lucent assumes the
//!   core saturates to 4095, which the repository does not document), B6 (zero records);
//! - rasterizer: triangles in index order, no lighting, no depth test, vertices rounded to
//!   integers and read as 12-bit unsigned values, the edge-function test on every pixel,
//!   column 0 never written, the frame buffer never cleared between frames;
//! - display: the VGA shows bits 11..0 of each 16-bit pixel as RGB444 (both builds).
//!
//! Not modelled: B7 (the rasterizer's likely off-by-one slot and 3-pixel shift), which the
//! spec marks unverified.

use crate::processor::Processor;
use half::f16;
use lucent_render::Film;
use rend3r_isa::{CameraTable, DecodeError};

/// Which board build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Build {
    /// The final ray-tracing build (raytracing branch).
    Raytracing,
    /// The final rasterization build (main branch).
    Raster,
}

impl Build {
    /// Program memory words.
    #[must_use]
    pub fn rom_words(self) -> usize {
        match self {
            Build::Raytracing => 32,
            Build::Raster => 128,
        }
    }
}

/// A processor with the board's program memory and record capacities: words beyond the
/// ROM are dropped, the rest of the ROM is zero, the PC wraps around it, `nr` leaves the
/// scene alone, and record indices wrap (2 shapes and 2 lights for the ray-tracing build,
/// 8 triangles and 8 lights for the rasterization build).
pub fn board_processor(words: &[u32], build: Build) -> Result<Processor, DecodeError> {
    let n = build.rom_words();
    let mut rom: Vec<u32> = words.iter().copied().take(n).collect();
    rom.resize(n, 0);
    let (sets, lights) = match build {
        Build::Raytracing => (2, 2),
        Build::Raster => (8, 8),
    };
    Processor::new_board(rom, if build == Build::Raster { CameraTable::Old } else { CameraTable::Final }, sets, lights)
}

/// Binary16 arithmetic as the Xilinx cores do it: subnormal inputs read as zero, results
/// rounded to nearest even and flushed to zero when subnormal. f32 arithmetic rounded once
/// to f16 is exact for +, −, ×, ÷, √ (f32 has at least 2p + 2 bits: Figueroa, 1995).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct H(pub f16);

impl H {
    fn ftz(x: f16) -> f16 {
        let b = x.to_bits();
        if b & 0x7C00 == 0 && b & 0x03FF != 0 {
            if x.is_sign_negative() {
                f16::NEG_ZERO
            } else {
                f16::ZERO
            }
        } else {
            x
        }
    }
    /// From raw bits.
    #[must_use]
    pub fn bits(b: u16) -> Self {
        H(Self::ftz(f16::from_bits(b)))
    }
    fn of(x: f32) -> Self {
        H(Self::ftz(f16::from_f32(x)))
    }
    /// As f32.
    #[must_use]
    pub fn f(self) -> f32 {
        self.0.to_f32()
    }
    fn add(self, o: H) -> H {
        H::of(self.f() + o.f())
    }
    fn sub(self, o: H) -> H {
        H::of(self.f() - o.f())
    }
    fn mul(self, o: H) -> H {
        H::of(self.f() * o.f())
    }
    fn div(self, o: H) -> H {
        H::of(self.f() / o.f())
    }
    fn sqrt(self) -> H {
        H::of(self.f().sqrt())
    }
    fn neg(self) -> H {
        H(-self.0)
    }
    fn sign(self) -> bool {
        self.0.is_sign_negative()
    }
}

type V = [H; 3];
type Q = [H; 4];

/// Hamilton product in the hardware's term order (SPEC §6.2).
fn ham(a: Q, b: Q) -> Q {
    let w = a[0].mul(b[0]).sub(a[1].mul(b[1])).sub(a[2].mul(b[2]).add(a[3].mul(b[3])));
    let x = a[0].mul(b[1]).add(a[1].mul(b[0])).add(a[2].mul(b[3]).sub(a[3].mul(b[2])));
    let y = a[0].mul(b[2]).sub(a[1].mul(b[3])).add(a[2].mul(b[0]).add(a[3].mul(b[1])));
    let z = a[0].mul(b[3]).add(a[1].mul(b[2])).sub(a[2].mul(b[1]).sub(a[3].mul(b[0])));
    [w, x, y, z]
}

fn dot(a: V, b: V) -> H {
    a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
}

struct Shape {
    typ: u16,
    t: V,
    q: Q,
    s: V,
    col: u16,
}

fn shape(r: &crate::Record) -> Shape {
    let h = |p: u8| H::bits(r.u(p));
    Shape { typ: r.u(13) & 15, t: [h(1), h(2), h(3)], q: [h(4), h(5), h(6), h(7)], s: [h(8), h(9), h(10)], col: r.u(11) }
}

/// Ray into shape space: p = R⁻¹(O − T)·S, d = R⁻¹(D)·S (SPEC §6.2).
fn to_local(sh: &Shape, o: V, d: V) -> (V, V) {
    let qc = [sh.q[0], sh.q[1].neg(), sh.q[2].neg(), sh.q[3].neg()];
    let rot = |v: V| {
        let m = ham([H(f16::ZERO), v[0], v[1], v[2]], sh.q);
        let r = ham(qc, m);
        [r[1], r[2], r[3]]
    };
    let p = [o[0].add(sh.t[0].neg()), o[1].add(sh.t[1].neg()), o[2].add(sh.t[2].neg())];
    let p = rot(p);
    let d = rot(d);
    ([p[0].mul(sh.s[0]), p[1].mul(sh.s[1]), p[2].mul(sh.s[2])], [d[0].mul(sh.s[0]), d[1].mul(sh.s[1]), d[2].mul(sh.s[2])])
}

/// The quadric root per SPEC §6.3 (with bug B2: t1 is taken first whatever the sign of 2a).
fn root(typ: u16, p: V, d: V) -> Option<H> {
    let two = |x: H| x.add(x);
    let (a, b, c) = match typ {
        2 => {
            let a = d[0].mul(d[0]).add(d[1].mul(d[1]));
            let b = two(d[0].mul(p[0]).add(d[1].mul(p[1])));
            let c = p[0].mul(p[0]).add(p[1].mul(p[1])).add(H::of(-1.0));
            (a, b, c)
        }
        3 => {
            let a = d[0].mul(d[0]).add(d[1].mul(d[1])).sub(d[2].mul(d[2]));
            let b = two(d[0].mul(p[0]).add(d[1].mul(p[1])).sub(d[2].mul(p[2])));
            let c = p[0].mul(p[0]).add(p[1].mul(p[1])).sub(p[2].mul(p[2]));
            (a, b, c)
        }
        // Sphere, and types 4..15, which intersect like a sphere (SPEC §6.4).
        _ => {
            let a = dot(d, d);
            let b = two(dot(d, p));
            let c = p[0].mul(p[0]).add(p[1].mul(p[1])).add(p[2].mul(p[2]).sub(H::of(1.0)));
            (a, b, c)
        }
    };
    let a2 = a.add(a);
    let disc = b.mul(b).sub(a2.mul(c.add(c)));
    if disc.sign() {
        return None;
    }
    let sq = disc.sqrt();
    let n1 = b.neg().sub(sq);
    let n2 = b.neg().add(sq);
    // Sign of each t = sign(numerator) XOR sign(2a), decided before the division.
    if n1.sign() == a2.sign() || n1.0 == f16::ZERO {
        return Some(n1.div(a2));
    }
    if n2.sign() == a2.sign() || n2.0 == f16::ZERO {
        return Some(n2.div(a2));
    }
    None
}

/// The board's ray tracer: one 512×384 frame buffer of RGB565 words (SPEC §5–§6, bugs B1, B2,
/// B3, B6). `best` is the closest-hit register that carries over between casts (bug B1).
#[must_use]
pub fn trace_frame(sets: &[crate::Record], lights: &[crate::Record], camera: &crate::Record, switches: u16, best: &mut H) -> Vec<u16> {
    let shapes: Vec<Shape> = sets.iter().map(shape).collect();
    let o: V = [H::bits(camera.u(1)), H::bits(camera.u(2)), H::bits(camera.u(3))];
    let l0 = &lights[0];
    let lf: V = [H::bits(l0.u(4)), H::bits(l0.u(5)), H::bits(l0.u(6))];
    let ldir: V = [lf[0].neg(), lf[1].neg(), lf[2].neg()];
    let (dxs, dys) = directions();
    let mut fb = vec![0u16; 512 * 384];
    for (y, &dy) in dys.iter().enumerate() {
        for (x, &dx) in dxs.iter().enumerate() {
            let d: V = [dx, dy, H::bits(0xBC00)];
            fb[y * 512 + x] = pixel(&shapes, o, d, ldir, switches, best);
        }
    }
    fb
}

/// The board's per-column x and per-row y ray directions: accumulated in binary16 from
/// 0xC4FD and 0xC37B by steps of 0x2500 (SPEC §5).
#[must_use]
pub fn directions() -> (Vec<H>, Vec<H>) {
    let step = H::bits(0x2500);
    let walk = |start: u16, n: usize| {
        let mut v = Vec::with_capacity(n);
        let mut d = H::bits(start);
        for _ in 0..n {
            v.push(d);
            d = d.add(step);
        }
        v
    };
    (walk(0xC4FD, 512), walk(0xC37B, 384))
}

/// One cast through the shape unit: the accepted hit (index, t), with the stale best-distance
/// comparison of bug B1 (shape 0 is accepted whenever it hits; later shapes are compared
/// with the register as it was two cycles earlier, i.e. before this cast).
fn cast(shapes: &[Shape], o: V, d: V, skip: Option<usize>, best: &mut H) -> Option<(usize, H)> {
    let stale = *best;
    let dd = dot(d, d);
    let mut out = None;
    for (i, sh) in shapes.iter().enumerate() {
        if sh.typ == 0 || Some(i) == skip {
            continue;
        }
        let (p, ld) = to_local(sh, o, d);
        let Some(t) = root(sh.typ, p, ld) else { continue };
        let dist = t.mul(t).mul(dd);
        if i == 0 || dist.f() < stale.f() {
            out = Some((i, t));
            *best = dist;
        }
    }
    out
}

fn pixel(shapes: &[Shape], o: V, d: V, ldir: V, switches: u16, best: &mut H) -> u16 {
    let Some((h, t)) = cast(shapes, o, d, None, best) else { return switches };
    let sh = &shapes[h];
    let hit: V = [o[0].add(t.mul(d[0])), o[1].add(t.mul(d[1])), o[2].add(t.mul(d[2]))];
    // Shadow: any other shape with a real root t ≥ 0 along -forward from the hit point.
    if cast(shapes, hit, ldir, Some(h), best).is_some() {
        return 0;
    }
    let (p, ld) = to_local(sh, o, d);
    let lp: V = [p[0].add(t.mul(ld[0])), p[1].add(t.mul(ld[1])), p[2].add(t.mul(ld[2]))];
    let n: V = match sh.typ {
        2 => [lp[0], lp[1], H(f16::ZERO)],
        3 => [lp[0], lp[1], lp[2].neg()],
        _ => lp,
    };
    let n: V = [n[0].mul(sh.s[0]), n[1].mul(sh.s[1]), n[2].mul(sh.s[2])];
    let r = ham(ham(sh.q, [H(f16::ZERO), n[0], n[1], n[2]]), [sh.q[0], sh.q[1].neg(), sh.q[2].neg(), sh.q[3].neg()]);
    let nw: V = [r[1], r[2], r[3]];
    let cos = dot(nw, ldir).div(dot(nw, nw).sqrt().mul(dot(ldir, ldir).sqrt()));
    if cos.sign() || cos.0.is_nan() {
        return 0;
    }
    let a = cos.f().abs();
    // B3: |cosθ|·2^14 into a 13-bit signed fixed value; assumed to saturate at 4095.
    let k: u32 = if a > 1.0 { 16384 } else { (H::of(a).mul(H::of(16384.0)).f().round_ties_even() as u32).min(4095) };
    let c = sh.col as u32;
    let (r5, g6, b5) = ((c >> 11) & 31, (c >> 5) & 63, c & 31);
    ((((r5 * k) >> 14) << 11) | (((g6 * k) >> 14) << 5) | ((b5 * k) >> 14)) as u16
}

/// The board's rasterizer into a persistent frame buffer (SPEC §7, bug B6).
pub fn raster_frame(sets: &[crate::Record], fb: &mut [u16]) {
    for r in sets {
        let h = |p: u8| H::bits(r.u(p));
        let mut v = [(0i32, 0i32); 3];
        for (k, slot) in v.iter_mut().enumerate() {
            let (x, y, z) = (h(1 + 3 * k as u8), h(2 + 3 * k as u8), h(3 + 3 * k as u8));
            let sx = x.div(z.neg());
            let sy = y.div(z.neg());
            let nx = sx.div(H::of(10.0)).add(H::of(0.5));
            let ny = sy.div(H::of(7.5)).add(H::of(0.5));
            let fix = |q: H| if q.f().is_finite() { q.f().round_ties_even() as i32 } else { 0 };
            let px = fix(nx.mul(H::of(512.0)));
            let py = fix(H::of(1.0).sub(ny).mul(H::of(384.0)));
            // 12-bit unsigned: negatives wrap.
            *slot = (px & 0xFFF, py & 0xFFF);
        }
        let col = r.u(11);
        for vy in 0..384i64 {
            for hx in 1..512i64 {
                let e = |a: (i32, i32), b: (i32, i32)| {
                    (hx - b.0 as i64) * (a.1 as i64 - b.1 as i64) - (a.0 as i64 - b.0 as i64) * (vy - b.1 as i64)
                };
                let es = [e(v[0], v[1]), e(v[1], v[2]), e(v[2], v[0])];
                if !(es.iter().any(|&x| x < 0) && es.iter().any(|&x| x > 0)) {
                    fb[vy as usize * 512 + hx as usize] = col;
                }
            }
        }
    }
}

/// Runs the board model frame by frame.
pub struct Board {
    /// The processor (board ROM and capacities).
    pub processor: Processor,
    build: Build,
    /// Background: the board switches `sw[15:0]`.
    pub switches: u16,
    best: H,
    fb: Vec<u16>,
}

impl Board {
    /// A board running `words`.
    pub fn new(words: &[u32], build: Build, switches: u16) -> Result<Self, DecodeError> {
        Ok(Self { processor: board_processor(words, build)?, build, switches, best: H(f16::ZERO), fb: vec![0; 512 * 384] })
    }

    /// Renders the current state into the board's frame buffer; returns what the VGA shows.
    pub fn frame(&mut self) -> Film {
        let st = &self.processor.state;
        let cap = if self.build == Build::Raytracing { 2 } else { 8 };
        let sets = st.sets.dense(cap);
        match self.build {
            Build::Raytracing => self.fb = trace_frame(&sets[..cap], &st.lights, &st.camera, self.switches, &mut self.best),
            Build::Raster => raster_frame(&sets[..cap], &mut self.fb),
        }
        display(&self.fb)
    }

    /// The raw 16-bit frame buffer.
    #[must_use]
    pub fn frame_buffer(&self) -> &[u16] {
        &self.fb
    }
}

/// What the VGA shows of a 16-bit frame buffer: bits 11..0 as RGB444 (SPEC §1.2).
#[must_use]
pub fn display(fb: &[u16]) -> Film {
    let mut f = Film::new(512, 384);
    for (p, &w) in f.pixels.iter_mut().zip(fb) {
        let c = |s: u16| lucent_scene::srgb_to_linear(((w >> s) & 15) as f32 / 15.0);
        *p = glam::Vec3::new(c(8), c(4), c(0));
    }
    f
}
