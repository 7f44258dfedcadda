//! The path tracer on lanes: a small wavefront inside each thread (issue 58).
//!
//! `path::li` follows one path to its end before it starts the next. Here a block's
//! samples (its pixels × the sample range, pixel by pixel) are a queue, and up to
//! [`CAP`] paths of it are in flight at once, as lanes of a structure of arrays
//! (`Wave`): every step runs one stage for every lane that is at it, and a lane whose
//! path ended takes the next sample of the queue at once (path regeneration), so the lanes
//! stay full until the queue runs dry. The stages:
//!
//! 1. trace the closest hits (the camera rays of new lanes as packets, the others one by
//!    one) and rebuild the surfaces, their BSDFs and shading frames, lane by lane;
//! 2. on lanes: the sampler's numbers of the bounce, the directions in the shading
//!    frame ([`crate::lanes`] compiles each loop for AVX-512, AVX2 and the baseline, with
//!    the same bits);
//! 3. a light sample per lane, the BSDF toward it, multiple importance sampling, the
//!    shadow rays (traced one by one);
//! 4. the BSDF's sample, the throughput, roulette and the next ray, on lanes.
//!
//! The estimator is the path tracer's own, number for number: the same sampler dimensions
//! per (pixel, sample, bounce), the same BSDFs, lights, MIS and roulette, so a sample's
//! value is the scalar path tracer's bit for bit (`tests/image_bits.rs` checks both
//! kernels), whatever its lane, its wave or its neighbours: images do not depend on
//! threads, tiles or regions.
//!
//! Camera rays of one pixel's samples lie in one pixel's footprint: they are traced as one
//! packet (up to 64 rays), where the packet kernels cull almost every node for all of them
//! at once (Mitsuba's lanes are pixel-major for the same reason).

// Lane loops index several arrays by the lane number; written so, they vectorize.
#![allow(clippy::needless_range_loop)]

use super::hit::{bsdf_frame, coherent, emitted, light_normal, material, shading_normal, Bend};
use super::path::{LightSampling, PathSettings, CHOICES, PAIRS};
use super::wave_profile::{now, Part, Watch};
use crate::bsdf::microfacet::{reflect, SlopeSearch};
use crate::bsdf::sample::reflection_lane;
use crate::bsdf::{
    Blend, Bsdf, BsdfSample, Conductor, Dielectric, Diffuse, DiffuseGlossy, Mask, MetallicRoughness, Plastic, Principled, RoughConductor,
    RoughDielectric, RoughPlasticLane, ThinDielectric,
};
use crate::lanes::{get3, on_lanes, put3};
use crate::lights::area::EmissiveTri;
use crate::lights::delta::DeltaLane;
use crate::lights::environment::EnvBatch;
use crate::lights::{delta_sample, flat_sample, Choice, LightSample, Weights};
use crate::sampler::PixelSampler;
use crate::sampling::{power_heuristic, ShadingFrame};
use crate::tiles::{Block, SampleBlock, NO_RAYS};
use crate::world::surface::Surface;
use crate::world::World;
use glam::Vec3;
use lucent_accel::{Hit, Ray, MAX_PACKET};
use lucent_scene::Distribution;

/// Paths in flight per thread. (64 before: 128 made the envmap scene 7% and the
/// materials and rough_checker scenes 2% faster, whole renders; the BSDF loops see twice
/// the lanes of a model.)
pub const CAP: usize = 128;

// (Every lane's environment sample fits one batch.)
const _: () = assert!(crate::lights::environment::ENV_BATCH >= CAP);

/// Half the lanes: the other constant count a cheap model's loops run over
/// ([`Model::PAD_ALL`]).
const HALF: usize = CAP / 2;

/// Queue entries rendered before their values are added to the pixels' sums: the values
/// wait in a buffer until every path of the chunk has ended, so that each pixel's samples
/// are added in order of their index.
const CHUNK: usize = 1024;

/// Three rows of lanes (a vector per lane).
type Rows = [[f32; CAP]; 3];

/// Adds `v` to lane `i` of three rows.
#[inline(always)]
fn add3(r: &mut Rows, i: usize, v: Vec3) {
    r[0][i] += v.x;
    r[1][i] += v.y;
    r[2][i] += v.z;
}

/// The paths in flight, as lanes: lane `i` of every field is path `i`.
struct Wave<'w> {
    /// Lanes in use.
    n: usize,
    /// Each path's entry in the chunk (where its value goes), sample index and pixel
    /// sampler.
    slot: [u32; CAP],
    k: [u32; CAP],
    px: [PixelSampler; CAP],
    /// The ray to trace next (as the world takes it).
    ray: [Ray; CAP],
    /// The camera ray's closest hit, found by a packet (`Some`), or to find (`None`).
    first: [Option<Option<Hit>>; CAP],
    radiance: Rows,
    beta: Rows,
    /// The previous bounce: its BSDF pdf, whether it was a delta lobe, where it was.
    prev_pdf: [f32; CAP],
    prev_delta: [bool; CAP],
    prev_p: Rows,
    /// (Its light normal, `light_normal`: where the light choice was weighed and the
    /// sky sampled.)
    prev_n: Rows,
    /// The light-choice weights at the previous bounce (its light stage weighed them
    /// there, `weighed`): the probability of choosing a light met after it.
    weights: [Weights; CAP],
    weighed: [bool; CAP],
    depth: [u32; CAP],
    eta: [f32; CAP],
    /// This bounce (stage 1): whether the path scatters here, its surface, BSDF, frame
    /// and the direction toward the viewer in it.
    scatter: [bool; CAP],
    surf: [Surface; CAP],
    bsdf: [Option<Bsdf<'w>>; CAP],
    frame: [ShadingFrame; CAP],
    bend: [Bend; CAP],
    wo: Rows,
    /// This bounce's numbers (stage 2): the light choice and point, the lobe choice and
    /// direction.
    u_light: [f32; CAP],
    u2_light: [[f32; CAP]; 2],
    u_bsdf: [f32; CAP],
    u2_bsdf: [[f32; CAP]; 2],
    u_rr: [f32; CAP],
    /// The path ended (its value is written when it leaves).
    done: [bool; CAP],
}

impl<'w> Wave<'w> {
    fn new() -> Box<Self> {
        let zero = [[0.0; CAP]; 3];
        let surf = Surface { p: Vec3::ZERO, ng: Vec3::Z, ns: Vec3::Z, uv: glam::Vec2::ZERO, material: 0, p_err: Vec3::ZERO };
        Box::new(Self {
            n: 0,
            slot: [0; CAP],
            k: [0; CAP],
            px: [PixelSampler::default(); CAP],
            ray: [NO_RAYS[0]; CAP],
            first: [None; CAP],
            radiance: zero,
            beta: zero,
            prev_pdf: [0.0; CAP],
            prev_delta: [true; CAP],
            prev_p: zero,
            prev_n: zero,
            weights: [Weights::UNIFORM; CAP],
            weighed: [false; CAP],
            depth: [0; CAP],
            eta: [1.0; CAP],
            scatter: [false; CAP],
            surf: [surf; CAP],
            bsdf: [None; CAP],
            frame: [ShadingFrame::new(Vec3::Z); CAP],
            bend: [Bend::NONE; CAP],
            wo: zero,
            u_light: [0.0; CAP],
            u2_light: [[0.0; CAP]; 2],
            u_bsdf: [0.0; CAP],
            u2_bsdf: [[0.0; CAP]; 2],
            u_rr: [0.0; CAP],
            done: [false; CAP],
        })
    }

    /// A new path in lane `i`: sample `k` of the pixel of sampler `px`, along `ray`.
    fn start(&mut self, i: usize, slot: u32, k: u32, px: PixelSampler, ray: Ray) {
        self.slot[i] = slot;
        self.k[i] = k;
        self.px[i] = px;
        self.ray[i] = ray;
        self.first[i] = None;
        put3(&mut self.radiance, i, Vec3::ZERO);
        put3(&mut self.beta, i, Vec3::ONE);
        self.prev_pdf[i] = 0.0;
        self.prev_delta[i] = true;
        put3(&mut self.prev_p, i, ray.org);
        put3(&mut self.prev_n, i, Vec3::ZERO);
        self.weighed[i] = false;
        self.depth[i] = 0;
        self.eta[i] = 1.0;
        self.done[i] = false;
    }

    /// The light-choice weights at lane `i`'s previous bounce: kept by its light stage,
    /// else found again.
    #[inline]
    fn prev_weights(&self, lights: &crate::lights::LightSet, i: usize) -> Weights {
        if self.weighed[i] {
            self.weights[i]
        } else {
            lights.weigh(get3(&self.prev_p, i), get3(&self.prev_n, i))
        }
    }

    /// Moves the path of lane `from` into lane `to` (what a path carries between bounces).
    fn relocate(&mut self, from: usize, to: usize) {
        self.slot[to] = self.slot[from];
        self.k[to] = self.k[from];
        self.px[to] = self.px[from];
        self.ray[to] = self.ray[from];
        self.first[to] = self.first[from];
        for c in 0..3 {
            self.radiance[c][to] = self.radiance[c][from];
            self.beta[c][to] = self.beta[c][from];
            self.prev_p[c][to] = self.prev_p[c][from];
            self.prev_n[c][to] = self.prev_n[c][from];
        }
        self.prev_pdf[to] = self.prev_pdf[from];
        self.prev_delta[to] = self.prev_delta[from];
        self.weights[to] = self.weights[from];
        self.weighed[to] = self.weighed[from];
        self.depth[to] = self.depth[from];
        self.eta[to] = self.eta[from];
        self.done[to] = self.done[from];
    }
}

