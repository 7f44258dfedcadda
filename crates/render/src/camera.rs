//! Cameras: pinhole (eye, look-at, up, vertical field of view) and orthographic.
//!
//! Ray generation follows the benchmark harness's convention exactly (shared/bench): pixel
//! (x, y) with y = 0 at the top maps to `sx = (2 (x + 0.5) / w - 1) tan(fov/2) w/h` and
//! `sy = (1 - 2 (y + 0.5) / h) tan(fov/2)`, direction `normalize(f + sx r + sy u)`.

use glam::Vec3;
use lucent_accel::Ray;
use lucent_scene::CameraDesc;

/// A camera ready to make rays for a `width` × `height` image.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    half_w: f32,
    half_h: f32,
    ortho: bool,
    normalize: bool,
    tmin: f32,
    tmax: f32,
    width: u32,
    height: u32,
    /// Thin lens: aperture radius (0: a pinhole) and distance of the plane in focus.
    lens_radius: f32,
    focus: f32,
    /// The principal point's offset from the image centre, in view-plane units (added to
    /// the view-plane coordinates of every ray), and whether it is not zero.
    shift: (f32, f32),
    shifted: bool,
}

impl Camera {
    /// Sets up a camera; `ortho_height` in `desc` makes it orthographic.
    #[must_use]
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Self {
        let forward = (desc.look_at - desc.eye).normalize_or(-Vec3::Z);
        let mut right = forward.cross(desc.up).normalize_or_zero();
        if right == Vec3::ZERO {
            right = forward.any_orthonormal_vector();
        }
        let up = right.cross(forward);
        let (half_h, ortho) = match desc.ortho_height {
            Some(h) => (h * 0.5, true),
            None => ((desc.vfov_deg.to_radians() * 0.5).tan(), false),
        };
        let aspect = width as f32 / height.max(1) as f32;
        Self { ortho, ..Self::pinhole(desc.eye, (right, up, forward), (half_h * aspect, half_h), width, height) }
    }

    /// A pinhole at `eye` with the axes `(right, up, forward)` and the view plane's half
    /// extents at unit distance, no lens, clip, or principal-point shift.
    fn pinhole(eye: Vec3, (right, up, forward): (Vec3, Vec3, Vec3), (half_w, half_h): (f32, f32), width: u32, height: u32) -> Self {
        Self {
            eye,
            forward,
            right,
            up,
            half_w,
            half_h,
            ortho: false,
            normalize: true,
            tmin: 0.0,
            tmax: f32::INFINITY,
            width: width.max(1),
            height: height.max(1),
            lens_radius: 0.0,
            focus: 1.0,
            shift: (0.0, 0.0),
            shifted: false,
        }
    }

    /// A pinhole camera as a calibrated camera is described (OpenCV's and Open3D's pinhole
    /// model): the eye, the camera's unit axes in the world (`right`, `down`, `forward`,
    /// pixel x growing along `right`, pixel y along `down`), focal lengths and principal
    /// point in pixels, the image size. A pixel's ray passes through
    /// `forward + right (x + ½ − cx)/fx + down (y + ½ − cy)/fy`, normalized.
    #[allow(clippy::too_many_arguments)]
    #[must_use]
    pub fn from_intrinsics(
        eye: Vec3,
        right: Vec3,
        down: Vec3,
        forward: Vec3,
        (fx, fy): (f32, f32),
        (cx, cy): (f32, f32),
        width: u32,
        height: u32,
    ) -> Self {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let shift = ((0.5 * w - cx) / fx, (cy - 0.5 * h) / fy);
        Self {
            shifted: shift != (0.0, 0.0),
            shift,
            ..Self::pinhole(eye, (right, -down, forward), (0.5 * w / fx, 0.5 * h / fy), width, height)
        }
    }

    /// Words in [`Camera::to_bits`].
    pub const BITS: usize = 24;

