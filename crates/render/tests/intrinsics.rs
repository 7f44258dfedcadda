//! A calibrated camera whose principal point is off the image centre renders with the tile
//! loop (packets, and the screen-space culling of instances that skips rays) exactly what
//! the camera's rays give pixel by pixel: the culling follows the skewed view axis.

use lucent_render::{render, render_pixel, Camera, Integrator, RenderSettings, Traversal, World};

#[test]
fn an_off_centre_camera_renders_its_rays_pixel_by_pixel() {
    let scene = lucent_scene::demo_scene();
    let desc = scene.camera.expect("the demo has a camera");
    let world = World::new(scene, lucent_accel::MeshOptions::default()).expect("world");
    let forward = (desc.look_at - desc.eye).normalize();
    let right = forward.cross(desc.up).normalize();
    let down = forward.cross(right);
    let (w, h) = (96, 64);
    for (cx, cy) in [(48.0, 32.0), (20.0, 50.0), (90.0, 5.0)] {
        let cam = Camera::from_intrinsics(desc.eye, right, down, forward, (80.0, 70.0), (cx, cy), w, h);
        let image = |packets| {
            let settings =
                RenderSettings { integrator: Integrator::EyeLight, traversal: Traversal { packets }, ..RenderSettings::new(w, h) };
            render(&world, &cam, &settings, &|_| {}).0.pixels
        };
        let (a, b) = (image(true), image(false));
        assert_eq!(a, b, "principal point {cx},{cy}");
        let settings = RenderSettings { integrator: Integrator::EyeLight, ..RenderSettings::new(w, h) };
        for y in 0..h {
            for x in 0..w {
                let want = render_pixel(&world, &cam, &settings, x, y);
                assert_eq!(a[(y * w + x) as usize], want, "pixel {x},{y}, principal point {cx},{cy}");
            }
        }
        assert!(a.iter().filter(|p| p.max_element() > 0.0).count() > 100, "something in view");
    }
}
