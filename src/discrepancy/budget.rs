//! How many rows of each recording an analysis may take on this machine now: at most
//! [`super::MAX_ROWS`], and fewer where the memory free would not hold the analysis's peak.
//!
//! The analysis holds both recordings and builds its candidate corrections at full rate, so its
//! peak grows with the rows. Killed by the system for want of memory, the command would end
//! without a word, and the HMI, which runs the analysis in its own process, would take the
//! live machine's view and any compensation in progress down with it. The readers stop at the
//! budget instead, with a message that says how to read the recording averaged.

use std::path::Path;

use super::MAX_ROWS;

/// Memory the analysis takes at its peak beyond what grows with the rows, bytes.
const PEAK_BASE_BYTES: u64 = 250_000_000;
/// Memory the analysis takes at its peak per row of each recording, bytes.
const PEAK_BYTES_PER_ROW: u64 = 2_200;
/// Fewest rows a budget allows, whatever the memory (5.5 h at 1 Hz, about 0.3 GB at the peak):
/// with less than about 0.6 GB free the rule would refuse every recording, even the short ones
/// whose analysis takes little more than its base.
const MIN_ROWS: usize = 20_000;
/// The environment variable that states the free memory in MB instead of the system: for a
/// machine whose limit the system does not report, and for tests, which cannot change the
/// memory a machine has.
pub const FREE_MEMORY_VARIABLE: &str = "SERVOSIGHT_FREE_MEMORY_MB";

/// The memory the analysis takes at its peak with `rows` rows of each recording, bytes:
/// 250 MB + 2.2 kB a row, a little above what was measured on the twin's 46-column recordings
/// (160 MB at 18,001 rows, 334 MB at 100,001, 752 MB at 300,001, 1.28 GB at 600,001 and
/// 2.1 GB at 1,080,001; a step asked again with the corrections refitted adds up to 0.2 GB;
/// docs/performance.md).
pub fn peak_memory_bytes(rows: usize) -> u64 {
    PEAK_BASE_BYTES + PEAK_BYTES_PER_ROW * rows as u64
}

/// The most rows of each recording an analysis takes, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowBudget {
    /// The most rows of each recording.
    pub rows: usize,
    /// The memory free when the budget was set, bytes, where that (not [`MAX_ROWS`]) set it.
    pub free_bytes: Option<u64>,
}

impl RowBudget {
    /// The budget with `free` bytes of memory free (`None`: unknown): rows whose peak takes
    /// at most half of it (the rest stays for the system and, in the HMI, the live machine),
    /// between 20,000 rows and [`MAX_ROWS`].
    pub fn for_free_memory(free: Option<u64>) -> RowBudget {
        let Some(free) = free else {
            return RowBudget {
                rows: MAX_ROWS,
                free_bytes: None,
            };
        };
        let rows = (free / 2).saturating_sub(PEAK_BASE_BYTES) / PEAK_BYTES_PER_ROW;
        let rows = usize::try_from(rows).unwrap_or(usize::MAX).max(MIN_ROWS);
        if rows >= MAX_ROWS {
            RowBudget {
                rows: MAX_ROWS,
                free_bytes: None,
            }
        } else {
            RowBudget {
                rows,
                free_bytes: Some(free),
            }
        }
    }

    /// The budget with the memory free now ([`free_memory_bytes`]).
    pub fn now() -> RowBudget {
        RowBudget::for_free_memory(free_memory_bytes())
    }

    /// Why the budget is what it is, for a message that refuses a longer recording.
    pub fn reason(&self) -> String {
        match self.free_bytes {
            Some(free) => format!(
                "with {:.1} GB of memory free, the analysis takes at most {} rows of each \
                 recording (about {:.1} GB at its peak, half of what is free)",
                free as f64 / 1e9,
                self.rows,
                peak_memory_bytes(self.rows) as f64 / 1e9
            ),
            None => format!(
                "the analysis takes at most {} rows of each recording",
                self.rows
            ),
        }
    }
}

