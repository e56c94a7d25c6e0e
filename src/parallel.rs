//! Work spread over the machine's cores: a map whose items take turns on a few scoped
//! threads, and the joins that raise a thread's panic again on the caller's.

/// `f` over `items` on up to as many threads as the machine has cores (at most four), the
/// results in the order of the items. Each thread takes the next item not yet taken: the items
/// may differ in cost (a discrepancy family of two-lag members next to one of plain gains, a
/// heat fit at a long τ next to one at a short τ), and contiguous chunks would leave one
/// thread with the dear ones while the others wait.
pub fn parallel_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = worker_threads(items.len());
    if threads <= 1 {
        return items.iter().map(&f).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut indexed: Vec<(usize, R)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(item) = items.get(i) else {
                            return done;
                        };
                        done.push((i, f(item)));
                    }
                })
            })
            .collect();
        joined(handles)
    });
    indexed.sort_unstable_by_key(|(i, _)| *i);
    indexed.into_iter().map(|(_, r)| r).collect()
}

/// How many threads share `tasks` tasks: as many as the machine has cores, at most four, and
/// no more than there are tasks.
pub fn worker_threads(tasks: usize) -> usize {
    std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .clamp(1, 4)
        .min(tasks.max(1))
}

/// Every scoped thread's results, thread after thread; a thread's panic is raised again here.
pub fn joined<R>(handles: Vec<std::thread::ScopedJoinHandle<'_, Vec<R>>>) -> Vec<R> {
    handles.into_iter().flat_map(join_or_resume).collect()
}

/// A scoped thread's result; its panic is raised again here, as if it had run on this thread.
pub fn join_or_resume<T>(handle: std::thread::ScopedJoinHandle<'_, T>) -> T {
    match handle.join() {
        Ok(result) => result,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The items may take very different times; the results still come in the items' order,
    /// one per item, on any number of threads.
    #[test]
    fn parallel_map_keeps_the_order_of_unequal_items() {
        let items: Vec<u64> = (0..37)
            .map(|i| if i % 5 == 0 { 20_000 } else { 10 })
            .collect();
        let work = |&n: &u64| -> u64 { (0..n).fold(n, |a, k| a.wrapping_mul(31).wrapping_add(k)) };
        let sequential: Vec<u64> = items.iter().map(work).collect();
        assert_eq!(parallel_map(&items, work), sequential);
        assert_eq!(parallel_map(&items[..1], work), sequential[..1]);
        assert!(parallel_map(&[] as &[u64], work).is_empty());
    }
}
