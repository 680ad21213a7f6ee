//! How much memory the FEM's sparse Cholesky factors may take, checked after the symbolic
//! analysis and before any numeric factorization (a fine reference, such as the
//! convergence check of a thin shape, can need a factor larger than the machine; without the
//! check the process is killed by the operating system hours into a table, with nothing
//! reported).

use serde::{Deserialize, Serialize};

/// The most memory the factors of one [`crate::FemSimulator`] may take.
///
/// The need is `2 · nnz(L) · 8` bytes (a carried or previous factor and the fresh one live at
/// once) plus the factorization's workspace; a simulator whose need exceeds the limit is
/// refused with [`crate::FemSetupError::FactorTooLarge`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FactorMemoryLimit {
    /// The memory available when the simulator is set up: the smaller of the machine's
    /// (`MemAvailable` of `/proc/meminfo`) and, under a scheduler that limits the process's
    /// cgroup (v2), the cgroup's room (`memory.max − memory.current`); no limit where neither
    /// can be read (default).
    #[default]
    Available,
    /// At most this many bytes.
    Bytes(u64),
    /// No limit.
    Unlimited,
}

impl FactorMemoryLimit {
    /// The limit in bytes now, or `None` for no limit.
    pub fn bytes(self) -> Option<u64> {
        match self {
            FactorMemoryLimit::Available => available_memory_bytes(),
            FactorMemoryLimit::Bytes(bytes) => Some(bytes),
            FactorMemoryLimit::Unlimited => None,
        }
    }
}

/// The smaller of `MemAvailable` of `/proc/meminfo` and the room left in the process's cgroup
/// (v2), in bytes, or `None` where neither can be read (not Linux).
fn available_memory_bytes() -> Option<u64> {
    let machine = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|meminfo| parse_mem_available(&meminfo));
    let cgroup = cgroup_room_bytes();
    match (machine, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// `memory.max − memory.current` of the process's cgroup v2 (the `0::PATH` line of
/// `/proc/self/cgroup` under `/sys/fs/cgroup`), or `None` without a cgroup v2 limit.
fn cgroup_room_bytes() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = own.lines().find_map(|line| line.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let max = std::fs::read_to_string(dir.join("memory.max")).ok()?;
    let current = std::fs::read_to_string(dir.join("memory.current")).ok()?;
    cgroup_room(&max, &current)
}

/// The room `max − current` (bytes) of a cgroup's `memory.max` and `memory.current` texts;
/// `None` for `max` (no limit) or text that is not a number.
fn cgroup_room(max: &str, current: &str) -> Option<u64> {
    let max: u64 = max.trim().parse().ok()?;
    let current: u64 = current.trim().parse().ok()?;
    Some(max.saturating_sub(current))
}

/// The `MemAvailable:  N kB` line of a `/proc/meminfo` text, in bytes.
fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo
        .lines()
        .find_map(|line| line.strip_prefix("MemAvailable:"))?;
    let mut fields = line.split_whitespace();
    let value: u64 = fields.next()?.parse().ok()?;
    match fields.next() {
        Some("kB") => value.checked_mul(1024),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cgroup_limit_leaves_its_room_and_max_means_no_limit() {
        assert_eq!(cgroup_room("4294967296\n", "1073741824\n"), Some(3 << 30));
        assert_eq!(cgroup_room("1000\n", "2000\n"), Some(0));
        assert_eq!(cgroup_room("max\n", "1073741824\n"), None);
        assert_eq!(cgroup_room("", "1"), None);
    }

    #[test]
    fn mem_available_is_read_in_bytes_and_a_malformed_line_gives_no_limit() {
        let meminfo = "MemTotal:       24576000 kB\nMemFree:         1000 kB\n\
                       MemAvailable:   20000000 kB\nBuffers:  10 kB\n";
        assert_eq!(parse_mem_available(meminfo), Some(20_000_000 * 1024));
        assert_eq!(parse_mem_available("MemTotal: 5 kB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: lots\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: 5 MB\n"), None);
        assert_eq!(FactorMemoryLimit::Bytes(7).bytes(), Some(7));
        assert_eq!(FactorMemoryLimit::Unlimited.bytes(), None);
    }
}
