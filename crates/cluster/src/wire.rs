//! The messages ranks exchange, as bytes: a tag byte, then little-endian fields. Every
//! decoder is total: bytes that are not a message give a [`DecodeError`] naming what is wrong
//! and where, never a panic, and no length read from the bytes is allocated before the
//! bytes are checked to hold it.

use glam::Vec3;
use lucent_render::{
    Camera, Integrator, LightSampling, PathSettings, Region, RegionFilm, RenderSettings, Traversal, VplSettings, WhittedSettings,
};
use lucent_scene::PixelFilter;

/// Why bytes are not a message.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DecodeError {
    /// The bytes end inside a field.
    #[error("the message ends at byte {at} inside {what}")]
    Short {
        /// Offset where the field starts.
        at: usize,
        /// The field.
        what: &'static str,
    },
    /// A field holds a value no message has.
    #[error("byte {at}: {what}")]
    Invalid {
        /// Offset of the field.
        at: usize,
        /// What is wrong.
        what: String,
    },
    /// Bytes follow the message.
    #[error("{extra} bytes follow the {len}-byte message")]
    Trailing {
        /// Bytes the message holds.
        len: usize,
        /// Bytes after it.
        extra: usize,
    },
}

/// Largest region a message may carry (pixels): 16384 × 16384, the largest image
/// `lucent render` makes.
pub const MAX_REGION_PIXELS: u64 = 16384 * 16384;

/// Longest error text a message may carry (bytes).
pub const MAX_TEXT: usize = 64 * 1024;

/// What a frame's regions are rendered with.
#[derive(Clone, Copy, Debug)]
pub struct FrameSpec {
    /// Set by the master: frames of one run, and of later runs, have increasing ids.
    pub id: u32,
    /// The animation time to pose the scene at, if it is animated.
    pub time: Option<f32>,
    /// Image size, samples per pixel of the image, integrator and traversal.
    pub settings: RenderSettings,
    /// The camera; `None`: the one the worker's own scene gives at `time` (an animation's
    /// camera), as `lucent animate` chooses it.
    pub camera: Option<Camera>,
}

/// A message between the master (rank 0) and a worker.
#[derive(Clone, Debug)]
pub enum Msg {
    /// Worker → master, once, when its scene is loaded: a digest of the scene (the master
    /// refuses ranks that loaded a different one) and its thread count.
    Hello {
        /// [`crate::scene_digest`] of the worker's world.
        digest: u64,
        /// Worker threads.
        threads: u32,
    },
    /// Master → worker: the frame the next jobs belong to.
    Frame(FrameSpec),
    /// Master → worker: render `region` of the current frame.
    Job {
        /// Job id (the master's index of the region).
        id: u32,
        /// Pixels and sample indices.
        region: Region,
    },
    /// Worker → master: a job's sums.
    Done {
        /// Job id.
        id: u32,
        /// Rays traced.
        rays: u64,
        /// Seconds the render took on the worker.
        seconds: f32,
        /// The sums.
        film: RegionFilm,
    },
    /// Worker → master, every quarter second: alive.
    Heartbeat,
    /// Worker → master: a job (or the worker) failed.
    Failed {
        /// The job, if one failed.
        id: Option<u32>,
        /// Why.
        message: String,
    },
    /// Master → worker: no more work; leave.
    Stop,
}

const HELLO: u8 = 1;
const FRAME: u8 = 2;
const JOB: u8 = 3;
const DONE: u8 = 4;
const HEARTBEAT: u8 = 5;
const FAILED: u8 = 6;
const STOP: u8 = 7;

/// A little-endian writer.
struct Out(Vec<u8>);

impl Out {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
    fn region(&mut self, r: &Region) {
        for v in [r.x0, r.y0, r.x1, r.y1, r.s0, r.s1] {
            self.u32(v);
        }
    }
}

/// A little-endian reader over a message's bytes.
struct In<'a> {
    b: &'a [u8],
    at: usize,
}