/// A BSDF model whose `sample`, `eval` and `pdf` run on lanes: called in a loop over lanes
/// of one model (their parameters packed), written branch-free enough that LLVM vectorizes
/// the loop, and the same code as one call (the same bits).
trait Model: Copy {
    /// Whether the model's loops vectorize (their lane counts are then padded to whole
    /// vectors: a scalar remainder costs more than the padding's extra lanes).
    const VECTOR: bool = false;
    /// With [`Model::VECTOR`]: padded to [`HALF`] or all [`CAP`] lanes, one loop of a constant count
    /// (a cheap model: the Lambertian's strip loops did not vectorize, its 64-lane loop
    /// does), else to whole strips of [`STRIP`] lanes.
    const PAD_ALL: bool = false;
    /// Whether its sample is taken in two parts: the direction lane by lane
    /// ([`Model::prepare`]: what does not vectorize, such as a facet normal or a table's
    /// entry), then its value and density on lanes ([`Model::eval_pdf`]); the sample is a
    /// reflection (weight f / pdf, where the directions lie on the same side and the
    /// density is positive).
    const TWO_PHASE: bool = false;
    /// The sample and whether there is one (when not, its fields go unused).
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool);
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32);
    /// With [`Model::TWO_PHASE`]: the sample's direction (it may keep what `eval_pdf`
    /// needs for it in `self`).
    #[inline(always)]
    fn prepare(&mut self, _wo: Vec3, _u: f32, _u2: (f32, f32)) -> Vec3 {
        Vec3::Z
    }
    /// With [`Model::TWO_PHASE`]: the sample from its direction, value and density, and
    /// whether there is one (by default a reflection's, see [`reflection_lane`]).
    #[inline(always)]
    fn finish(&self, wo: Vec3, wi: Vec3, f: Vec3, pdf: f32) -> (BsdfSample, bool) {
        reflection_lane(wo, wi, f, pdf)
    }
    /// With [`Model::TWO_PHASE`]: whether its direction starts with a Beckmann slope
    /// search whose first steps run on lanes ([`Model::search`]) before the rest of the
    /// direction is found lane by lane ([`Model::prepare_from`]).
    const SEARCH: bool = false;
    /// With [`Model::SEARCH`]: the search's first part (branch-free).
    #[inline(always)]
    fn search(&self, _wo: Vec3, _u: f32, _u2: (f32, f32)) -> SlopeSearch {
        SlopeSearch::default()
    }
    /// With [`Model::SEARCH`]: [`Model::prepare`] from the search's first part.
    #[inline(always)]
    fn prepare_from(&mut self, wo: Vec3, u: f32, u2: (f32, f32), _s: SlopeSearch) -> Vec3 {
        self.prepare(wo, u, u2)
    }
    /// With [`Model::TWO_PHASE`]: whether the direction is found on lanes too
    /// ([`Model::direction_lane`], branch-free), its sample then being `f / pdf` where the
    /// direction is valid and the density positive and finite (not a delta).
    const LANE_DIRECTION: bool = false;
    /// With [`Model::LANE_DIRECTION`]: the sample's direction, the relative index it
    /// crosses, and whether there is one.
    #[inline(always)]
    fn direction_lane(&self, _wo: Vec3, _u: f32, _u2: (f32, f32)) -> (Vec3, f32, bool) {
        (Vec3::Z, 1.0, false)
    }
}

/// A sample as [`Model::sample`] gives it.
#[inline(always)]
fn some(s: Option<BsdfSample>) -> (BsdfSample, bool) {
    (s.unwrap_or(BsdfSample { wi: Vec3::Z, weight: Vec3::ZERO, pdf: 0.0, delta: false, eta: 1.0 }), s.is_some())
}

impl Model for Diffuse {
    const VECTOR: bool = true;
    const PAD_ALL: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, _u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        self.sample_lane(wo, u2)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        (self.eval(wo, wi), self.pdf(wo, wi))
    }
}
/// Smooth conductors only (the rough ones are packed as [`RoughConductor`]), lane by lane.
impl Model for Conductor {
    #[inline(always)]
    fn sample(&self, wo: Vec3, _u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        some(Conductor::sample(self, wo, u2))
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        Conductor::eval_pdf(self, wo, wi)
    }
}
impl<const BECKMANN: bool> Model for RoughConductor<BECKMANN> {
    const VECTOR: bool = true;
    // (PERF: for GGX, one loop of sample, value, density and weight did not vectorize; in
    // two parts it does. Beckmann's sample does not vectorize at all.)
    const TWO_PHASE: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, _u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        RoughConductor::sample(self, wo, u2)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        RoughConductor::eval_pdf(self, wo, wi)
    }
    #[inline(always)]
    fn prepare(&mut self, wo: Vec3, _u: f32, u2: (f32, f32)) -> Vec3 {
        self.direction(wo, u2)
    }
    // (Conductors only: a rough plastic's or an MTL surface's lanes take a facet only
    // where they choose the glossy lobe, often a few, and there the search's first steps
    // on every lane cost more than the steps one by one: bumpmap 12%, normalmap 8% slower.)
    const SEARCH: bool = BECKMANN;
    #[inline(always)]
    fn search(&self, wo: Vec3, _u: f32, u2: (f32, f32)) -> SlopeSearch {
        self.mf.beckmann_start(wo, u2)
    }
    #[inline(always)]
    fn prepare_from(&mut self, wo: Vec3, _u: f32, _u2: (f32, f32), s: SlopeSearch) -> Vec3 {
        reflect(wo, self.mf.beckmann_from(self.mf.stretched(wo), s))
    }
}
/// Smooth dielectrics only (the rough ones are packed as [`RoughDielectric`]).
impl Model for Dielectric {
    const VECTOR: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, _u2: (f32, f32)) -> (BsdfSample, bool) {
        self.smooth_sample(wo, u)
    }
    #[inline(always)]
    fn eval_pdf(&self, _wo: Vec3, _wi: Vec3) -> (Vec3, f32) {
        (Vec3::ZERO, 0.0)
    }
}
impl<const BECKMANN: bool> Model for RoughDielectric<BECKMANN> {
    const VECTOR: bool = true;
    const TWO_PHASE: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        RoughDielectric::sample(*self, wo, u, u2)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        RoughDielectric::eval_pdf(self, wo, wi)
    }
    #[inline(always)]
    fn prepare(&mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        self.direction(wo, u, u2)
    }
    #[inline(always)]
    fn finish(&self, wo: Vec3, wi: Vec3, f: Vec3, pdf: f32) -> (BsdfSample, bool) {
        RoughDielectric::finish(self, wo, wi, f, pdf)
    }
}
impl Model for Plastic {
    const VECTOR: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        self.sample_lane(wo, u, u2)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        Plastic::eval_pdf(self, wo, wi)
    }
}
impl<const BECKMANN: bool> Model for RoughPlasticLane<'_, BECKMANN> {
    const VECTOR: bool = true;
    const TWO_PHASE: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        RoughPlasticLane::sample(*self, wo, u, u2)
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        RoughPlasticLane::eval_pdf(self, wo, wi)
    }
    #[inline(always)]
    fn prepare(&mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        RoughPlasticLane::prepare(self, wo, u, u2)
    }
}
/// glTF's metallic-roughness BRDF on lanes: its direction lane by lane (kept valid or not),
/// value and density branch-free.
#[derive(Clone, Copy)]
struct MetallicRoughnessLane {
    b: MetallicRoughness,
    valid: bool,
}
impl Model for MetallicRoughnessLane {
    const VECTOR: bool = true;
    const TWO_PHASE: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        some(self.b.sample(wo, u, u2))
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.b.eval_pdf(wo, wi)
    }
    #[inline(always)]
    fn prepare(&mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        let wi = self.b.direction(wo, u, u2);
        self.valid = wi.is_some();
        wi.unwrap_or(Vec3::Z)
    }
    #[inline(always)]
    fn finish(&self, _wo: Vec3, wi: Vec3, f: Vec3, pdf: f32) -> (BsdfSample, bool) {
        // (Thin-walled: no index is crossed either way.)
        (BsdfSample { wi, weight: f / pdf, pdf, delta: false, eta: 1.0 }, self.valid & (pdf > 0.0) & pdf.is_finite())
    }
}
/// Mitsuba's principled BSDF on lanes: its direction, value and density all branch-free,
/// each a loop over lanes.
impl Model for Principled {
    const VECTOR: bool = true;
    const TWO_PHASE: bool = true;
    const LANE_DIRECTION: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        some(Principled::sample(self, wo, u, u2))
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        Principled::eval_pdf_lane(*self, wo, wi)
    }
    #[inline(always)]
    fn direction_lane(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (Vec3, f32, bool) {
        Principled::direction_lane(*self, wo, u, u2)
    }
}
impl Model for ThinDielectric {
    const VECTOR: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, _u2: (f32, f32)) -> (BsdfSample, bool) {
        (self.sample_lane(wo, u), true)
    }
    #[inline(always)]
    fn eval_pdf(&self, _wo: Vec3, _wi: Vec3) -> (Vec3, f32) {
        (Vec3::ZERO, 0.0)
    }
}
impl Model for DiffuseGlossy {
    const VECTOR: bool = true;
    const TWO_PHASE: bool = true;
    #[inline(always)]
    fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        some(DiffuseGlossy::sample(self, wo, u, u2))
    }
    #[inline(always)]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        DiffuseGlossy::eval_pdf(self, wo, wi)
    }
    #[inline(always)]
    fn prepare(&mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        // (Below the surface there is no sample: the second phase finds it so.)
        if wo.z > 0.0 {
            self.direction(wo, u, u2)
        } else {
            Vec3::Z
        }
    }
}

