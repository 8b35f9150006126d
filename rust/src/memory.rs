//! Size checks before large allocations. A request the machine cannot hold becomes an error
//! that names the quantity (the bindings raise it as `MemoryError`), never an abort: Rust
//! aborts the whole process when an infallible allocation fails, and on Linux an allocation
//! that overcommit lets through is killed later, when touched. So the size is compared with the
//! memory available before anything is allocated, and the allocation itself is fallible.

/// Bytes of memory available to new allocations: `MemAvailable` of /proc/meminfo where it
/// exists (Linux), else None (then only the fallible allocation guards).
pub fn available_bytes() -> Option<u128> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u128 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

fn gib(bytes: u128) -> f64 {
    bytes as f64 / (1u128 << 30) as f64
}

/// Ok if `count` items of `item_bytes` each fit in the memory available now.
/// `what` names the quantity, e.g. "trace rows (integrator.duration / integrator.dt)".
pub fn check(what: &str, count: u128, item_bytes: u128) -> Result<(), String> {
    let bytes = count.saturating_mul(item_bytes);
    // Beyond isize::MAX bytes no Vec can exist, whatever the machine.
    let limit = available_bytes().unwrap_or(isize::MAX as u128);
    if bytes > limit.min(isize::MAX as u128) {
        return Err(format!(
            "{what}: {count} values need {:.3} GiB, more than the {:.3} GiB of memory available",
            gib(bytes),
            gib(limit)
        ));
    }
    Ok(())
}

/// A zero-filled vector of `len` items, checked with [`check`] and allocated fallibly.
pub fn zeroed_vec<T: Copy>(what: &str, len: usize, zero: T) -> Result<Vec<T>, String> {
    check(what, len as u128, std::mem::size_of::<T>() as u128)?;
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| format!("{what}: could not allocate {len} values"))?;
    v.resize(len, zero);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_sizes_are_refused_with_the_quantity_named() {
        let e = check("runs * rows", 1 << 70, 8).unwrap_err();
        assert!(e.starts_with("runs * rows: "), "{e}");
        assert!(zeroed_vec("gust samples", usize::MAX / 2, 0.0f64).is_err());
        assert_eq!(zeroed_vec("small", 3, 1.5f64).unwrap(), vec![1.5; 3]);
    }
}
