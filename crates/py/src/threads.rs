//! The thread pools queries run on: one per thread count asked for, kept for the next call
//! (a pool is made once; a query on 2 threads does not pay for starting them).

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The default thread count (0: every core), set by `set_num_threads`.
static DEFAULT: AtomicUsize = AtomicUsize::new(0);

static POOLS: Mutex<Option<HashMap<usize, Arc<rayon::ThreadPool>>>> = Mutex::new(None);

/// Cores on this machine.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

/// Sets the default thread count.
pub fn set_default(n: usize) {
    DEFAULT.store(n, Ordering::Relaxed);
}

/// The thread count a call with `threads` uses.
pub fn resolve(threads: Option<usize>) -> usize {
    match threads.unwrap_or_else(|| DEFAULT.load(Ordering::Relaxed)) {
        0 => cores(),
        n => n,
    }
}

/// The default thread count now.
pub fn current() -> usize {
    resolve(None)
}

/// Runs `f` on a pool of `threads` threads (see [`resolve`]).
pub fn run<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> T {
    let n = resolve(threads);
    let pool = {
        let mut pools = POOLS.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let map = pools.get_or_insert_with(HashMap::new);
        match map.get(&n) {
            Some(p) => Some(p.clone()),
            None => match rayon::ThreadPoolBuilder::new().num_threads(n).thread_name(|i| format!("lucent-{i}")).build() {
                Ok(p) => {
                    let p = Arc::new(p);
                    map.insert(n, p.clone());
                    Some(p)
                }
                Err(_) => None,
            },
        }
    };
    match pool {
        Some(p) => p.install(f),
        // (A pool that cannot start: the global one.)
        None => f(),
    }
}