/// The lanes of one model, packed: which lanes, their BSDFs and directions; the sample's
/// results, or `eval` and `pdf` toward `wi`.
struct Packed<B> {
    lane: Vec<u8>,
    bsdf: Vec<B>,
    wo: Rows,
    /// In: the direction toward the light (eval); out: the sampled direction.
    wi: Rows,
    u: [f32; CAP],
    u2: [[f32; CAP]; 2],
    /// Out: `eval` (or the sample's weight), `pdf` (or the sample's), and the sample's
    /// delta flag, relative index and whether there is one.
    f: Rows,
    pdf: [f32; CAP],
    delta: [bool; CAP],
    eta: [f32; CAP],
    ok: [bool; CAP],
    /// With [`Model::SEARCH`]: the slope searches' first parts, as rows
    /// ([`SlopeSearch::to_row`]).
    search: [[f32; CAP]; 11],
}

/// Runs `$body` for the packed lanes `$j` of `$bsdfs` (`$bsdf`: their BSDFs, `$n` of
/// them): over a constant [`CAP`] lanes when [`Model::VECTOR`] padded them (a loop LLVM
/// turns into whole vectors), else over `0..$n`.
macro_rules! packed_loop {
    ($bsdfs:expr, $n:expr, |$bsdf:ident, $j:ident| $body:block) => {
        if B::VECTOR && $n == CAP {
            let $bsdf = &$bsdfs[..CAP];
            for $j in 0..CAP $body
        } else if B::VECTOR && $n == HALF {
            let $bsdf = &$bsdfs[..HALF];
            for $j in 0..HALF $body
        } else if B::VECTOR && $n % STRIP == 0 {
            let $bsdf = &$bsdfs[..$n];
            for strip in 0..$n / STRIP {
                let base = strip * STRIP;
                assert!(base + STRIP <= CAP && base + STRIP <= $bsdf.len());
                for k in 0..STRIP {
                    let $j = base + k;
                    $body
                }
            }
        } else {
            let $bsdf = &$bsdfs[..$n];
            for $j in 0..$n $body
        }
    };
}

/// At most this many lanes of a vector model run unpadded (lane by lane): a strip's
/// vectors cost more than a few lanes one by one.
const SPARSE: usize = 4;

/// Lanes per strip of a vector model's loops: its packed lanes are padded to whole strips,
/// each strip a loop of this constant count (whole vectors: two of AVX2, one of AVX-512).
const STRIP: usize = 16;

impl<B: Model> Packed<B> {
    fn new() -> Box<Self> {
        let z = [[0.0; CAP]; 3];
        Box::new(Self {
            lane: Vec::with_capacity(CAP),
            bsdf: Vec::with_capacity(CAP),
            wo: z,
            wi: z,
            u: [0.0; CAP],
            u2: [[0.0; CAP]; 2],
            f: z,
            pdf: [0.0; CAP],
            delta: [false; CAP],
            eta: [1.0; CAP],
            ok: [false; CAP],
            search: [[0.0; CAP]; 11],
        })
    }

    fn clear(&mut self) {
        self.lane.clear();
        self.bsdf.clear();
    }

    /// Lane `i` of the wave, of BSDF `b`, seen from `wo`, toward `wi` (eval) or with the
    /// numbers `u`, `u2` (sample).
    #[inline(always)]
    fn push(&mut self, i: usize, b: B, wo: Vec3, wi: Vec3, u: f32, u2: (f32, f32)) {
        let j = self.lane.len();
        self.lane.push(i as u8);
        self.bsdf.push(b);
        put3(&mut self.wo, j, wo);
        put3(&mut self.wi, j, wi);
        self.u[j] = u;
        (self.u2[0][j], self.u2[1][j]) = u2;
    }

    /// The number of lanes the loops run over: with [`Model::VECTOR`], whole strips of
    /// [`STRIP`] lanes, the BSDFs padded with copies of the last (their results go unused).
    /// PERF: a loop of a constant count is whole vectors; over `0..n` LLVM vectorized 4
    /// vectors per step and sent any `n` below 64 down its scalar remainder; padded to all
    /// [`CAP`] lanes, a few lanes of a costly model (a rough conductor) paid for 64.
    #[inline(always)]
    fn padded(&mut self) -> usize {
        let n = self.bsdf.len();
        if B::VECTOR && n > SPARSE {
            let last = self.bsdf[n - 1];
            let to = match (B::PAD_ALL, n <= HALF) {
                (true, true) => HALF,
                (true, false) => CAP,
                (false, _) => n.div_ceil(STRIP) * STRIP,
            };
            self.bsdf.resize(to, last);
        }
        self.bsdf.len()
    }

    /// The sample of every packed lane.
    #[inline(always)]
    fn sample_all(&mut self) {
        if B::TWO_PHASE && B::LANE_DIRECTION {
            let n = self.padded();
            packed_loop!(self.bsdf, n, |bsdf, j| {
                let (wi, eta, ok) = bsdf[j].direction_lane(get3(&self.wo, j), self.u[j], (self.u2[0][j], self.u2[1][j]));
                put3(&mut self.wi, j, wi);
                self.eta[j] = eta;
                self.ok[j] = ok;
            });
            packed_loop!(self.bsdf, n, |bsdf, j| {
                let (f, pdf) = bsdf[j].eval_pdf(get3(&self.wo, j), get3(&self.wi, j));
                put3(&mut self.f, j, f / pdf);
                self.pdf[j] = pdf;
                self.ok[j] &= (pdf > 0.0) & pdf.is_finite();
                self.delta[j] = false;
            });
            return;
        }
        if B::TWO_PHASE {
            // (The directions lane by lane, then their values and densities on lanes as
            // `eval_all` takes them, then the weights. PERF: one loop for the last two, as
            // `sample` is written, did not vectorize.)
            if B::SEARCH {
                // (The searches' first steps on lanes, then the directions lane by lane.)
                let live = self.bsdf.len();
                let n = self.padded();
                packed_loop!(self.bsdf, n, |bsdf, j| {
                    let row = bsdf[j].search(get3(&self.wo, j), self.u[j], (self.u2[0][j], self.u2[1][j])).to_row();
                    for k in 0..11 {
                        self.search[k][j] = row[k];
                    }
                });
                for j in 0..live {
                    let s = SlopeSearch::from_row(std::array::from_fn(|k| self.search[k][j]));
                    let wi = self.bsdf[j].prepare_from(get3(&self.wo, j), self.u[j], (self.u2[0][j], self.u2[1][j]), s);
                    put3(&mut self.wi, j, wi);
                }
            } else {
                for j in 0..self.bsdf.len() {
                    let wi = self.bsdf[j].prepare(get3(&self.wo, j), self.u[j], (self.u2[0][j], self.u2[1][j]));
                    put3(&mut self.wi, j, wi);
                }
            }
            let n = self.padded();
            packed_loop!(self.bsdf, n, |bsdf, j| {
                let (f, pdf) = bsdf[j].eval_pdf(get3(&self.wo, j), get3(&self.wi, j));
                put3(&mut self.f, j, f);
                self.pdf[j] = pdf;
            });
            packed_loop!(self.bsdf, n, |bsdf, j| {
                let (wo, wi) = (get3(&self.wo, j), get3(&self.wi, j));
                let (s, ok) = bsdf[j].finish(wo, wi, get3(&self.f, j), self.pdf[j]);
                self.ok[j] = ok;
                put3(&mut self.f, j, s.weight);
                self.delta[j] = s.delta;
                self.eta[j] = s.eta;
            });
            return;
        }
        let n = self.padded();
        packed_loop!(self.bsdf, n, |bsdf, j| {
            let (s, ok) = bsdf[j].sample(get3(&self.wo, j), self.u[j], (self.u2[0][j], self.u2[1][j]));
            self.ok[j] = ok;
            put3(&mut self.wi, j, s.wi);
            put3(&mut self.f, j, s.weight);
            self.pdf[j] = s.pdf;
            self.delta[j] = s.delta;
            self.eta[j] = s.eta;
        });
    }

    /// `eval` and `pdf` of every packed lane toward its `wi`.
    #[inline(always)]
    fn eval_all(&mut self) {
        let n = self.padded();
        packed_loop!(self.bsdf, n, |bsdf, j| {
            let (wo, wi) = (get3(&self.wo, j), get3(&self.wi, j));
            let (f, pdf) = bsdf[j].eval_pdf(wo, wi);
            put3(&mut self.f, j, f);
            self.pdf[j] = pdf;
        });
    }
}