    /// The camera as words, bit for bit (for sending it to another process:
    /// [`Camera::from_bits`] gives back the same camera, hence the same rays).
    #[must_use]
    pub fn to_bits(&self) -> [u32; Self::BITS] {
        let v = |v: Vec3| v.to_array().map(f32::to_bits);
        let [e, f, r, u] = [v(self.eye), v(self.forward), v(self.right), v(self.up)];
        [
            e[0],
            e[1],
            e[2],
            f[0],
            f[1],
            f[2],
            r[0],
            r[1],
            r[2],
            u[0],
            u[1],
            u[2],
            self.half_w.to_bits(),
            self.half_h.to_bits(),
            u32::from(self.ortho),
            u32::from(self.normalize),
            self.tmin.to_bits(),
            self.tmax.to_bits(),
            self.width,
            self.height,
            self.lens_radius.to_bits(),
            self.focus.to_bits(),
            self.shift.0.to_bits(),
            self.shift.1.to_bits(),
        ]
    }

    /// The camera [`Camera::to_bits`] wrote, or `None` for words no camera has (a flag
    /// other than 0 or 1, a size of 0, a non-finite vector or extent, a clip range that is
    /// not `0 <= near < far`, a negative lens).
    #[must_use]
    pub fn from_bits(b: &[u32; Self::BITS]) -> Option<Self> {
        let f = |i: usize| f32::from_bits(b[i]);
        let v = |i: usize| Vec3::new(f(i), f(i + 1), f(i + 2));
        let flag = |i: usize| match b[i] {
            0 => Some(false),
            1 => Some(true),
            _ => None,
        };
        let c = Self {
            eye: v(0),
            forward: v(3),
            right: v(6),
            up: v(9),
            half_w: f(12),
            half_h: f(13),
            ortho: flag(14)?,
            normalize: flag(15)?,
            tmin: f(16),
            tmax: f(17),
            width: b[18],
            height: b[19],
            lens_radius: f(20),
            focus: f(21),
            shift: (f(22), f(23)),
            shifted: (f(22), f(23)) != (0.0, 0.0),
        };
        let finite = [c.eye, c.forward, c.right, c.up].iter().all(|v| v.is_finite())
            && [c.half_w, c.half_h, c.lens_radius, c.focus, c.shift.0, c.shift.1].iter().all(|x| x.is_finite());
        let ok = finite && c.width > 0 && c.height > 0 && c.tmin >= 0.0 && c.tmax > c.tmin && c.lens_radius >= 0.0;
        ok.then_some(c)
    }

    /// The same camera with a thin lens (Mitsuba's `thinlens`): rays start on a disk of
    /// radius `aperture_radius` about the eye, across the view, and pass through the
    /// point their pinhole ray meets at depth `focus_distance`. A radius of zero (or a
    /// non-finite one) keeps the pinhole.
    #[must_use]
    pub fn with_lens(mut self, aperture_radius: f32, focus_distance: f32) -> Self {
        let ok = aperture_radius > 0.0 && aperture_radius.is_finite() && focus_distance > 0.0 && focus_distance.is_finite();
        self.lens_radius = if ok && !self.ortho { aperture_radius } else { 0.0 };
        self.focus = if ok { focus_distance } else { 1.0 };
        self
    }

    /// The same camera seeing only depths in [`near`, `far`) along the view axis (Mitsuba's
    /// `near_clip`, `far_clip`).
    #[must_use]
    pub fn with_clip(mut self, near: f32, far: f32) -> Self {
        if near >= 0.0 && far > near {
            self.tmin = near;
            self.tmax = far;
        }
        self
    }

    /// Whether rays start on a lens rather than at the eye.
    #[must_use]
    pub fn has_lens(&self) -> bool {
        self.lens_radius > 0.0
    }