impl In<'_> {
    fn take(&mut self, n: usize, what: &'static str) -> Result<&[u8], DecodeError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len()).ok_or(DecodeError::Short { at: self.at, what })?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self, what: &'static str) -> Result<u8, DecodeError> {
        Ok(self.take(1, what)?[0])
    }
    fn u32(&mut self, what: &'static str) -> Result<u32, DecodeError> {
        let s = self.take(4, what)?;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn u64(&mut self, what: &'static str) -> Result<u64, DecodeError> {
        Ok(u64::from(self.u32(what)?) | (u64::from(self.u32(what)?) << 32))
    }
    fn f32(&mut self, what: &'static str) -> Result<f32, DecodeError> {
        Ok(f32::from_bits(self.u32(what)?))
    }
    fn flag(&mut self, what: &'static str) -> Result<bool, DecodeError> {
        let at = self.at;
        match self.u8(what)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(DecodeError::Invalid { at, what: format!("{what} is {v}, not 0 or 1") }),
        }
    }
    fn region(&mut self) -> Result<Region, DecodeError> {
        let at = self.at;
        let mut v = [0u32; 6];
        for x in &mut v {
            *x = self.u32("a region")?;
        }
        let r = Region { x0: v[0], y0: v[1], x1: v[2], y1: v[3], s0: v[4], s1: v[5] };
        if r.x0 > r.x1 || r.y0 > r.y1 || r.s0 > r.s1 {
            return Err(invalid(at, format!("region {r:?} ends before it starts")));
        }
        if r.pixels() as u64 > MAX_REGION_PIXELS {
            return Err(invalid(at, format!("region {r:?} holds more than {MAX_REGION_PIXELS} pixels")));
        }
        Ok(r)
    }
}

fn invalid(at: usize, what: String) -> DecodeError {
    DecodeError::Invalid { at, what }
}

fn put_settings(o: &mut Out, s: &RenderSettings) {
    o.u32(s.width);
    o.u32(s.height);
    o.u32(s.spp);
    o.u8(u8::from(s.traversal.packets));
    match s.integrator {
        Integrator::Whitted(w) => {
            o.u8(0);
            o.u32(w.max_depth);
            o.u8(u8::from(w.shadows));
        }
        Integrator::Path(p) => {
            o.u8(1);
            o.u32(p.max_depth);
            o.u32(p.rr_depth);
            o.u8(u8::from(p.hide_emitters));
            o.u8(match p.sampling {
                LightSampling::Mis => 0,
                LightSampling::Bsdf => 1,
                LightSampling::Nee => 2,
            });
            o.u32(p.seed);
            o.u8(u8::from(p.lanes));
        }
        Integrator::Vpl(v) => {
            o.u8(2);
            o.u32(v.count);
            o.u32(v.max_depth);
            o.f32(v.clamp);
            o.u32(v.interleave);
            o.u8(u8::from(v.discontinuity));
            o.u32(v.seed);
        }
        Integrator::EyeLight => o.u8(3),
        Integrator::Normals => o.u8(4),
        Integrator::Aov(kind) => {
            o.u8(5);
            o.u8(lucent_scene::AovKind::ALL.iter().position(|&k| k == kind).unwrap_or(0) as u8);
        }
    }
    match s.filter {
        PixelFilter::Box => o.u8(0),
        PixelFilter::Tent { radius } => {
            o.u8(1);
            o.f32(radius);
        }
        PixelFilter::Gaussian { stddev } => {
            o.u8(2);
            o.f32(stddev);
        }
        PixelFilter::Mitchell { b, c } => {
            o.u8(3);
            o.f32(b);
            o.f32(c);
        }
        PixelFilter::Lanczos { lobes } => {
            o.u8(4);
            o.f32(lobes);
        }
    }
    match s.window {
        None => o.u8(0),
        Some(win) => {
            o.u8(1);
            for v in win {
                o.u32(v);
            }
        }
    }
}