/// Runs `$method` (`sample_all` or `eval_all`) on the packed lanes of every model, each loop
/// on lanes.
macro_rules! run_models {
    ($models:expr, $method:ident) => {{
        let m = $models;
        if !m.diffuse.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<Diffuse>| p.$method())(&mut m.diffuse);
        }
        if !m.conductor.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<Conductor>| p.$method())(&mut m.conductor);
        }
        if !m.ggx_conductor.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<RoughConductor<false>>| p.$method())(&mut m.ggx_conductor);
        }
        if !m.beckmann_conductor.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<RoughConductor<true>>| p.$method())(&mut m.beckmann_conductor);
        }
        if !m.dielectric.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<Dielectric>| p.$method())(&mut m.dielectric);
        }
        if !m.ggx_dielectric.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<RoughDielectric<false>>| p.$method())(&mut m.ggx_dielectric);
        }
        if !m.beckmann_dielectric.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<RoughDielectric<true>>| p.$method())(&mut m.beckmann_dielectric);
        }
        if !m.plastic.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<Plastic>| p.$method())(&mut m.plastic);
        }
        if !m.beckmann_plastic.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<RoughPlasticLane<'_, true>>| p.$method())(&mut m.beckmann_plastic);
        }
        if !m.ggx_plastic.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<RoughPlasticLane<'_, false>>| p.$method())(&mut m.ggx_plastic);
        }
        if !m.metallic_roughness.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<MetallicRoughnessLane>| p.$method())(&mut m.metallic_roughness);
        }
        if !m.thin.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<ThinDielectric>| p.$method())(&mut m.thin);
        }
        if !m.diffuse_glossy.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<DiffuseGlossy>| p.$method())(&mut m.diffuse_glossy);
        }
        if !m.principled.bsdf.is_empty() {
            on_lanes!(|p: &mut Packed<Principled>| p.$method())(&mut m.principled);
        }
    }};
}

/// Calls `$f(packed)` for every model's packed lanes.
macro_rules! each_model {
    ($models:expr, |$p:ident| $body:expr) => {{
        let m = $models;
        {
            let $p = &mut m.diffuse;
            $body
        }
        {
            let $p = &mut m.conductor;
            $body
        }
        {
            let $p = &mut m.ggx_conductor;
            $body
        }
        {
            let $p = &mut m.beckmann_conductor;
            $body
        }
        {
            let $p = &mut m.dielectric;
            $body
        }
        {
            let $p = &mut m.ggx_dielectric;
            $body
        }
        {
            let $p = &mut m.beckmann_dielectric;
            $body
        }
        {
            let $p = &mut m.plastic;
            $body
        }
        {
            let $p = &mut m.beckmann_plastic;
            $body
        }
        {
            let $p = &mut m.ggx_plastic;
            $body
        }
        {
            let $p = &mut m.metallic_roughness;
            $body
        }
        {
            let $p = &mut m.thin;
            $body
        }
        {
            let $p = &mut m.diffuse_glossy;
            $body
        }
        {
            let $p = &mut m.principled;
            $body
        }
    }};
}

/// The scatter stage's samples by lane: whether there is one, its direction, weight,
/// density, delta flag and relative index.
struct SampleRows {
    ok: [bool; CAP],
    wi: Rows,
    weight: Rows,
    pdf: [f32; CAP],
    delta: [bool; CAP],
    eta: [f32; CAP],
}

impl SampleRows {
    fn new() -> Self {
        Self { ok: [false; CAP], wi: [[0.0; CAP]; 3], weight: [[0.0; CAP]; 3], pdf: [0.0; CAP], delta: [false; CAP], eta: [1.0; CAP] }
    }

    /// Lane `i`'s sample from packed lane `j` of `p`.
    #[inline(always)]
    fn put<B>(&mut self, i: usize, p: &Packed<B>, j: usize) {
        self.ok[i] = p.ok[j];
        put3(&mut self.wi, i, get3(&p.wi, j));
        put3(&mut self.weight, i, get3(&p.f, j));
        (self.pdf[i], self.delta[i], self.eta[i]) = (p.pdf[j], p.delta[j], p.eta[j]);
    }

    /// Lane `i`'s sample (whether there is one: `ok`).
    #[inline]
    fn get(&self, i: usize) -> BsdfSample {
        BsdfSample { wi: get3(&self.wi, i), weight: get3(&self.weight, i), pdf: self.pdf[i], delta: self.delta[i], eta: self.eta[i] }
    }

    /// Sets lane `i`'s sample to `s`, or to none.
    #[inline]
    fn set(&mut self, i: usize, s: Option<BsdfSample>) {
        self.ok[i] = s.is_some();
        if let Some(s) = s {
            put3(&mut self.wi, i, s.wi);
            put3(&mut self.weight, i, s.weight);
            (self.pdf[i], self.delta[i], self.eta[i]) = (s.pdf, s.delta, s.eta);
        }
    }
}

/// One packed set per model, made once per thread's wave.
struct Models<'w> {
    diffuse: Box<Packed<Diffuse>>,
    conductor: Box<Packed<Conductor>>,
    ggx_conductor: Box<Packed<RoughConductor<false>>>,
    beckmann_conductor: Box<Packed<RoughConductor<true>>>,
    dielectric: Box<Packed<Dielectric>>,
    ggx_dielectric: Box<Packed<RoughDielectric<false>>>,
    beckmann_dielectric: Box<Packed<RoughDielectric<true>>>,
    plastic: Box<Packed<Plastic>>,
    beckmann_plastic: Box<Packed<RoughPlasticLane<'w, true>>>,
    ggx_plastic: Box<Packed<RoughPlasticLane<'w, false>>>,
    metallic_roughness: Box<Packed<MetallicRoughnessLane>>,
    thin: Box<Packed<ThinDielectric>>,
    diffuse_glossy: Box<Packed<DiffuseGlossy>>,
    principled: Box<Packed<Principled>>,
    /// The lanes whose BSDF is a blend or a mask, shaded through their parts' packs, and
    /// how each lane's results combine ([`Models::push_eval`], [`Models::push_sample`]).
    mixed: Vec<(u8, Mix)>,
    /// A blend's second part (eval) or the part it did not choose (sample, evaluated
    /// toward the sample), packed apart (made when first needed).
    parts: Option<Box<Models<'w>>>,
    /// The parts blends' samples did not choose, by lane, for the second phase.
    others: Vec<(u8, Bsdf<'w>)>,
}

/// How a lane's BSDF, a blend or a mask, is made of packed BSDFs (Mitsuba's `blendbsdf`
/// and `mask`: [`crate::bsdf::Blend`], [`crate::bsdf::Mask`], whose scalar forms these
/// follow step for step, so the lanes give their bits).
#[derive(Clone, Copy, Debug)]
enum Mix {
    /// A mask of opacity α: its inner BSDF's value and density times α (eval; nothing
    /// packed where α is 0), or its sample's density times α (sample).
    Mask(f32),
    /// A mask's null lobe was chosen (sample): straight through, probability 1 − α.
    Null(f32),
    /// A blend of weight w (eval): (1 − w)·first + w·second, the first packed here, the
    /// second in `parts`, each only where its share is positive.
    Blend(f32),
    /// A blend's sample, drawn from the part chosen with probability p; the other part,
    /// evaluated toward it in `parts` (or one by one), is mixed in.
    Chosen(f32),
}

/// Whether `b` packs as it is (not a blend, a mask or the user's).
#[inline]
fn packable(b: &Bsdf) -> bool {
    !matches!(b, Bsdf::Blend(_) | Bsdf::Mask(_) | Bsdf::Custom(..))
}

impl<'w> Models<'w> {
    fn new() -> Self {
        Self {
            diffuse: Packed::new(),
            conductor: Packed::new(),
            ggx_conductor: Packed::new(),
            beckmann_conductor: Packed::new(),
            dielectric: Packed::new(),
            ggx_dielectric: Packed::new(),
            beckmann_dielectric: Packed::new(),
            plastic: Packed::new(),
            beckmann_plastic: Packed::new(),
            ggx_plastic: Packed::new(),
            metallic_roughness: Packed::new(),
            thin: Packed::new(),
            diffuse_glossy: Packed::new(),
            principled: Packed::new(),
            mixed: Vec::new(),
            parts: None,
            others: Vec::new(),
        }
    }

    fn clear(&mut self) {
        each_model!(&mut *self, |p| p.clear());
        self.mixed.clear();
        self.others.clear();
        if let Some(parts) = &mut self.parts {
            parts.clear();
        }
    }