    /// The pinhole ray `r` (one of this camera's) through the lens at `u` in [0, 1)² (a
    /// point of the aperture by Shirley and Chiu's concentric map).
    #[must_use]
    pub fn through_lens(&self, r: &Ray, u: (f32, f32)) -> Ray {
        if self.lens_radius <= 0.0 {
            return *r;
        }
        let (a, b) = (2.0 * u.0 - 1.0, 2.0 * u.1 - 1.0);
        let (rad, phi) = if a == 0.0 && b == 0.0 {
            (0.0, 0.0)
        } else if a.abs() > b.abs() {
            (a, std::f32::consts::FRAC_PI_4 * (b / a))
        } else {
            (b, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b))
        };
        let (lx, ly) = (rad * phi.cos() * self.lens_radius, rad * phi.sin() * self.lens_radius);
        let depth = r.dir.dot(self.forward);
        if depth <= 0.0 {
            return *r;
        }
        let focus_point = r.org + r.dir * (self.focus / depth);
        let org = self.eye + self.right * lx + self.up * ly;
        let d = (focus_point - org).normalize_or(r.dir);
        // (Clip depths along the new direction.)
        let inv = 1.0 / d.dot(self.forward).max(1e-6);
        let (near, far) = if self.normalize { (self.tmin, self.tmax) } else { (0.0, f32::INFINITY) };
        Ray::new(org, d).with_range(near * inv, far * inv)
    }

    /// A camera with an explicit frame: rays `forward + sx·right + sy·up` over the viewport
    /// `[-half_w, half_w] × [-half_h, half_h]` at distance 1, *not* normalized, so `t` is the
    /// depth along `forward`; `[tmin, tmax)` bounds them (near and far clip). This is
    /// REND3R's camera.
    #[allow(clippy::too_many_arguments)]
    #[must_use]
    pub fn viewport(
        eye: Vec3,
        right: Vec3,
        up: Vec3,
        forward: Vec3,
        half_w: f32,
        half_h: f32,
        tmin: f32,
        tmax: f32,
        width: u32,
        height: u32,
    ) -> Self {
        Self {
            eye,
            forward,
            right,
            up,
            half_w,
            half_h,
            ortho: false,
            normalize: false,
            tmin,
            tmax,
            width: width.max(1),
            height: height.max(1),
            lens_radius: 0.0,
            focus: 1.0,
            shift: (0.0, 0.0),
            shifted: false,
        }
    }

    /// The ray through image position (`x`, `y`) in pixels (pixel centres at +0.5).
    // PERF: inlined into the block loops, so the 64 rays of a block overlap their square
    // roots and divisions (a call per ray showed as an eighth of a sparse REND3R frame).
    #[inline]
    #[must_use]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.half_w;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.half_h;
        // (Not added when zero: −0 + 0 would turn a direction's −0 into +0.)
        let (sx, sy) = if self.shifted { (sx + self.shift.0, sy + self.shift.1) } else { (sx, sy) };
        if self.ortho {
            return Ray::new(self.eye + self.right * sx + self.up * sy, self.forward).with_range(self.tmin, self.tmax);
        }
        let d = self.forward + self.right * sx + self.up * sy;
        if self.normalize {
            // Depth clips are planes: along the unit direction, depth × |d|.
            let len = d.length();
            Ray::new(self.eye, d.normalize()).with_range(self.tmin * len, self.tmax * len)
        } else {
            Ray::new(self.eye, d).with_range(self.tmin, self.tmax)
        }
    }

    /// The rays through image positions `pts` into `out` (as many as the shorter holds):
    /// bit for bit the rays of [`Camera::ray`], computed a component at a time over up to
    /// 64 positions so the compiler can vectorize them (PERF: ray by ray, the division
    /// and square root of each ray stalled the next; an eighth of a sparse REND3R frame).
    pub fn rays_at(&self, pts: &[(f32, f32)], out: &mut [Ray]) {
        const N: usize = 64;
        let (w, h) = (self.width as f32, self.height as f32);
        for (pts, out) in pts.chunks(N).zip(out.chunks_mut(N)) {
            let n = pts.len().min(out.len());
            let (mut sx, mut sy) = ([0f32; N], [0f32; N]);
            for i in 0..n {
                sx[i] = (2.0 * pts[i].0 / w - 1.0) * self.half_w;
                sy[i] = (1.0 - 2.0 * pts[i].1 / h) * self.half_h;
            }
            if self.shifted {
                for i in 0..n {
                    sx[i] += self.shift.0;
                    sy[i] += self.shift.1;
                }
            }
            if self.ortho {
                for i in 0..n {
                    out[i] = Ray::new(self.eye + self.right * sx[i] + self.up * sy[i], self.forward).with_range(self.tmin, self.tmax);
                }
                continue;
            }
            // The same operations in the same order as `ray` (and glam's `normalize`).
            let mut d = [[0f32; N]; 3];
            for (k, dk) in d.iter_mut().enumerate() {
                let (f, r, u) = (self.forward[k], self.right[k], self.up[k]);
                for i in 0..n {
                    dk[i] = f + r * sx[i] + u * sy[i];
                }
            }
            if self.normalize {
                let mut len = [0f32; N];
                for i in 0..n {
                    len[i] = (d[0][i] * d[0][i] + d[1][i] * d[1][i] + d[2][i] * d[2][i]).sqrt();
                }
                for dk in &mut d {
                    for i in 0..n {
                        dk[i] *= 1.0 / len[i];
                    }
                }
                for (i, o) in out[..n].iter_mut().enumerate() {
                    *o = Ray {
                        org: self.eye,
                        dir: Vec3::new(d[0][i], d[1][i], d[2][i]),
                        tmin: self.tmin * len[i],
                        tmax: self.tmax * len[i],
                    };
                }
                continue;
            }
            for (i, o) in out[..n].iter_mut().enumerate() {
                *o = Ray { org: self.eye, dir: Vec3::new(d[0][i], d[1][i], d[2][i]), tmin: self.tmin, tmax: self.tmax };
            }
        }
    }

    /// Projects a world point to image coordinates (pixels, y down) and its depth along
    /// the view axis; `None` behind the eye (perspective cameras).
    #[must_use]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let v = p - self.eye;
        let (x, y, z) = (v.dot(self.right), v.dot(self.up), v.dot(self.forward));
        let (sx, sy) = if self.ortho {
            (x, y)
        } else {
            if z <= 0.0 {
                return None;
            }
            // Directions are forward + sx·right + sy·up with unit right/up/forward.
            (x / z, y / z)
        };
        let (sx, sy) = if self.shifted { (sx - self.shift.0, sy - self.shift.1) } else { (sx, sy) };
        let px = (sx / self.half_w + 1.0) * 0.5 * self.width as f32;
        let py = (1.0 - sy / self.half_h) * 0.5 * self.height as f32;
        Some((px, py, z))
    }

    /// The image size the camera was set up for.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Eye, right, up and forward vectors and the half extents of the viewport at distance
    /// 1 (orthographic: of the view), for projecting the scene onto the image.
    pub(crate) fn basis(&self) -> CameraBasis {
        // (A shifted principal point skews the view axis: rays are (forward + shift) +
        // sx·right + sy·up.)
        let forward = if self.shifted { self.forward + self.right * self.shift.0 + self.up * self.shift.1 } else { self.forward };
        let eye = if self.shifted && self.ortho { self.eye + self.right * self.shift.0 + self.up * self.shift.1 } else { self.eye };
        let forward = if self.ortho { self.forward } else { forward };
        CameraBasis { vectors: [eye, self.right, self.up, forward], half_w: self.half_w, half_h: self.half_h, ortho: self.ortho }
    }

    /// Near and far clip.
    #[must_use]
    pub fn clip(&self) -> (f32, f32) {
        (self.tmin, self.tmax)
    }

    /// Eye position.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.eye
    }

    /// The unit view axis (depth is measured along it).
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        self.forward
    }
}