fn get_settings(i: &mut In) -> Result<RenderSettings, DecodeError> {
    let at = i.at;
    let (width, height, spp) = (i.u32("the width")?, i.u32("the height")?, i.u32("the samples per pixel")?);
    if width == 0 || height == 0 || width > 16384 || height > 16384 || spp == 0 {
        return Err(invalid(at, format!("{width}x{height} at {spp} spp is not an image")));
    }
    let packets = i.flag("the packets flag")?;
    let at = i.at;
    let integrator = match i.u8("the integrator")? {
        0 => Integrator::Whitted(WhittedSettings { max_depth: i.u32("max_depth")?, shadows: i.flag("the shadows flag")? }),
        1 => {
            let (max_depth, rr_depth, hide_emitters) = (i.u32("max_depth")?, i.u32("rr_depth")?, i.flag("hide_emitters")?);
            let at = i.at;
            let sampling = match i.u8("the light sampling")? {
                0 => LightSampling::Mis,
                1 => LightSampling::Bsdf,
                2 => LightSampling::Nee,
                v => return Err(invalid(at, format!("light sampling {v} does not exist"))),
            };
            let seed = i.u32("the seed")?;
            Integrator::Path(PathSettings { max_depth, rr_depth, hide_emitters, sampling, seed, lanes: i.flag("the lanes flag")? })
        }
        2 => {
            let (count, max_depth) = (i.u32("the VPL count")?, i.u32("max_depth")?);
            let at = i.at;
            let clamp = i.f32("the VPL clamp")?;
            if !(clamp >= 0.0 && clamp.is_finite()) {
                return Err(invalid(at, format!("VPL clamp {clamp} is not a fraction of the diagonal")));
            }
            let at = i.at;
            let interleave = i.u32("the interleave")?;
            if !(1..=64).contains(&interleave) {
                return Err(invalid(at, format!("interleave {interleave} is not 1..=64")));
            }
            Integrator::Vpl(VplSettings {
                count,
                max_depth,
                clamp,
                interleave,
                discontinuity: i.flag("the discontinuity flag")?,
                seed: i.u32("the seed")?,
            })
        }
        3 => Integrator::EyeLight,
        4 => Integrator::Normals,
        5 => {
            let at = i.at;
            let k = i.u8("the AOV kind")?;
            match lucent_scene::AovKind::ALL.get(usize::from(k)) {
                Some(&kind) => Integrator::Aov(kind),
                None => return Err(invalid(at, format!("AOV kind {k} does not exist"))),
            }
        }
        v => return Err(invalid(at, format!("integrator {v} does not exist"))),
    };
    let at = i.at;
    let filter = match i.u8("the filter")? {
        0 => PixelFilter::Box,
        k @ (1 | 2) => {
            let at = i.at;
            let r = i.f32("the filter's size")?;
            if !(r > 0.0 && r < 64.0) {
                return Err(invalid(at, format!("filter size {r} is not a positive size below 64")));
            }
            if k == 1 {
                PixelFilter::Tent { radius: r }
            } else {
                PixelFilter::Gaussian { stddev: r }
            }
        }
        3 => {
            let at = i.at;
            let (b, c) = (i.f32("the filter's B")?, i.f32("the filter's C")?);
            if !(b.is_finite() && c.is_finite() && b.abs() < 16.0 && c.abs() < 16.0) {
                return Err(invalid(at, format!("Mitchell filter B {b}, C {c}: expected finite values below 16")));
            }
            PixelFilter::Mitchell { b, c }
        }
        4 => {
            let at = i.at;
            let lobes = i.f32("the filter's lobes")?;
            if !(1.0..=16.0).contains(&lobes) || lobes.fract() != 0.0 {
                return Err(invalid(at, format!("Lanczos filter of {lobes} lobes: expected 1 to 16")));
            }
            PixelFilter::Lanczos { lobes }
        }
        v => return Err(invalid(at, format!("filter {v} does not exist"))),
    };
    let at = i.at;
    let window = match i.u8("the crop window's flag")? {
        0 => None,
        1 => {
            let mut win = [0u32; 4];
            for v in &mut win {
                *v = i.u32("the crop window")?;
            }
            let [x, y, w, h] = win;
            if w == 0 || h == 0 || x.checked_add(w).is_none_or(|e| e > width) || y.checked_add(h).is_none_or(|e| e > height) {
                return Err(invalid(at, format!("crop window {w} x {h} at ({x}, {y}) does not lie in the {width} x {height} image")));
            }
            Some(win)
        }
        v => return Err(invalid(at, format!("crop window flag {v}: expected 0 or 1"))),
    };
    Ok(RenderSettings { width, height, spp, integrator, traversal: Traversal { packets }, filter, window })
}