    /// The packs of blends' other parts.
    fn parts(&mut self) -> &mut Models<'w> {
        self.parts.get_or_insert_with(|| Box::new(Models::new()))
    }

    /// Packs lane `i` for `eval` toward `wi`: its BSDF's model, or a blend's or a mask's
    /// parts (combined by [`Models::mix_eval`]); `false` for what has no lane form, which
    /// the caller takes lane by lane.
    fn push_eval(&mut self, i: usize, b: Bsdf<'w>, wo: Vec3, wi: Vec3) -> bool {
        match b {
            Bsdf::Mask(m) => {
                if m.opacity > 0.0 {
                    let inner = m.inner();
                    if !packable(&inner) {
                        return false;
                    }
                    self.push(i, inner, wo, wi, 0.0, (0.0, 0.0));
                }
                self.mixed.push((i as u8, Mix::Mask(m.opacity)));
                true
            }
            Bsdf::Blend(bl) => {
                let w = bl.weight;
                let (first, second) = (bl.first(), bl.second());
                if (w < 1.0 && !packable(&first)) || (w > 0.0 && !packable(&second)) {
                    return false;
                }
                if w < 1.0 {
                    self.push(i, first, wo, wi, 0.0, (0.0, 0.0));
                }
                if w > 0.0 {
                    self.parts().push(i, second, wo, wi, 0.0, (0.0, 0.0));
                }
                self.mixed.push((i as u8, Mix::Blend(w)));
                true
            }
            _ => self.push(i, b, wo, wi, 0.0, (0.0, 0.0)),
        }
    }

    /// Runs `eval_all` on the blends' second parts.
    fn eval_parts(&mut self) {
        if let Some(parts) = &mut self.parts {
            run_models!(&mut **parts, eval_all);
        }
    }

    /// The results of every lane [`Models::push_eval`] took into `f` and `pdf`: the packed
    /// lanes' as they are, the blends' and masks' combined as their scalar `eval_pdf`.
    fn mix_eval(&mut self, f: &mut Rows, pdf: &mut [f32; CAP]) {
        each_model!(&mut *self, |p| {
            for (j, &i) in p.lane.iter().enumerate() {
                put3(f, usize::from(i), get3(&p.f, j));
                pdf[usize::from(i)] = p.pdf[j];
            }
        });
        if self.mixed.is_empty() {
            return;
        }
        let (mut f2, mut pdf2): (Rows, [f32; CAP]) = ([[0.0; CAP]; 3], [0.0; CAP]);
        if let Some(parts) = &mut self.parts {
            parts.mix_eval(&mut f2, &mut pdf2);
        }
        for &(i, mix) in &self.mixed {
            let i = usize::from(i);
            let own = (get3(f, i), pdf[i]);
            let (fi, pi) = match mix {
                Mix::Mask(a) => Mask::scaled(a, || own),
                Mix::Blend(w) => Blend::mix(w, || own, || (get3(&f2, i), pdf2[i])),
                Mix::Null(_) | Mix::Chosen(_) => own,
            };
            put3(f, i, fi);
            pdf[i] = pi;
        }
    }

    /// Packs lane `i` for a sample (numbers `u`, `u2`): its BSDF's model, or the part a
    /// blend or a mask chooses with `u` (finished by [`Models::mix_sample`]); `false` for
    /// what has no lane form.
    fn push_sample(&mut self, i: usize, b: Bsdf<'w>, wo: Vec3, u: f32, u2: (f32, f32)) -> bool {
        match b {
            Bsdf::Mask(m) => {
                let a = m.opacity;
                let Ok(u) = Mask::choose(a, wo, u) else {
                    self.mixed.push((i as u8, Mix::Null(a)));
                    return true;
                };
                let inner = m.inner();
                if !packable(&inner) {
                    return false;
                }
                self.push(i, inner, wo, Vec3::ZERO, u, u2);
                self.mixed.push((i as u8, Mix::Mask(a)));
                true
            }
            Bsdf::Blend(bl) => {
                let (chosen, other, p, u) = bl.choose(u);
                if !packable(&chosen) {
                    return false;
                }
                self.push(i, chosen, wo, Vec3::ZERO, u, u2);
                self.others.push((i as u8, other));
                self.mixed.push((i as u8, Mix::Chosen(p)));
                true
            }
            _ => self.push(i, b, wo, Vec3::ZERO, u, u2),
        }
    }

    /// The samples of every lane [`Models::push_sample`] took, after `sample_all`: the
    /// packed lanes' as they are, the masks' and blends' finished as their scalar
    /// `sample` (a blend's other part evaluated toward the sample, on lanes where it
    /// packs).
    fn mix_sample(&mut self, wo: &Rows, out: &mut SampleRows) {
        each_model!(&mut *self, |p| {
            for (j, &i) in p.lane.iter().enumerate() {
                out.put(usize::from(i), p, j);
            }
        });
        if self.mixed.is_empty() {
            return;
        }
        let mut alone: Vec<(usize, Vec3, f32)> = Vec::new();
        let others = std::mem::take(&mut self.others);
        for &(i, other) in &others {
            let i = usize::from(i);
            if !out.ok[i] {
                continue;
            }
            let (o, wi) = (get3(wo, i), get3(&out.wi, i));
            if packable(&other) {
                self.parts().push(i, other, o, wi, 0.0, (0.0, 0.0));
            } else {
                let (of, op) = other.eval_pdf(o, wi);
                alone.push((i, of, op));
            }
        }
        self.others = others;
        self.eval_parts();
        let (mut of, mut op): (Rows, [f32; CAP]) = ([[0.0; CAP]; 3], [0.0; CAP]);
        if let Some(parts) = &mut self.parts {
            parts.mix_eval(&mut of, &mut op);
        }
        for (i, f, p) in alone {
            put3(&mut of, i, f);
            op[i] = p;
        }
        for &(i, mix) in &self.mixed {
            let i = usize::from(i);
            match mix {
                Mix::Null(a) => out.set(i, Some(Mask::null(a, get3(wo, i)))),
                Mix::Mask(a) if out.ok[i] => out.set(i, Some(Mask::through(out.get(i), a))),
                Mix::Chosen(p) if out.ok[i] => out.set(i, Blend::mixed(out.get(i), p, get3(&of, i), op[i])),
                Mix::Mask(_) | Mix::Chosen(_) | Mix::Blend(_) => {}
            }
        }
    }

    /// Counts the packed loops just run, and `alone` lanes shaded one by one.
    fn count(&mut self, watch: &mut Watch, alone: usize) {
        if let Some(prof) = &mut watch.p {
            each_model!(self, |p| if !p.lane.is_empty() {
                prof.packed_loops += 1;
                prof.packed_lanes += p.lane.len() as u64;
            });
            prof.alone_lanes += alone as u64;
        }
    }

    /// Packs lane `i` (BSDF `b`) with its model's lanes; `false` for a BSDF without a lane
    /// form (the thin sheet, the user's), which the caller takes lane by lane.
    #[inline(always)]
    fn push(&mut self, i: usize, b: Bsdf<'w>, wo: Vec3, wi: Vec3, u: f32, u2: (f32, f32)) -> bool {
        match b {
            Bsdf::Diffuse(b) => self.diffuse.push(i, b, wo, wi, u, u2),
            Bsdf::Conductor(b) => match b.mf {
                Some(mf) if mf.dist == Distribution::Ggx => self.ggx_conductor.push(i, RoughConductor::of(&b, mf), wo, wi, u, u2),
                Some(mf) => self.beckmann_conductor.push(i, RoughConductor::of(&b, mf), wo, wi, u, u2),
                None => self.conductor.push(i, b, wo, wi, u, u2),
            },
            Bsdf::Dielectric(b) => match b.mf {
                Some(mf) if mf.dist == Distribution::Ggx => self.ggx_dielectric.push(i, RoughDielectric::of(&b, mf), wo, wi, u, u2),
                Some(mf) => self.beckmann_dielectric.push(i, RoughDielectric::of(&b, mf), wo, wi, u, u2),
                None => self.dielectric.push(i, b, wo, wi, u, u2),
            },
            Bsdf::Plastic(b) => self.plastic.push(i, b, wo, wi, u, u2),
            Bsdf::RoughPlastic(b) => match b.mf.dist {
                Distribution::Beckmann => self.beckmann_plastic.push(i, RoughPlasticLane::new(&b, wo, wi), wo, wi, u, u2),
                Distribution::Ggx => self.ggx_plastic.push(i, RoughPlasticLane::new(&b, wo, wi), wo, wi, u, u2),
            },
            Bsdf::MetallicRoughness(b) => self.metallic_roughness.push(i, MetallicRoughnessLane { b, valid: false }, wo, wi, u, u2),
            Bsdf::Thin(b) => self.thin.push(i, b, wo, wi, u, u2),
            Bsdf::DiffuseGlossy(b) => self.diffuse_glossy.push(i, b, wo, wi, u, u2),
            Bsdf::Principled(b) => self.principled.push(i, b, wo, wi, u, u2),
            Bsdf::Blend(_) | Bsdf::Mask(_) | Bsdf::Custom(..) => return false,
        }
        true
    }
}

/// Renders the samples `s.range` of `block`'s pixels with `settings`, each pixel's sum (in
/// order of the sample index) into `sums`.
pub(crate) fn shade_samples(settings: &PathSettings, s: &SampleBlock, block: &Block, sums: &mut [Vec3]) {
    let samples = s.range.len();
    shade_with(settings, s, block, |j, kk, v| {
        if samples == 1 {
            sums[j] = v;
        } else {
            if kk == 0 {
                sums[j] = Vec3::ZERO;
            }
            sums[j] += v;
        }
    });
}

