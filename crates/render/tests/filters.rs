//! Reconstruction filters: a small bright disk at one pixel's centre shows the filter's
//! profile in the pixels around it (Mitsuba's `rfilter` plugins, placed by filter
//! importance sampling), and the box filter leaves images as they were.

use glam::{Affine3A, Vec3};
use lucent_render::{render, Camera, Integrator, PathSettings, RenderSettings, World};
use lucent_scene::{CameraDesc, Geom, Instance, Material, PixelFilter, Scene, ShapeKind};

/// Radius of the disk, in pixels.
const RHO: f32 = 0.15;

/// A 9 × 9 orthographic view, one world unit per pixel, of an emitting sphere of radius
/// `RHO` at the centre of pixel (4, 4), rendered with `filter`.
fn footprint(filter: PixelFilter, spp: u32) -> Vec<f32> {
    footprint_at(filter, spp, 0.0)
}

/// [`footprint`] with the disk moved `dx` pixels to the right.
fn footprint_at(filter: PixelFilter, spp: u32, dx: f32) -> Vec<f32> {
    let mut s = Scene::default();
    s.materials.push(Material { emission: Vec3::ONE, diffuse: Vec3::ZERO, ..Material::default() });
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 },
        world_from_object: Affine3A::from_scale_rotation_translation(Vec3::splat(RHO), glam::Quat::IDENTITY, Vec3::new(dx, 0.0, -5.0)),
    });
    let desc = CameraDesc { eye: Vec3::ZERO, look_at: -Vec3::Z, up: Vec3::Y, vfov_deg: 45.0, ortho_height: Some(9.0) };
    let cam = Camera::new(&desc, 9, 9);
    let world = World::new(s, lucent_accel::MeshOptions::default()).expect("world");
    let settings = RenderSettings { spp, integrator: Integrator::Path(PathSettings::default()), filter, ..RenderSettings::new(9, 9) };
    let (film, _) = render(&world, &cam, &settings, &|_| {});
    film.pixels.iter().map(|p| p.x).collect()
}

/// The expected value of pixel (4 + i, 4 + j) over pixel (4, 4)'s: the filter's weight
/// integrated over the disk, by quadrature.
fn expected_ratio(f: impl Fn(f32) -> f32, i: f32, j: f32) -> f32 {
    let n = 200;
    let (mut num, mut den) = (0.0, 0.0);
    for a in 0..n {
        for b in 0..n {
            let (x, y) = ((a as f32 + 0.5) / n as f32 * 2.0 - 1.0, (b as f32 + 0.5) / n as f32 * 2.0 - 1.0);
            if x * x + y * y > 1.0 {
                continue;
            }
            let (x, y) = (x * RHO, y * RHO);
            num += f(x - i) * f(y - j);
            den += f(x) * f(y);
        }
    }
    num / den
}

#[test]
fn the_gaussian_and_tent_profiles_show_around_a_point() {
    let spp = 1 << 16;
    let gauss = |x: f32| ((-x * x / (2.0 * 0.25)).exp() - (-8.0f32).exp()).max(0.0);
    let img = footprint(PixelFilter::Gaussian { stddev: 0.5 }, spp);
    let c = img[4 * 9 + 4];
    assert!(c > 0.0);
    for (i, j) in [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1)] {
        let got = img[(4 + j) as usize * 9 + (4 + i) as usize] / c;
        let want = expected_ratio(gauss, i as f32, j as f32);
        assert!((got - want).abs() < 0.12 * want + 0.002, "gaussian ({i}, {j}): {got} against {want}");
    }
    // Two pixels away the Gaussian of σ 0.5 is e^-8 of its peak: nothing to see.
    assert!(img[4 * 9 + 6] < 0.01 * c);
    let tent = |x: f32| (1.0 - x.abs() / 1.5).max(0.0);
    let img = footprint(PixelFilter::Tent { radius: 1.5 }, spp);
    let c = img[4 * 9 + 4];
    for (i, j) in [(1, 0), (0, -1), (-1, -1)] {
        let got = img[(4 + j) as usize * 9 + (4 + i) as usize] / c;
        let want = expected_ratio(tent, i as f32, j as f32);
        assert!((got - want).abs() < 0.12 * want + 0.002, "tent ({i}, {j}): {got} against {want}");
    }
    // The box keeps every sample in its own pixel.
    let img = footprint(PixelFilter::Box, 1024);
    assert!(img[4 * 9 + 4] > 0.0);
    assert!(img.iter().enumerate().all(|(k, &v)| k == 4 * 9 + 4 || v == 0.0));
}

