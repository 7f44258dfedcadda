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