/// Renders the samples `s.range` of `block`'s pixels with `settings`, each sample's value
/// into `out[j · n + kk]` (see [`crate::tiles::BlockShader::shade_each`]).
pub(crate) fn shade_each(settings: &PathSettings, s: &SampleBlock, block: &Block, out: &mut [Vec3]) {
    let samples = s.range.len();
    shade_with(settings, s, block, |j, kk, v| out[j * samples + kk] = v);
}

/// Renders the samples `s.range` of `block`'s pixels, handing each value to `emit(pixel,
/// sample - s.range.start, value)`, pixel by pixel in order of the sample index.
fn shade_with(settings: &PathSettings, s: &SampleBlock, block: &Block, mut emit: impl FnMut(usize, usize, Vec3)) {
    let w = s.world;
    let samples = s.range.len();
    let total = block.pixels.len() * samples;
    let sampler = settings.sampler();
    let mut vals = vec![Vec3::ZERO; CHUNK.min(total)];
    let mut wave = Wave::new();
    let mut models = Models::new();
    let mut flat = Flat::new();
    let mut envs = EnvBatch::new();
    let mut deltas = Deltas::new();
    let mut watch = Watch::new();
    let mut next = 0usize;
    while next < total {
        let end = (next + CHUNK).min(total);
        let chunk = next..end;
        let mut queue = chunk.clone();
        wave.n = 0;
        while wave.n > 0 || !queue.is_empty() {
            // Refill: the next entries of the queue take the free lanes; their camera rays,
            // made together, go out as packets when they are coherent.
            let fresh = wave.n;
            refill(s, block, &sampler, chunk.start, &mut queue, &mut wave);
            watch.lap(Part::Camera);
            camera_packets(w, &mut wave, fresh, block.among, s.traversal.packets);
            watch.lap(Part::ClosestHits);
            step(w, settings, &mut wave, &mut models, (&mut flat, &mut envs, &mut deltas), &mut vals, &mut watch);
        }
        // The chunk's values, pixel by pixel in order of the sample index.
        for e in chunk.clone() {
            emit(e / samples, e % samples, vals[e - chunk.start]);
        }
        next = end;
        watch.lap(Part::Film);
    }
    if let Some(p) = &mut watch.p {
        p.samples += total as u64;
    }
    watch.finish();
}

/// Fills the free lanes with the next entries of `queue` (entry `e`: sample `e % samples`
/// of pixel `e / samples`, its value at `e - start`): their samplers, then their camera
/// rays made together ([`crate::camera::Camera::rays_at`], which vectorizes; the same
/// bits as [`SampleBlock::camera_ray`], ray by ray).
fn refill(
    s: &SampleBlock,
    block: &Block,
    sampler: &crate::sampler::Sampler,
    start: usize,
    queue: &mut std::ops::Range<usize>,
    wave: &mut Wave,
) {
    let samples = s.range.len();
    let fresh = wave.n;
    let (mut xs, mut ys, mut ks) = ([0u32; CAP], [0u32; CAP], [0u32; CAP]);
    let mut m = 0;
    while fresh + m < CAP {
        let Some(e) = queue.next() else { break };
        let (j, k) = (e / samples, s.range.start + (e % samples) as u32);
        (xs[m], ys[m]) = block.pixels[j];
        ks[m] = k;
        wave.slot[fresh + m] = (e - start) as u32;
        m += 1;
    }
    // The lanes' pixel samplers and positions in their pixels: hashes and scrambles, on
    // lanes where the samples are the sampler's first pair as they are (no filter to
    // place them by: the tile renderer splats), else lane by lane.
    let mut px = [PixelSampler::default(); CAP];
    let mut pts = [(0f32, 0f32); CAP];
    let cs = &s.samples;
    match cs.sobol {
        Some(sob) if !cs.centred && cs.filter == lucent_scene::PixelFilter::Box => {
            // (In whole strips of lanes: a loop of a constant count vectorizes.)
            on_lanes!(|sob: &crate::sampler::Sampler,
                       sampler: &crate::sampler::Sampler,
                       xs: &[u32; CAP],
                       ys: &[u32; CAP],
                       ks: &[u32; CAP],
                       px: &mut [PixelSampler; CAP],
                       pts: &mut [(f32, f32); CAP],
                       m: usize| {
                for strip in 0..m.div_ceil(STRIP).min(CAP / STRIP) {
                    for l in 0..STRIP {
                        let i = strip * STRIP + l;
                        px[i] = sampler.pixel(xs[i], ys[i]);
                        let (jx, jy) = sob.get2(xs[i], ys[i], ks[i], 0);
                        pts[i] = (xs[i] as f32 + jx, ys[i] as f32 + jy);
                    }
                }
            })(&sob, sampler, &xs, &ys, &ks, &mut px, &mut pts, m);
        }
        _ => {
            for i in 0..m {
                px[i] = sampler.pixel(xs[i], ys[i]);
                let (jx, jy) = cs.pixel(xs[i], ys[i], ks[i]);
                pts[i] = (xs[i] as f32 + jx, ys[i] as f32 + jy);
            }
        }
    }
    let mut rays = [NO_RAYS[0]; CAP];
    s.camera.rays_at(&pts[..m], &mut rays[..m]);
    let lens = s.camera.has_lens();
    for q in 0..m {
        let ray = if lens { s.camera.through_lens(&rays[q], cs.lens(xs[q], ys[q], ks[q])) } else { rays[q] };
        let i = fresh + q;
        wave.start(i, wave.slot[i], ks[q], px[q], ray);
    }
    wave.n = fresh + m;
}

/// The closest hits of the camera rays of lanes `fresh..`, as packets of up to
/// [`MAX_PACKET`] where they are coherent (as the scalar path tracer's blocks: the same
/// hits as single rays).
fn camera_packets(w: &World, wave: &mut Wave, fresh: usize, among: Option<&[u32]>, packets: bool) {
    if !packets || w.has_alpha() {
        return;
    }
    let mut at = fresh;
    while at < wave.n {
        let m = (wave.n - at).min(MAX_PACKET);
        let rays = &wave.ray[at..at + m];
        if coherent(rays) {
            let mut hits = [None; MAX_PACKET];
            match among {
                Some(ids) => w.intersect_packet_among(rays, ids, &mut hits[..m]),
                None => w.intersect_packet(rays, &mut hits[..m]),
            }
            for (f, h) in wave.first[at..at + m].iter_mut().zip(hits) {
                *f = Some(h);
            }
        }
        at += m;
    }
}

/// One bounce of every lane; ended paths write their values and leave.
fn step<'w>(
    w: &'w World,
    s: &PathSettings,
    wave: &mut Wave<'w>,
    models: &mut Models<'w>,
    batches: (&mut Flat, &mut EnvBatch, &mut Deltas),
    vals: &mut [Vec3],
    watch: &mut Watch,
) {
    if let Some(p) = &mut watch.p {
        p.steps += 1;
        p.lanes += wave.n as u64;
    }
    let rays = trace(w, s, wave, watch.is_on());
    watch.lap(Part::Surfaces);
    watch.moved(rays, Part::Surfaces, Part::ClosestHits);
    numbers(wave);
    watch.lap(Part::Numbers);
    light(w, s, wave, models, batches, watch);
    scatter(s, wave, models, watch);
    watch.lap(Part::Scatter);
    // Ended paths leave (their order among the lanes does not matter): from the back, so
    // the lane each removal moves in has been looked at already.
    for i in (0..wave.n).rev() {
        if wave.done[i] {
            let r = get3(&wave.radiance, i);
            vals[wave.slot[i] as usize] = if r.is_finite() { r } else { Vec3::ZERO };
            wave.n -= 1;
            if i != wave.n {
                wave.relocate(wave.n, i);
            }
        }
    }
    watch.lap(Part::Film);
}

