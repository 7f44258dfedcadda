//! Direct-mapped caches of fixed-size items, as SaarCOR's traversal, list and
//! transformation caches (its Table 4: 4, 2 and 6 KB of 512 items each).

/// A direct-mapped cache of `lines` items of `item_bytes` bytes. An access of a range of
/// bytes looks up every item the range touches; each lookup is a hit or a miss (a miss
/// replaces the line).
#[derive(Clone, Debug)]
pub struct DirectMapped {
    item_bytes: u64,
    tags: Vec<u64>,
    /// Lookups that hit.
    pub hits: u64,
    /// Lookups that missed (each one an item read from memory).
    pub misses: u64,
}

impl DirectMapped {
    /// A cache of `bytes` bytes in `items` lines (at least one byte an item).
    #[must_use]
    pub fn new(bytes: u64, items: u64) -> Self {
        let items = items.max(1);
        Self { item_bytes: (bytes / items).max(1), tags: vec![u64::MAX; items as usize], hits: 0, misses: 0 }
    }

    /// Bytes of one item.
    #[must_use]
    pub fn item_bytes(&self) -> u64 {
        self.item_bytes
    }

    /// Looks up the items of `bytes` bytes at `addr`; returns the misses.
    pub fn access(&mut self, addr: u64, bytes: u64) -> u64 {
        let first = addr / self.item_bytes;
        let last = (addr + bytes.max(1) - 1) / self.item_bytes;
        let n = self.tags.len() as u64;
        let mut missed = 0;
        for item in first..=last {
            let slot = &mut self.tags[(item % n) as usize];
            if *slot == item {
                self.hits += 1;
            } else {
                *slot = item;
                missed += 1;
            }
        }
        self.misses += missed;
        missed
    }

    /// Hits over lookups, in percent (100 when nothing was looked up).
    #[must_use]
    pub fn hit_rate(&self) -> f64 {
        let n = self.hits + self.misses;
        if n == 0 {
            100.0
        } else {
            100.0 * self.hits as f64 / n as f64
        }
    }

    /// Bytes read from memory on misses.
    #[must_use]
    pub fn miss_bytes(&self) -> u64 {
        self.misses * self.item_bytes
    }
}

#[cfg(test)]
mod tests {
    use super::DirectMapped;

    /// Traces with known hit rates.
    #[test]
    fn known_traces() {
        // A loop over 256 items of 8 bytes fits a 4 KB cache of 512: only the first pass misses.
        let mut c = DirectMapped::new(4096, 512);
        for _ in 0..10 {
            for i in 0..256 {
                c.access(i * 8, 8);
            }
        }
        assert_eq!((c.misses, c.hits), (256, 2304));
        assert!((c.hit_rate() - 90.0).abs() < 1e-9);
        // Two addresses one cache size apart share a line: they evict each other every time.
        let mut c = DirectMapped::new(4096, 512);
        for _ in 0..100 {
            c.access(0, 8);
            c.access(4096, 8);
        }
        assert_eq!(c.hits, 0);
        // A stream of 4-byte reads through 8-byte items: every second read hits.
        let mut c = DirectMapped::new(4096, 512);
        for i in 0..1000 {
            c.access(i * 4, 4);
        }
        assert_eq!((c.hits, c.misses), (500, 500));
        // A 40-byte read over 12-byte items touches 4 items when it starts at 0 (0..40 -> items 0..=3).
        let mut c = DirectMapped::new(6144, 512);
        assert_eq!(c.item_bytes(), 12);
        assert_eq!(c.access(0, 40), 4);
        assert_eq!(c.access(0, 40), 0);
        assert_eq!(c.miss_bytes(), 48);
    }
}