/// See [`Camera::frame`].
pub(crate) struct CameraBasis {
    /// Eye, right, up, forward.
    pub vectors: [Vec3; 4],
    pub half_w: f32,
    pub half_h: f32,
    pub ortho: bool,
}

/// A camera that frames `bounds` from the front (+z side), looking at its centre.
#[must_use]
pub fn framing_camera(lo: Vec3, hi: Vec3) -> CameraDesc {
    let c = (lo + hi) * 0.5;
    let r = ((hi - lo).length() * 0.5).max(1e-6);
    let vfov: f32 = 45.0;
    let dist = r / (vfov.to_radians() * 0.5).sin();
    let eye = c + Vec3::new(0.35, 0.3, 1.0).normalize() * dist;
    CameraDesc { eye, look_at: c, up: Vec3::Y, vfov_deg: vfov, ortho_height: None }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `rays_at` gives `ray`'s rays bit for bit, for pinhole, viewport and orthographic
    /// cameras, over more positions than one chunk.
    #[test]
    fn rays_at_matches_ray() {
        let desc = CameraDesc {
            eye: Vec3::new(1.0, 2.0, 3.0),
            look_at: Vec3::new(-0.3, 0.1, -2.0),
            up: Vec3::Y,
            vfov_deg: 53.0,
            ortho_height: None,
        };
        let cams = [
            Camera::new(&desc, 317, 211),
            Camera::new(&CameraDesc { ortho_height: Some(4.5), ..desc }, 317, 211),
            Camera::viewport(
                Vec3::new(0.5, -1.0, 2.0),
                Vec3::new(1.1, 0.1, 0.0),
                Vec3::new(0.0, 0.9, 0.2),
                Vec3::new(0.1, 0.0, -1.0),
                5.0,
                3.75,
                1.0,
                90.0,
                512,
                384,
            ),
            Camera::from_intrinsics(Vec3::new(0.2, 0.3, 4.0), Vec3::X, -Vec3::Y, -Vec3::Z, (300.0, 280.0), (140.0, 120.5), 317, 211),
        ];
        let pts: Vec<(f32, f32)> = (0..150).map(|i| ((i * 37 % 317) as f32 + (i % 7) as f32 / 7.0, (i * 53 % 211) as f32 + 0.5)).collect();
        for cam in &cams {
            let mut got = vec![Ray::new(Vec3::ZERO, Vec3::X); pts.len()];
            cam.rays_at(&pts, &mut got);
            for (&(x, y), g) in pts.iter().zip(&got) {
                let want = cam.ray(x, y);
                assert_eq!(
                    [g.org.to_array(), g.dir.to_array()].map(|a| a.map(f32::to_bits)),
                    [want.org.to_array(), want.dir.to_array()].map(|a| a.map(f32::to_bits)),
                    "{x},{y}"
                );
                assert_eq!((g.tmin, g.tmax), (want.tmin, want.tmax));
            }
        }
    }

    /// A calibrated camera: with its principal point at the image centre it is the
    /// look-at camera of the same field of view; shifted, each pixel's ray passes through
    /// the point its intrinsics say, and projecting a point of it gives the pixel back.
    #[test]
    fn intrinsics_follow_opencvs_pinhole_model() {
        let (w, h) = (64u32, 48u32);
        let vfov = 50f32;
        let f = 0.5 * h as f32 / (vfov.to_radians() * 0.5).tan();
        let desc = CameraDesc { eye: Vec3::ZERO, look_at: -Vec3::Z, up: Vec3::Y, vfov_deg: vfov, ortho_height: None };
        let a = Camera::new(&desc, w, h);
        let b = Camera::from_intrinsics(Vec3::ZERO, Vec3::X, -Vec3::Y, -Vec3::Z, (f, f), (32.0, 24.0), w, h);
        for (x, y) in [(0.5, 0.5), (10.25, 40.0), (63.5, 47.5)] {
            assert!((a.ray(x, y).dir - b.ray(x, y).dir).length() < 1e-6, "{x},{y}");
        }
        let (fx, fy, cx, cy) = (70.0f32, 65.0f32, 20.0f32, 30.0f32);
        let c = Camera::from_intrinsics(Vec3::new(1.0, 2.0, 3.0), Vec3::X, -Vec3::Y, -Vec3::Z, (fx, fy), (cx, cy), w, h);
        for (x, y) in [(0.5f32, 0.5f32), (20.0, 30.0), (55.5, 7.25)] {
            let d = c.ray(x, y).dir;
            // In camera axes (x right, y down, z forward): (x − cx)/fx, (y − cy)/fy, 1.
            let cam = Vec3::new(d.x, -d.y, -d.z) / -d.z;
            assert!((cam.x - (x - cx) / fx).abs() < 1e-5 && (cam.y - (y - cy) / fy).abs() < 1e-5, "{x},{y}: {cam}");
            let (px, py, _) = c.project(c.ray(x, y).at(2.0)).expect("in front");
            assert!((px - x).abs() < 1e-3 && (py - y).abs() < 1e-3, "{x},{y}: {px},{py}");
        }
        let back = Camera::from_bits(&c.to_bits()).expect("a camera");
        assert_eq!(back.ray(3.0, 4.0).dir, c.ray(3.0, 4.0).dir);
    }
}