/// Stage 1, lane by lane: the closest hits, the light of what they meet (or of the
/// environment), and where paths go on, the surface's BSDF and shading frame. With
/// `timed`, returns the clock counts spent in the closest-hit queries.
#[inline(never)]
fn trace<'w>(w: &'w World, s: &PathSettings, wave: &mut Wave<'w>, timed: bool) -> u64 {
    let mut ray_ticks = 0u64;
    let lights = &w.light_set;
    let hidden = |depth: u32| depth == 0 && s.hide_emitters;
    let mis = s.sampling == LightSampling::Mis;
    // The lanes whose rays left the scene: their directions and previous normals.
    let (mut esc_lane, mut esc_dir, mut esc_n, mut n_esc) = ([0u8; CAP], [Vec3::ZERO; CAP], [Vec3::ZERO; CAP], 0);
    // Every lane's closest hit first, asking for the cache lines its surface will read:
    // made after all of them, the surfaces' misses overlap (PERF: one miss after another,
    // the face normal's load was a quarter of `World::surface` on Sponza).
    let t0 = if timed { now() } else { 0 };
    let mut found = [None; CAP];
    for (i, f) in found.iter_mut().enumerate().take(wave.n) {
        *f = w.first_hit(&wave.ray[i], wave.first[i].take());
        if let Some((_, h)) = f {
            w.prefetch_surface(h);
        }
    }
    if timed {
        ray_ticks += now().wrapping_sub(t0);
    }
    for i in 0..wave.n {
        wave.scatter[i] = false;
        let depth = wave.depth[i];
        let beta = get3(&wave.beta, i);
        let Some((hit_ray, hit)) = found[i] else {
            if !hidden(depth) {
                // (The environment's radiance and density after the loop, together.)
                esc_lane[n_esc] = i as u8;
                esc_dir[n_esc] = wave.ray[i].dir.normalize();
                esc_n[n_esc] = get3(&wave.prev_n, i);
                n_esc += 1;
            }
            wave.done[i] = true;
            continue;
        };
        wave.ray[i] = hit_ray;
        let surf = w.surface(&hit_ray, &hit);
        let d = hit_ray.dir.normalize();
        let mat = material(w, surf.material);
        if mat.emission.max_element() > 0.0 && d.dot(surf.ng) < 0.0 && !hidden(depth) {
            let le = emitted(w, mat, surf.uv);
            let weight = if wave.prev_delta[i] {
                1.0
            } else {
                let wt = wave.prev_weights(lights, i);
                match (s.sampling, lights.pdf_hit_in(&wt, hit.inst, hit.prim, get3(&wave.prev_p, i), surf.p, d)) {
                    (LightSampling::Bsdf, _) | (_, None) => 1.0,
                    (LightSampling::Nee, Some(_)) => 0.0,
                    (LightSampling::Mis, Some(light_pdf)) => power_heuristic(wave.prev_pdf[i], light_pdf),
                }
            };
            add3(&mut wave.radiance, i, beta * le * weight);
        }
        if depth.saturating_add(1) >= s.max_depth {
            wave.done[i] = true;
            continue;
        }
        let ns = shading_normal(w, &hit_ray, &hit, &surf);
        let (bsdf, frame) = bsdf_frame(w, &hit_ray, &hit, &surf, ns, d);
        wave.bend[i] = Bend::of(w, &surf, ns);
        wave.surf[i] = surf;
        wave.bsdf[i] = Some(bsdf);
        wave.frame[i] = frame;
        put3(&mut wave.wo, i, frame.to_local(-d));
        wave.scatter[i] = true;
    }
    // Light from the environment (or the background) along the rays that left.
    let mut env = [(Vec3::ZERO, 0.0f32); CAP];
    let has_env = lights.env_radiance_pdf_batch(&esc_dir[..n_esc], &esc_n[..n_esc], mis, &mut env[..n_esc]);
    for j in 0..n_esc {
        let i = usize::from(esc_lane[j]);
        let beta = get3(&wave.beta, i);
        let add = if has_env {
            let (le, dir_pdf) = env[j];
            let weight = if wave.prev_delta[i] {
                1.0
            } else {
                match s.sampling {
                    LightSampling::Bsdf => 1.0,
                    LightSampling::Nee => 0.0,
                    LightSampling::Mis => power_heuristic(wave.prev_pdf[i], lights.env_choice_in(&wave.prev_weights(lights, i)) * dir_pdf),
                }
            };
            beta * le * weight
        } else {
            beta * w.scene.background
        };
        add3(&mut wave.radiance, i, add);
    }
    ray_ticks
}

/// Stage 2, on lanes: the bounce's sampler numbers (for every lane: those of lanes that
/// do not scatter, or past `n`, go unused). PERF: the loop runs over all [`CAP`] lanes
/// (the lanes past `n` hold an ended path's state), whole vectors: over `0..n`, the
/// scalar remainder was 64% of this stage's time on the Cornell box.
fn numbers(wave: &mut Wave) {
    on_lanes!(|wv: &mut Wave| {
        for strip in 0..wv.n.div_ceil(STRIP).min(CAP / STRIP) {
            for l in 0..STRIP {
                let i = strip * STRIP + l;
                let (px, k, depth) = (wv.px[i], wv.k[i], wv.depth[i]);
                let base = 1 + depth.saturating_mul(PAIRS);
                let choices = depth.saturating_mul(CHOICES);
                wv.u_light[i] = px.get1(k, choices);
                (wv.u2_light[0][i], wv.u2_light[1][i]) = px.get2(k, base);
                wv.u_bsdf[i] = px.get1(k, choices + 1);
                (wv.u2_bsdf[0][i], wv.u2_bsdf[1][i]) = px.get2(k, base + 1);
                wv.u_rr[i] = px.get1_hashed(k, choices + 3);
            }
        }
    })(wave);
}

/// Stage 3: next-event estimation. A light sample per lane that scatters (lane by lane),
/// the BSDF toward it on lanes (packed by model), then every shadow ray.
#[inline(never)]
fn light<'w>(
    w: &'w World,
    s: &PathSettings,
    wave: &mut Wave<'w>,
    models: &mut Models<'w>,
    (flat, envs, deltas): (&mut Flat, &mut EnvBatch, &mut Deltas),
    watch: &mut Watch,
) {
    let lights = &w.light_set;
    wave.weighed = [false; CAP];
    if lights.is_empty() || s.sampling == LightSampling::Bsdf {
        return;
    }
    let textures = &w.scene.textures;
    models.clear();
    let mut sampled = [false; CAP];
    let mut dir: Rows = [[0.0; CAP]; 3];
    let mut li: Rows = [[0.0; CAP]; 3];
    let mut pdf = [0.0f32; CAP];
    let mut delta = [false; CAP];
    let mut dist = [0.0f32; CAP];
    let mut alone = [0u8; CAP];
    let mut n_alone = 0;
    // (A light sample's BSDF value, packed with its model's lanes.)
    let mut pack = |models: &mut Models<'w>, i: usize, bsdf: Bsdf<'w>, ls: &LightSample| {
        sampled[i] = true;
        put3(&mut dir, i, ls.dir);
        put3(&mut li, i, ls.li);
        (pdf[i], delta[i], dist[i]) = (ls.pdf, ls.delta, ls.dist);
        let wi = wave.frame[i].to_local(ls.dir);
        if !models.push_eval(i, bsdf, get3(&wave.wo, i), wi) {
            alone[n_alone] = i as u8;
            n_alone += 1;
        }
    };
    // The lights chosen lane by lane; untextured triangles and parallelograms are
    // sampled after, on lanes (their square roots and divisions in vectors), environment
    // maps after in a batch (their cache misses overlapped), the others here.
    flat.n = 0;
    envs.n = 0;
    deltas.n = 0;
    for i in 0..wave.n {
        let Some(bsdf) = wave.bsdf[i].filter(|_| wave.scatter[i]) else { continue };
        if bsdf.is_delta() {
            continue;
        }
        let (p, n) = (wave.surf[i].p, light_normal(&bsdf, &wave.frame[i]));
        let u2 = (wave.u2_light[0][i], wave.u2_light[1][i]);
        let wt = lights.weigh(p, n);
        // (Kept only when weighed: uniform weights cost nothing to find again.)
        if wt.is_weighed() {
            (wave.weights[i], wave.weighed[i]) = (wt, true);
        }
        match lights.choice(&wt, wave.u_light[i]) {
            Choice::Nothing => {}
            Choice::Flat { light, quad, pmf } => flat.push(i, light, quad, pmf, p, u2),
            Choice::Delta { light, pmf } => deltas.push(i, light, pmf, p),
            Choice::Env { pmf } => envs.push(i as u8, u2, n, pmf),
            Choice::Other { entry, pmf } => {
                if let Some(ls) = lights.sample_entry(entry, pmf, p, n, u2, textures, s.sampling == LightSampling::Mis) {
                    pack(models, i, bsdf, &ls);
                }
            }
        }
    }
    on_lanes!(|f: &mut Flat| f.sample_all())(flat);
    on_lanes!(|d: &mut Deltas| d.sample_all())(deltas);
    for j in 0..deltas.n {
        let i = usize::from(deltas.lane[j]);
        if let (true, Some(bsdf)) = (deltas.ok[j], wave.bsdf[i]) {
            pack(models, i, bsdf, &deltas.out[j]);
        }
    }
    for j in 0..flat.n {
        let i = usize::from(flat.lane[j]);
        if let (true, Some(bsdf)) = (flat.ok[j], wave.bsdf[i]) {
            let ls = LightSample { dir: get3(&flat.dir, j), dist: flat.dist[j], li: get3(&flat.li, j), pdf: flat.pdf[j], delta: false };
            pack(models, i, bsdf, &ls);
        }
    }
    lights.sample_env_batch(envs, s.sampling == LightSampling::Mis);
    for j in 0..envs.n {
        let i = usize::from(envs.lane[j]);
        if let (Some(ls), Some(bsdf)) = (envs.out[j], wave.bsdf[i]) {
            pack(models, i, bsdf, &ls);
        }
    }
    run_models!(&mut *models, eval_all);
    models.eval_parts();
    models.count(watch, n_alone);
    let mut f: Rows = [[0.0; CAP]; 3];
    let mut bsdf_pdf = [0.0f32; CAP];
    models.mix_eval(&mut f, &mut bsdf_pdf);
    for &i in &alone[..n_alone] {
        let i = usize::from(i);
        let Some(bsdf) = wave.bsdf[i] else { continue };
        let (wo, wi) = (get3(&wave.wo, i), wave.frame[i].to_local(get3(&dir, i)));
        let (fi, pdf) = bsdf.eval_pdf(wo, wi);
        put3(&mut f, i, fi);
        bsdf_pdf[i] = pdf;
    }
    let mut pending: [(u8, Ray, Vec3); CAP] = [(0, NO_RAYS[0], Vec3::ZERO); CAP];
    let mut count = 0;
    for i in 0..wave.n {
        let fi = get3(&f, i) * wave.bend[i].weight(get3(&dir, i));
        if !sampled[i] || fi.max_element() <= 0.0 {
            continue;
        }
        let tmax = if dist[i].is_finite() { dist[i] * (1.0 - 1e-4) } else { f32::INFINITY };
        let weight = if delta[i] || s.sampling == LightSampling::Nee { 1.0 } else { power_heuristic(pdf[i], bsdf_pdf[i]) };
        let ray = wave.surf[i].spawn(get3(&dir, i)).with_range(0.0, tmax);
        pending[count] = (i as u8, ray, get3(&wave.beta, i) * fi * get3(&li, i) * (weight / pdf[i]));
        count += 1;
    }
    // (Measured: the first bounce's shadow rays of one pixel toward one light, sorted
    // together and traced as packets where coherent, made the bunny 3% and Sponza 1%
    // slower; the Cornell box's area light spreads them past a packet's cone.)
    watch.lap(Part::Lights);
    for &(i, ray, c) in &pending[..count] {
        if !w.occluded_solid(&ray) {
            add3(&mut wave.radiance, usize::from(i), c);
        }
    }
    watch.lap(Part::ShadowRays);
}

