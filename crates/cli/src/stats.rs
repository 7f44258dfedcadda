//! Small figures shared by the benchmark commands.

/// The median (upper middle for an even count; 0 for none). Sorts `v`.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// The rays `render` sends to `world`, recorded on a one-thread pool (so that all of its
/// work is seen), and the median seconds of three passes tracing them again alone on the
/// current rayon pool: how long the render would take if only its rays cost time.
pub fn rays_alone<R: Send>(
    world: &lucent_render::World,
    render: impl FnOnce() -> R + Send,
) -> anyhow::Result<(lucent_render::RecordedRays, f64)> {
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let (_, rays) = one.install(|| lucent_render::record_rays(render));
    let mut times: Vec<f64> = (0..3)
        .map(|_| {
            let t = std::time::Instant::now();
            std::hint::black_box(rays.trace(world));
            t.elapsed().as_secs_f64()
        })
        .collect();
    let t = median(&mut times);
    Ok((rays, t))
}

/// A `/proc/self/status` field in KiB (`"VmRSS:"`, `"VmHWM:"`), on Linux.
pub fn proc_status_kib(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines().find(|l| l.starts_with(field))?.split_whitespace().nth(1)?.parse().ok()
}

/// A path-traced image of `world` through `cam` at `size`, `spp` samples per pixel with
/// sampler `seed`: read from `target/bench-cache/{stem}_{W}x{H}_{spp}spp_seed{seed}.exr`,
/// else rendered (minutes for a reference) and saved there. The benchmarks' references.
pub fn cached_path_image(
    stem: &str,
    world: &lucent_render::World,
    cam: &lucent_render::Camera,
    size: (u32, u32),
    spp: u32,
    seed: u32,
) -> anyhow::Result<lucent_render::Film> {
    use lucent_render::Film;
    let cache = std::path::PathBuf::from("target/bench-cache");
    std::fs::create_dir_all(&cache)?;
    let file = cache.join(format!("{stem}_{}x{}_{spp}spp_seed{seed:08x}.exr", size.0, size.1));
    if let Ok(f) = Film::load(&file) {
        return Ok(f);
    }
    eprintln!("{stem}: path tracing the reference ({spp} spp, cached in {})", file.display());
    let f = path_image(world, cam, size, spp, seed);
    f.save(&file)?;
    Ok(f)
}

/// A path-traced image of `world` through `cam` at `size`, `spp` samples per pixel with
/// sampler `seed` (the path tracer's other settings as default).
pub fn path_image(world: &lucent_render::World, cam: &lucent_render::Camera, size: (u32, u32), spp: u32, seed: u32) -> lucent_render::Film {
    use lucent_render::{render, Integrator, PathSettings, RenderSettings};
    let rs = RenderSettings {
        spp,
        integrator: Integrator::Path(PathSettings { seed, ..PathSettings::default() }),
        ..RenderSettings::new(size.0, size.1)
    };
    render(world, cam, &rs, &|_| {}).0
}
