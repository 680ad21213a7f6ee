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
    /// The memory the operating system reports available when the simulator is set up
    /// (`MemAvailable` of `/proc/meminfo`; no limit where that cannot be read) (default).
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

/// `MemAvailable` of `/proc/meminfo` in bytes, or `None` where it cannot be read (not Linux).
fn available_memory_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_available(&meminfo)
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