/// The memory free for a new allocation now, bytes: the system's estimate
/// (`MemAvailable` of `/proc/meminfo`), or less where this process's control group is
/// limited to less (cgroup v2 `memory.max` − `memory.current`, or v1 `limit_in_bytes` −
/// `usage_in_bytes`: a container sees the host's memory in `/proc/meminfo`).
/// [`FREE_MEMORY_VARIABLE`], a number of MB, overrides both (a value that is not one is
/// ignored, so a mistyped override cannot lift the limit); `None` where nothing tells (not
/// Linux).
pub fn free_memory_bytes() -> Option<u64> {
    if let Some(stated) = std::env::var(FREE_MEMORY_VARIABLE)
        .ok()
        .and_then(|text| stated_bytes(&text))
    {
        return Some(stated);
    }
    let read = |path: &str| std::fs::read_to_string(Path::new(path)).ok();
    let system = read("/proc/meminfo").and_then(|text| mem_available(&text));
    let group = [
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        (
            "/sys/fs/cgroup/memory/memory.limit_in_bytes",
            "/sys/fs/cgroup/memory/memory.usage_in_bytes",
        ),
    ]
    .iter()
    .find_map(|(limit, usage)| group_room(&read(limit)?, &read(usage)?));
    match (system, group) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The bytes a [`FREE_MEMORY_VARIABLE`] value states: a non-negative number of MB, or `None`.
fn stated_bytes(text: &str) -> Option<u64> {
    let mb = text.trim().parse::<f64>().ok()?;
    (mb.is_finite() && mb >= 0.0).then_some((mb * 1e6) as u64)
}

/// `MemAvailable` of a `/proc/meminfo` text, bytes.
fn mem_available(meminfo: &str) -> Option<u64> {
    meminfo.lines().find_map(|line| {
        let kb = line
            .strip_prefix("MemAvailable:")?
            .trim()
            .strip_suffix("kB")?;
        kb.trim().parse::<u64>().ok().map(|kb| kb * 1024)
    })
}

/// What a control group's limit leaves above its usage, bytes; `None` for no limit (`max`,
/// or v1's near-2⁶³ "unlimited").
fn group_room(limit: &str, usage: &str) -> Option<u64> {
    let limit = limit.trim().parse::<u64>().ok()?;
    if limit >= 1 << 60 {
        return None;
    }
    let usage = usage.trim().parse::<u64>().ok()?;
    Some(limit.saturating_sub(usage))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Plenty of memory, or none known: the fixed limit. Less: rows whose peak fits in half of
    /// what is free, never fewer than the floor; the reason names the memory and the peak.
    #[test]
    fn the_budget_keeps_the_peak_within_half_of_the_free_memory() {
        assert_eq!(RowBudget::for_free_memory(None).rows, MAX_ROWS);
        let plenty = RowBudget::for_free_memory(Some(64_000_000_000));
        assert_eq!(plenty, RowBudget::for_free_memory(None));
        assert_eq!(
            plenty.reason(),
            format!("the analysis takes at most {MAX_ROWS} rows of each recording")
        );
        let budget = RowBudget::for_free_memory(Some(4_000_000_000));
        assert_eq!(budget.rows, (2_000_000_000 - 250_000_000) / 2_200);
        assert!(peak_memory_bytes(budget.rows) <= 2_000_000_000);
        assert!(peak_memory_bytes(budget.rows + 1) > 2_000_000_000);
        assert_eq!(
            budget.reason(),
            "with 4.0 GB of memory free, the analysis takes at most 795454 rows of each \
             recording (about 2.0 GB at its peak, half of what is free)"
        );
        assert_eq!(RowBudget::for_free_memory(Some(100_000_000)).rows, MIN_ROWS);
        assert_eq!(RowBudget::for_free_memory(Some(0)).rows, MIN_ROWS);
    }

    /// The system's estimate and a control group's room are read from their files' text; no
    /// limit is no limit.
    #[test]
    fn free_memory_is_read_from_meminfo_and_the_control_group() {
        let meminfo = "MemTotal:       24684092 kB\nMemFree:         1000 kB\n\
                       MemAvailable:   23804464 kB\nBuffers: 5 kB\n";
        assert_eq!(mem_available(meminfo), Some(23_804_464 * 1024));
        assert_eq!(mem_available("MemTotal: 5 kB\n"), None);
        assert_eq!(group_room("max\n", "4476268544\n"), None);
        assert_eq!(group_room("9223372036854771712\n", "4476268544\n"), None);
        assert_eq!(
            group_room("8589934592\n", "4476268544\n"),
            Some(4_113_666_048)
        );
        assert_eq!(group_room("1000\n", "2000\n"), Some(0));
        assert_eq!(stated_bytes(" 600 "), Some(600_000_000));
        assert_eq!(stated_bytes("1.5"), Some(1_500_000));
        for mistyped in ["lots", "", "-5", "inf", "NaN", "600MB"] {
            assert_eq!(stated_bytes(mistyped), None, "{mistyped}");
        }
    }
}