impl Msg {
    /// The message as bytes.
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut o = Out(Vec::new());
        match self {
            Msg::Hello { digest, threads } => {
                o.u8(HELLO);
                o.u64(*digest);
                o.u32(*threads);
            }
            Msg::Frame(f) => {
                o.u8(FRAME);
                o.u32(f.id);
                o.u8(u8::from(f.time.is_some()));
                o.f32(f.time.unwrap_or(0.0));
                put_settings(&mut o, &f.settings);
                o.u8(u8::from(f.camera.is_some()));
                if let Some(c) = &f.camera {
                    for w in c.to_bits() {
                        o.u32(w);
                    }
                }
            }
            Msg::Job { id, region } => {
                o.u8(JOB);
                o.u32(*id);
                o.region(region);
            }
            Msg::Done { id, rays, seconds, film } => {
                o.0.reserve(45 + 16 * film.sum.len());
                o.u8(DONE);
                o.u32(*id);
                o.u64(*rays);
                o.f32(*seconds);
                o.region(&film.region);
                for (s, w) in film.sum.iter().zip(&film.weight) {
                    o.f32(s.x);
                    o.f32(s.y);
                    o.f32(s.z);
                    o.f32(*w);
                }
            }
            Msg::Heartbeat => o.u8(HEARTBEAT),
            Msg::Failed { id, message } => {
                o.u8(FAILED);
                o.u8(u8::from(id.is_some()));
                o.u32(id.unwrap_or(0));
                let text = &message.as_bytes()[..message.len().min(MAX_TEXT)];
                o.u32(text.len() as u32);
                o.0.extend_from_slice(text);
            }
            Msg::Stop => o.u8(STOP),
        }
        o.0
    }

    /// The message `bytes` hold.
    ///
    /// # Errors
    /// [`DecodeError`] for bytes that are not exactly one message.
    pub fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let mut i = In { b: bytes, at: 0 };
        let msg = match i.u8("the message tag")? {
            HELLO => Msg::Hello { digest: i.u64("the digest")?, threads: i.u32("the thread count")? },
            FRAME => {
                let id = i.u32("the frame id")?;
                let has_time = i.flag("the time flag")?;
                let at = i.at;
                let t = i.f32("the time")?;
                if has_time && !t.is_finite() {
                    return Err(invalid(at, format!("time {t} is not finite")));
                }
                let settings = get_settings(&mut i)?;
                let camera = if i.flag("the camera flag")? {
                    let at = i.at;
                    let mut w = [0u32; Camera::BITS];
                    for x in &mut w {
                        *x = i.u32("the camera")?;
                    }
                    Some(Camera::from_bits(&w).ok_or_else(|| invalid(at, "the camera's words are no camera's".into()))?)
                } else {
                    None
                };
                Msg::Frame(FrameSpec { id, time: has_time.then_some(t), settings, camera })
            }
            JOB => Msg::Job { id: i.u32("the job id")?, region: i.region()? },
            DONE => {
                let (id, rays, seconds) = (i.u32("the job id")?, i.u64("the ray count")?, i.f32("the render time")?);
                let region = i.region()?;
                let n = region.pixels();
                let at = i.at;
                // (Checked before allocating: the region's size comes from the bytes.)
                if bytes.len() - at != n * 16 {
                    return Err(invalid(
                        at,
                        format!("region {region:?} needs {} bytes of sums, the message has {}", n * 16, bytes.len() - at),
                    ));
                }
                let mut film = RegionFilm::new(region);
                for k in 0..n {
                    film.sum[k] = Vec3::new(i.f32("a sum")?, i.f32("a sum")?, i.f32("a sum")?);
                    film.weight[k] = i.f32("a weight")?;
                }
                Msg::Done { id, rays, seconds, film }
            }
            HEARTBEAT => Msg::Heartbeat,
            FAILED => {
                let has_id = i.flag("the job flag")?;
                let id = i.u32("the job id")?;
                let at = i.at;
                let len = i.u32("the text length")? as usize;
                if len > MAX_TEXT {
                    return Err(invalid(at, format!("a text of {len} bytes (at most {MAX_TEXT})")));
                }
                let text = i.take(len, "the text")?;
                Msg::Failed { id: has_id.then_some(id), message: String::from_utf8_lossy(text).into_owned() }
            }
            STOP => Msg::Stop,
            t => return Err(DecodeError::Invalid { at: 0, what: format!("message tag {t} does not exist") }),
        };
        if i.at != bytes.len() {
            return Err(DecodeError::Trailing { len: i.at, extra: bytes.len() - i.at });
        }
        Ok(msg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn camera() -> Camera {
        let desc = lucent_scene::CameraDesc::from_view(&[1.0, 2.0, 3.0, 0.0, 0.5, 0.0, 0.0, 1.0, 0.0, 47.0]);
        Camera::new(&desc, 320, 200).with_clip(0.25, 900.0).with_lens(0.05, 3.5)
    }

    #[test]
    fn every_message_round_trips() {
        let mut film = RegionFilm::new(Region { x0: 3, y0: 4, x1: 6, y1: 6, s0: 2, s1: 5 });
        film.add(4, 5, Vec3::new(0.1, -2.0, f32::MAX), 3.0);
        let settings = [
            Integrator::default(),
            Integrator::Path(PathSettings {
                max_depth: 7,
                rr_depth: 2,
                hide_emitters: true,
                sampling: LightSampling::Nee,
                seed: 99,
                lanes: false,
            }),
            Integrator::Vpl(VplSettings { count: 17, clamp: 0.5, interleave: 3, discontinuity: false, ..VplSettings::default() }),
            Integrator::EyeLight,
            Integrator::Normals,
        ]
        .into_iter()
        .zip(
            [
                PixelFilter::Box,
                PixelFilter::Gaussian { stddev: 0.5 },
                PixelFilter::Tent { radius: 1.5 },
                PixelFilter::Mitchell { b: 0.0, c: 0.5 },
                PixelFilter::Lanczos { lobes: 3.0 },
            ]
            .into_iter()
            .cycle(),
        )
        .enumerate()
        .map(|(k, (integrator, filter))| RenderSettings {
            spp: 9,
            integrator,
            traversal: Traversal { packets: false },
            filter,
            window: (k % 2 == 1).then_some([3, 1, 20, 5]),
            ..RenderSettings::new(33, 7)
        })
        .collect::<Vec<_>>();
        let mut msgs = vec![
            Msg::Hello { digest: 0x0123_4567_89ab_cdef, threads: 64 },
            Msg::Job { id: 5, region: Region { x0: 0, y0: 16, x1: 64, y1: 80, s0: 0, s1: 16 } },
            Msg::Done { id: 77, rays: 1 << 40, seconds: 0.25, film },
            Msg::Heartbeat,
            Msg::Failed { id: Some(3), message: "set_time: naïve".into() },
            Msg::Failed { id: None, message: String::new() },
            Msg::Stop,
        ];
        for (k, s) in settings.into_iter().enumerate() {
            let time = (k % 2 == 0).then_some(k as f32 * 0.5);
            msgs.push(Msg::Frame(FrameSpec { id: k as u32, time, settings: s, camera: (k != 1).then(camera) }));
        }
        for m in msgs {
            let b = m.encode();
            let back = Msg::decode(&b).unwrap_or_else(|e| panic!("{m:?}: {e}"));
            // (Cameras compare by their words; everything else by its Debug text, which shows
            // every field.)
            assert_eq!(back.encode(), b, "{m:?}");
            if let (Msg::Frame(a), Msg::Frame(z)) = (&m, &back) {
                assert_eq!(a.settings, z.settings);
                assert_eq!(a.camera.map(|c| c.to_bits()), z.camera.map(|c| c.to_bits()));
            }
            // Every shorter prefix and one byte more are refused.
            for n in 0..b.len() {
                assert!(Msg::decode(&b[..n]).is_err(), "{m:?} cut at {n}");
            }
            let mut longer = b.clone();
            longer.push(0);
            assert!(Msg::decode(&longer).is_err(), "{m:?} with a byte more");
        }
    }

    #[test]
    fn a_region_larger_than_its_bytes_is_refused_before_allocating() {
        let mut b = Msg::Done { id: 1, rays: 0, seconds: 0.0, film: RegionFilm::new(Region::full(1, 1, 0, 1)) }.encode();
        // Claim a 16384 x 16384 region: 4 GiB of sums that are not there.
        b[17..41].copy_from_slice(&[0u32, 0, 16384, 16384, 0, 1].map(u32::to_le_bytes).concat());
        let e = Msg::decode(&b).expect_err("refused");
        assert!(e.to_string().contains("needs 4294967296 bytes of sums"), "{e}");
        b[17..41].copy_from_slice(&[0u32, 0, 16385, 16384, 0, 1].map(u32::to_le_bytes).concat());
        assert!(Msg::decode(&b).expect_err("refused").to_string().contains("more than"));
    }

    #[test]
    fn bad_fields_are_named() {
        let e = Msg::decode(&[9]).expect_err("no such tag");
        assert_eq!(e.to_string(), "byte 0: message tag 9 does not exist");
        let mut b = Msg::Frame(FrameSpec { id: 0, time: None, settings: RenderSettings::new(4, 4), camera: Some(camera()) }).encode();
        let n = b.len();
        b[n - 4 * Camera::BITS + 14 * 4] = 2; // the orthographic flag
        assert!(Msg::decode(&b).expect_err("bad camera").to_string().contains("no camera's"));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Any bytes decode to a message or an error, never a panic; a message decoded
        /// round-trips.
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200), tag in 1u8..8) {
            let mut b = bytes;
            if let Some(first) = b.first_mut() {
                *first = tag;
            }
            if let Ok(m) = Msg::decode(&b) {
                let again = m.encode();
                prop_assert_eq!(Msg::decode(&again).map(|x| x.encode()), Ok(again));
            }
        }
    }
}