/// The lanes whose chosen light is a point, spot or directional light ([`Choice::Delta`]), sampled
/// together by [`delta_sample`].
struct Deltas {
    n: usize,
    lane: [u8; CAP],
    light: [DeltaLane; CAP],
    pmf: [f32; CAP],
    p: Rows,
    /// Out: the samples, and whether there is one.
    out: [LightSample; CAP],
    ok: [bool; CAP],
}

impl Deltas {
    fn new() -> Box<Self> {
        let none = LightSample { dir: Vec3::Z, dist: 0.0, li: Vec3::ZERO, pdf: 0.0, delta: true };
        Box::new(Self {
            n: 0,
            lane: [0; CAP],
            light: [DeltaLane::default(); CAP],
            pmf: [0.0; CAP],
            p: [[0.0; CAP]; 3],
            out: [none; CAP],
            ok: [false; CAP],
        })
    }

    #[inline(always)]
    fn push(&mut self, i: usize, light: DeltaLane, pmf: f32, p: Vec3) {
        let j = self.n;
        self.lane[j] = i as u8;
        self.light[j] = light;
        self.pmf[j] = pmf;
        put3(&mut self.p, j, p);
        self.n += 1;
    }

    /// Every lane's sample, in whole strips of [`STRIP`] (the lanes past `n` hold an
    /// earlier step's light; their results go unused).
    #[inline(always)]
    fn sample_all(&mut self) {
        for strip in 0..self.n.div_ceil(STRIP).min(CAP / STRIP) {
            for k in 0..STRIP {
                let j = strip * STRIP + k;
                (self.out[j], self.ok[j]) = delta_sample(&self.light[j], self.pmf[j], get3(&self.p, j));
            }
        }
    }
}

/// The lanes whose chosen light is an untextured triangle or parallelogram
/// ([`Choice::Flat`]), their lights' corners, edges, normals, areas and radiances copied
/// into rows, sampled together by [`flat_sample`] (over rows, the loop vectorizes; over
/// references to the lights, it did not).
struct Flat {
    n: usize,
    lane: [u8; CAP],
    p0: Rows,
    e1: Rows,
    e2: Rows,
    normal: Rows,
    area: [f32; CAP],
    le: Rows,
    quad: [bool; CAP],
    pmf: [f32; CAP],
    p: Rows,
    u2: [[f32; CAP]; 2],
    /// Out: the samples' directions, distances, radiances and densities, and whether
    /// there is one.
    dir: Rows,
    dist: [f32; CAP],
    li: Rows,
    pdf: [f32; CAP],
    ok: [bool; CAP],
}

impl Flat {
    fn new() -> Box<Self> {
        let z = [[0.0; CAP]; 3];
        Box::new(Self {
            n: 0,
            lane: [0; CAP],
            p0: z,
            e1: z,
            e2: z,
            normal: z,
            area: [1.0; CAP],
            le: z,
            quad: [false; CAP],
            pmf: [0.0; CAP],
            p: z,
            u2: [[0.0; CAP]; 2],
            dir: z,
            dist: [0.0; CAP],
            li: z,
            pdf: [0.0; CAP],
            ok: [false; CAP],
        })
    }

    #[inline(always)]
    fn push(&mut self, i: usize, light: &EmissiveTri, quad: bool, pmf: f32, p: Vec3, u2: (f32, f32)) {
        let j = self.n;
        self.lane[j] = i as u8;
        put3(&mut self.p0, j, light.p0);
        put3(&mut self.e1, j, light.e1);
        put3(&mut self.e2, j, light.e2);
        put3(&mut self.normal, j, light.n);
        self.area[j] = light.area;
        put3(&mut self.le, j, light.le);
        self.quad[j] = quad;
        self.pmf[j] = pmf;
        put3(&mut self.p, j, p);
        (self.u2[0][j], self.u2[1][j]) = u2;
        self.n += 1;
    }

    /// Every lane's sample: over a constant [`HALF`] or [`CAP`] lanes, whole vectors (the
    /// lanes past `n` hold an earlier step's light or none; their results go unused).
    #[inline(always)]
    fn sample_all(&mut self) {
        // (Two loops of a constant count: in strips, the loop did not vectorize as well.)
        if self.n <= HALF {
            for j in 0..HALF {
                self.sample_one(j);
            }
        } else {
            for j in 0..CAP {
                self.sample_one(j);
            }
        }
    }

    #[inline(always)]
    fn sample_one(&mut self, j: usize) {
        let light = EmissiveTri {
            p0: get3(&self.p0, j),
            e1: get3(&self.e1, j),
            e2: get3(&self.e2, j),
            n: get3(&self.normal, j),
            area: self.area[j],
            le: get3(&self.le, j),
            tex: None,
        };
        let (s, ok) = flat_sample(&light, self.quad[j], self.pmf[j], get3(&self.p, j), (self.u2[0][j], self.u2[1][j]));
        put3(&mut self.dir, j, s.dir);
        self.dist[j] = s.dist;
        put3(&mut self.li, j, s.li);
        self.pdf[j] = s.pdf;
        self.ok[j] = ok;
    }
}

/// Stage 4: the BSDF's sample (on lanes, packed by model), then the throughput, roulette
/// and the next ray.
#[inline(never)]
fn scatter<'w>(s: &PathSettings, wave: &mut Wave<'w>, models: &mut Models<'w>, watch: &mut Watch) {
    models.clear();
    let mut alone = [0u8; CAP];
    let mut n_alone = 0;
    for i in 0..wave.n {
        if !wave.scatter[i] {
            continue;
        }
        let Some(bsdf) = wave.bsdf[i] else { continue };
        if !models.push_sample(i, bsdf, get3(&wave.wo, i), wave.u_bsdf[i], (wave.u2_bsdf[0][i], wave.u2_bsdf[1][i])) {
            alone[n_alone] = i as u8;
            n_alone += 1;
        }
    }
    run_models!(&mut *models, sample_all);
    models.count(watch, n_alone);
    let mut out = SampleRows::new();
    models.mix_sample(&wave.wo, &mut out);
    for &i in &alone[..n_alone] {
        let i = usize::from(i);
        let Some(bsdf) = wave.bsdf[i] else { continue };
        if let Some(bs) = bsdf.sample(get3(&wave.wo, i), wave.u_bsdf[i], (wave.u2_bsdf[0][i], wave.u2_bsdf[1][i])) {
            out.set(i, Some(bs));
        }
    }
    let SampleRows { ok, wi, weight, pdf, delta, eta } = out;
    for i in 0..wave.n {
        if !wave.scatter[i] {
            continue;
        }
        if !ok[i] {
            wave.done[i] = true;
            continue;
        }
        let bend = wave.bend[i].weight(wave.frame[i].to_world(get3(&wi, i)));
        let beta = get3(&wave.beta, i) * get3(&weight, i) * bend;
        put3(&mut wave.beta, i, beta);
        if !beta.is_finite() || beta.max_element() <= 0.0 {
            wave.done[i] = true;
            continue;
        }
        wave.eta[i] *= eta[i];
        wave.prev_pdf[i] = pdf[i];
        wave.prev_delta[i] = delta[i];
        put3(&mut wave.prev_p, i, wave.surf[i].p);
        put3(&mut wave.prev_n, i, wave.bsdf[i].map_or(Vec3::ZERO, |b| light_normal(&b, &wave.frame[i])));
        wave.ray[i] = wave.surf[i].spawn(wave.frame[i].to_world(get3(&wi, i)));
        wave.depth[i] += 1;
        if wave.depth[i] >= s.rr_depth {
            let q = (beta.max_element() * wave.eta[i] * wave.eta[i]).min(0.95);
            // (The bounce's own numbers: drawn before `depth` moved on.)
            if wave.u_rr[i] >= q {
                wave.done[i] = true;
                continue;
            }
            put3(&mut wave.beta, i, beta / q);
        }
    }
}