/// Filters with negative lobes (Mitchell-Netravali, Catmull-Rom, Lanczos): with the disk
/// half a pixel right of pixel (4, 4)'s centre, pixel (4 + i, 4 + j) holds the filter at
/// offsets 0.5 − i and −j, negative lobes included (pixel (6, 4) is negative for all
/// three), each sample carrying its signed weight.
#[test]
fn negative_lobes_show_around_a_point() {
    let spp = 1 << 16;
    for f in [
        PixelFilter::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 },
        PixelFilter::Mitchell { b: 0.0, c: 0.5 },
        PixelFilter::Lanczos { lobes: 3.0 },
    ] {
        let img = footprint_at(f, spp, 0.5);
        let expected = |i: f32, j: f32| {
            let n = 200;
            let mut sum = 0.0f64;
            for a in 0..n {
                for b in 0..n {
                    let (x, y) = ((a as f32 + 0.5) / n as f32 * 2.0 - 1.0, (b as f32 + 0.5) / n as f32 * 2.0 - 1.0);
                    if x * x + y * y <= 1.0 {
                        sum += f64::from(f.eval(0.5 + x * RHO - i) * f.eval(y * RHO - j));
                    }
                }
            }
            sum
        };
        let c = img[4 * 9 + 4];
        let e0 = expected(0.0, 0.0);
        for (i, j) in [(1, 0), (2, 0), (-1, 0), (0, 1), (1, 1), (2, 1)] {
            let got = img[(4 + j) as usize * 9 + (4 + i) as usize] / c;
            let want = (expected(i as f32, j as f32) / e0) as f32;
            assert!((got - want).abs() < 0.1 * want.abs() + 0.004, "{f:?} ({i}, {j}): {got} against {want}");
        }
        assert!(img[4 * 9 + 6] < 0.0, "{f:?}: the negative lobe at pixel (6, 4): {}", img[4 * 9 + 6]);
        // The image's total is the disk's (the weights are normalised by ∫f).
        let total: f32 = img.iter().sum();
        let disk = std::f32::consts::PI * RHO * RHO;
        assert!((total / disk - 1.0).abs() < 0.03, "{f:?}: total {total} against the disk's {disk}");
    }
}

/// The offsets follow the filters' distributions (their CDFs at a few points, from a
/// fine grid of uniform numbers).
#[test]
fn filter_offsets_follow_the_filters() {
    use lucent_render::filter_offset;
    let n = 100_000;
    for (f, cdf) in [
        (
            PixelFilter::Tent { radius: 1.0 },
            Box::new(|x: f32| if x < 0.0 { 0.5 * (1.0 + x) * (1.0 + x) } else { 1.0 - 0.5 * (1.0 - x) * (1.0 - x) })
                as Box<dyn Fn(f32) -> f32>,
        ),
        (PixelFilter::Gaussian { stddev: 0.5 }, Box::new(|x: f32| 0.5 * (1.0 + erf(f64::from(x) / (0.5 * 2f64.sqrt())) as f32))),
    ] {
        let xs: Vec<f32> = (0..n).map(|k| filter_offset(f, (k as f32 + 0.5) / n as f32)).collect();
        assert!(xs.windows(2).all(|w| w[0] <= w[1]), "{f:?}: not monotone");
        assert!(xs.iter().all(|x| x.abs() <= f.radius()), "{f:?}: beyond the radius");
        for q in [-0.7f32, -0.3, 0.0, 0.2, 0.6] {
            let frac = xs.iter().filter(|&&x| x <= q).count() as f32 / n as f32;
            assert!((frac - cdf(q)).abs() < 2e-3, "{f:?} at {q}: {frac} against {}", cdf(q));
        }
    }
    assert_eq!(filter_offset(PixelFilter::Box, 0.25), -0.25);
}

/// erf by Abramowitz and Stegun 7.1.26 (within 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y =
        1.0 - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t + 0.254_829_592) * t * (-x * x).exp();
    y.copysign(x)
}
