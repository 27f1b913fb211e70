//! Helpers shared by the sampler's integration tests: this process's resident memory.

/// Resident memory of this process, from `/proc/self/status` (`VmRSS` now, `VmHWM` the peak
/// since the last [`reset_peak`]); 0 where the file is missing (non-Linux), which turns the
/// memory checks off. Resident pages are what a load really touched: zeroed memory that
/// nothing writes is not counted, so the budget is a floor, and the watchdog stops a runaway
/// load well before the machine's memory is gone. (A counting global allocator would be
/// exact, but it needs `unsafe`, which this workspace keeps to the GPU crate.)
pub fn status_bytes(key: &str) -> usize {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<usize>().ok())
        })
        .map_or(0, |kib| kib * 1024)
}

/// Resets `VmHWM` to the current resident size (`/proc/self/clear_refs`, value 5).
pub fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}
