//! Thread pools for the benchmarks, with each worker pinned to its own CPU.
//!
//! Why pin: on the 2-vCPU machines here, a 2-thread pool sometimes ran both workers on
//! one CPU for the whole of a short parallel job. The museum's BVH build (about 2 ms)
//! took 1.5 ms in some processes and 2.0–2.4 ms in others, as slow as one thread, in 4 of
//! 6 processes; with the workers pinned it took 1.47–1.58 ms in 6 of 6. A scheduler that
//! places a woken thread beside the one that woke it would do this, and would only spread
//! them again after the job had ended. Pinning is for benchmarks, where lucent owns the
//! machine; two pinned processes at once would share CPUs badly, so every benchmark has
//! `--no-pin`.

use anyhow::{Context, Result};

/// A pool of `threads` workers; with `pin`, worker `i` runs only on the `i`-th CPU this
/// process may use (when there are at least as many such CPUs as workers; else unpinned).
pub fn pool(threads: usize, pin: bool) -> Result<rayon::ThreadPool> {
    builder(threads, pin).build().context("cannot start the thread pool")
}

/// [`pool`] as rayon's global pool (for code that uses it implicitly), with rayon's own
/// default size: `RAYON_NUM_THREADS` when it is a positive number, else one worker per
/// available CPU.
pub fn global(pin: bool) -> Result<()> {
    let threads = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|s| s.parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    builder(threads, pin).build_global().context("cannot set up the global thread pool")
}

fn builder(threads: usize, pin: bool) -> rayon::ThreadPoolBuilder {
    let threads = threads.max(1);
    let cpus = if pin { allowed_cpus() } else { Vec::new() };
    let pin_to = (cpus.len() >= threads).then_some(cpus);
    if pin && pin_to.is_none() {
        tracing::debug!("{threads} workers for fewer CPUs: the workers are not pinned");
    }
    rayon::ThreadPoolBuilder::new().num_threads(threads).start_handler(move |i| {
        if let Some(c) = pin_to.as_ref().and_then(|c| c.get(i)) {
            pin_current(*c);
        }
    })
}

/// The CPUs this process may run on, in order (empty where that cannot be asked).
fn allowed_cpus() -> Vec<usize> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: `set` is a plain bit set on our stack; the kernel writes at most its size.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
                return Vec::new();
            }
            (0..libc::CPU_SETSIZE as usize).filter(|&c| libc::CPU_ISSET(c, &set)).collect()
        }
    }
    #[cfg(not(target_os = "linux"))]
    Vec::new()
}

/// Keeps the calling thread on CPU `cpu` (a failure is logged and otherwise ignored).
fn pin_current(cpu: usize) {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: as in `allowed_cpus`; `cpu` comes from the allowed set, so it is below
        // CPU_SETSIZE.
        let rc = unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
        };
        if rc != 0 {
            tracing::debug!("cannot pin a worker to CPU {cpu}: {}", std::io::Error::last_os_error());
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = cpu;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[cfg(target_os = "linux")]
    fn pinned_workers_run_on_distinct_allowed_cpus() {
        let cpus = allowed_cpus();
        assert!(!cpus.is_empty(), "sched_getaffinity reported no CPU");
        let n = cpus.len().min(2);
        let p = pool(n, true).expect("pool");
        let seen = std::sync::Mutex::new(Vec::new());
        p.broadcast(|ctx| {
            // SAFETY: no arguments; returns the CPU this thread runs on.
            let cpu = unsafe { libc::sched_getcpu() };
            // The worker's own affinity mask must hold that one CPU and no other.
            let mask = allowed_cpus();
            seen.lock().expect("lock").push((ctx.index(), cpu as usize, mask));
        });
        let mut seen = seen.into_inner().expect("lock");
        seen.sort_unstable_by_key(|s| s.0);
        let want: Vec<(usize, usize, Vec<usize>)> = (0..n).map(|i| (i, cpus[i], vec![cpus[i]])).collect();
        assert_eq!(seen, want, "worker i must run on allowed CPU i");
    }

    #[test]
    fn unpinned_pool_has_the_asked_workers() {
        let p = pool(3, false).expect("pool");
        assert_eq!(p.current_num_threads(), 3);
    }
}
